//! What a new user meets in the first hour with the local CLI: every error says what to do,
//! inputs outside the scene are refused or warned about, outputs are checked before the
//! work, and the plan command takes what its help lists (receding windows, endpoints).

use crate::common;
use crate::common::run;
use crate::common::scene_arg as scene;
use serde_json::Value;

/// A scene named as the service knows it, or with the wrong case, is not a file: the error
/// names the scene file meant.
#[test]
fn a_scene_name_instead_of_a_file_suggests_the_file() {
    let dir = common::reference_dir();
    let wrong = dir.join("Illustrative-3.json");
    let (code, _, err) = run(&["plan", "--scene", wrong.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    let meant = dir.join("illustrative-3.json");
    assert!(err.contains(&format!("did you mean {}?", meant.display())), "{err}");
}

/// `--out` in a directory that does not exist is refused before the plan is made, and no
/// figure is written either.
#[test]
fn plan_checks_its_outputs_before_planning() {
    let dir = tempfile::tempdir().unwrap();
    let fig = dir.path().join("plan.svg");
    let out = dir.path().join("missing").join("x.json");
    let (code, _, err) = run(&[
        "plan",
        "--scene",
        &scene("illustrative-3"),
        "--out",
        out.to_str().unwrap(),
        "--figure",
        fig.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("does not exist: create it first (mkdir -p"), "{err}");
    assert!(!err.contains("plan found"), "planned before failing: {err}");
    assert!(!fig.exists(), "the figure was written before the output was refused");
}

/// --start and --goal replace the scene's endpoints; the plan runs between them.
#[test]
fn plan_takes_start_and_goal() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.json");
    let (code, _, err) = run(&[
        "plan",
        "--scene",
        &scene("illustrative-3"),
        "--start",
        "-0.9",
        "0.8",
        "--goal",
        "0.9",
        "-0.8",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let plan: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let pieces = plan["pieces"].as_array().unwrap();
    let at = |p: &Value, t: f64| -> Vec<f64> {
        p["coeffs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|row| row.as_array().unwrap().iter().rev().fold(0.0, |acc, c| acc * t + c.as_f64().unwrap()))
            .collect()
    };
    let first = &pieces[0];
    let last = &pieces[pieces.len() - 1];
    let (s, g) = (at(first, first["t0"].as_f64().unwrap()), at(last, last["t1"].as_f64().unwrap()));
    assert!((s[0] + 0.9).abs() < 1e-9 && (s[1] - 0.8).abs() < 1e-9, "{s:?}");
    assert!((g[0] - 0.9).abs() < 1e-9 && (g[1] + 0.8).abs() < 1e-9, "{g:?}");
    let (code, _, err) = run(&["plan", "--scene", &scene("illustrative-3"), "--start", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("--start: the scene is 2-D, so give 2 coordinates, got 1"), "{err}");
}

/// `--planner receding` plans one window from the robot's state; the output names the
/// planner that ran. The window's flags without it are refused with the flag to add.
#[test]
fn plan_runs_the_receding_planner() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let (code, _, err) = run(&[
        "plan",
        "--scene",
        &scene("example-b-lane-change"),
        "--planner",
        "receding",
        "--t-now",
        "0.1",
        "--horizon",
        "0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(code == 0, "{err}");
    let plan: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(plan["planner"], "receding");
    let pieces = plan["pieces"].as_array().unwrap();
    assert_eq!(pieces[0]["t0"].as_f64(), Some(0.1));
    assert!(pieces[pieces.len() - 1]["t1"].as_f64().unwrap() <= 0.6 + 1e-12);
    let (code, _, err) = run(&["plan", "--scene", &scene("example-b-lane-change"), "--t-now", "0.1"]);
    assert_eq!(code, 2);
    assert!(err.contains("add --planner receding"), "{err}");
    // bench runs whole plans: receding is not among its planners
    let (code, _, err) = run(&["bench", "--planners", "receding"]);
    assert_eq!(code, 2, "{err}");
}

/// A time outside the horizon is refused by `contour`; a point outside the workspace or a
/// time outside the horizon is answered by `risk` with a warning.
#[test]
fn inputs_outside_the_scene_are_refused_or_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("c.svg");
    let (code, _, err) =
        run(&["contour", "--scene", &scene("illustrative-1"), "--time", "5", "--out", svg.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--time 5 is outside the horizon [0, 1]"), "{err}");
    let (code, _, err) = run(&["risk", "--scene", &scene("illustrative-1"), "--point", "5", "5"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("warning: --point (5, 5) is outside the workspace"), "{err}");
    let (code, _, err) = run(&["risk", "--scene", &scene("illustrative-1"), "--point", "0.5", "0.5", "--time", "3"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("warning: --time 3 is outside the horizon"), "{err}");
}

/// A negative number in exponent notation is a number, not a flag.
#[test]
fn negative_exponent_notation_is_a_number() {
    let (code, out, err) = run(&["risk", "--scene", &scene("illustrative-1"), "--point", "-1e-3", "0"]);
    assert_eq!(code, 0, "{err}");
    let r: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(r["point"][0].as_f64(), Some(-0.001));
}

/// A scene given as the trajectory is named as a scene; a plan of another scene is
/// verified with a warning that names both scenes.
#[test]
fn verify_names_a_scene_file_and_warns_of_another_scenes_plan() {
    let (code, _, err) =
        run(&["verify", "--scene", &scene("illustrative-3"), "--trajectory", &scene("illustrative-3")]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("this is a scene file") && err.contains("give it as --scene"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.json");
    let (code, _, err) = run(&["plan", "--scene", &scene("illustrative-3"), "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let (_, _, err) = run(&["verify", "--scene", &scene("illustrative-4"), "--trajectory", out.to_str().unwrap()]);
    assert!(
        err.contains("was planned on scene 'illustrative-3', and is verified here against scene 'illustrative-4'"),
        "{err}"
    );
}

/// `bench` names the commit of the binary that ran, wherever it runs (outside any git
/// checkout too: the commit is the binary's own, not asked of git in the working directory,
/// so the header never reads `git ;`).
#[test]
fn bench_names_the_binarys_commit_outside_a_checkout() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("no-scenes");
    std::fs::create_dir(&scenes).unwrap();
    let out = common::bin()
        .current_dir(dir.path())
        .env("OPENBLAS_NUM_THREADS", "1")
        .args(["bench", "--scenes", scenes.to_str().unwrap(), "--out", "b.jsonl"])
        .output()
        .expect("run riskplan bench");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let rev = stdout.split("; git ").nth(1).and_then(|r| r.split(';').next()).unwrap_or_default();
    assert!(!rev.is_empty() && rev.chars().all(|c| c.is_ascii_alphanumeric()), "no commit in {stdout:?}");
}
