//! `riskplan plan` and `riskplan verify` end to end: plans found, accepted by
//! `verify` as they are, reproducible by seed, and bad requests rejected with status 2.

use crate::common;
use crate::common::run;
use crate::common::scene_arg as scene;

use serde_json::Value;

#[test]
fn plan_output_verifies_and_is_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    for name in common::PLANNING_SCENES {
        let out = dir.path().join(format!("{name}.json"));
        let fig = dir.path().join(format!("{name}.svg"));
        let (code, _, err) = run(&[
            "plan",
            "--scene",
            &scene(name),
            "--seed",
            "4",
            "--out",
            out.to_str().unwrap(),
            "--figure",
            fig.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{name}: {err}");
        assert!(err.contains("plan found (certified)"), "{name}: {err}");
        let plan: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        assert_eq!(plan["certified"], true);
        assert_eq!(plan["planner"], "rrt-sos");
        for k in ["planning_time_s", "iterations", "edges_checked"] {
            assert!(plan["stats"][k].is_number(), "{name}: stats.{k}");
        }
        assert!(std::fs::read_to_string(&fig).unwrap().contains("<svg"));
        let (code, report, err) =
            run(&["verify", "--scene", &scene(name), "--trajectory", out.to_str().unwrap(), "--method", "both"]);
        assert_eq!(code, 0, "{name}: verify rejects the plan: {err} {report}");
        let r: Value = serde_json::from_str(&report).unwrap();
        assert_eq!(r["safe"], true);
        // same seed, same plan
        let (_, again, _) = run(&["plan", "--scene", &scene(name), "--seed", "4"]);
        let again: Value = serde_json::from_str(&again).unwrap();
        assert_eq!(again["pieces"], plan["pieces"], "{name}: not reproducible");
    }
}

#[test]
fn mc_rrt_output_is_marked_not_certified() {
    let (code, out, err) = run(&["plan", "--scene", &scene("illustrative-3"), "--planner", "mc-rrt"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("NOT certified"));
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["certified"], false);
    assert_eq!(v["planner"], "mc-rrt");
}

#[test]
fn verify_reports_unsafe_with_witness_and_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path().join("line.json");
    std::fs::write(
        &t,
        r#"{"format": "riskplan-trajectory/1", "pieces": [{"t0": 0, "t1": 1, "coeffs": [[-1, 2], [-1, 2]]}]}"#,
    )
    .unwrap();
    for method in ["exact", "sos", "both"] {
        let (code, out, err) = run(&[
            "verify",
            "--scene",
            &scene("illustrative-3"),
            "--trajectory",
            t.to_str().unwrap(),
            "--method",
            method,
        ]);
        assert_eq!(code, 1, "{method}: {err}");
        let v: Value = serde_json::from_str(&out).unwrap();
        assert_eq!(v["safe"], false);
        let c = &v["pieces"][0]["obstacles"][0]["constraints"];
        assert!(
            c.as_array().unwrap().iter().any(|c| c["status"] == "unsafe" && c["witness"]["t"].is_number()),
            "{method}: {out}"
        );
    }
}

#[test]
fn bad_requests_exit_2_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    // start inside a contour
    let mut s: Value = serde_json::from_str(&std::fs::read_to_string(scene("illustrative-3")).unwrap()).unwrap();
    s["start"] = serde_json::json!([0.1, 0.1]);
    let inside = dir.path().join("inside.json");
    std::fs::write(&inside, s.to_string()).unwrap();
    let (code, _, err) = run(&["plan", "--scene", inside.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("start") && err.contains("risk"), "{err}");
    // goal outside the workspace
    s["start"] = serde_json::json!([-1, -1]);
    s["goal"] = serde_json::json!([1.5, 1]);
    let outside = dir.path().join("outside.json");
    std::fs::write(&outside, s.to_string()).unwrap();
    let (code, _, err) = run(&["plan", "--scene", outside.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("goal") && err.contains("outside the workspace"), "{err}");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--delta", "1.5"], "--delta"),
        (vec!["--delta", "0"], "--delta"),
        (vec!["--pieces", "0"], "pieces"),
        (vec!["--time-limit", "0"], "--time-limit"),
        (vec!["--planner", "astar"], "astar"),
    ];
    let sc = scene("illustrative-4");
    for (extra, expect) in cases {
        let mut args = vec!["plan", "--scene", sc.as_str()];
        args.extend(extra.iter());
        let (code, _, err) = run(&args);
        assert_eq!(code, 2, "{extra:?}: {err}");
        assert!(err.contains(expect), "{extra:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // a contour-only scene has no start and goal
    let (code, _, err) = run(&["plan", "--scene", &scene("illustrative-1")]);
    assert_eq!(code, 2);
    assert!(err.contains("no start and goal"), "{err}");
    // verify: a trajectory outside the horizon, a discontinuous one
    let t = dir.path().join("bad.json");
    std::fs::write(
        &t,
        r#"{"format": "riskplan-trajectory/1", "pieces": [{"t0": 0, "t1": 2, "coeffs": [[-1, 1], [-1, 1]]}]}"#,
    )
    .unwrap();
    let (code, _, err) = run(&["verify", "--scene", &scene("illustrative-3"), "--trajectory", t.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("horizon"), "{err}");
    std::fs::write(&t, r#"{"format": "riskplan-trajectory/1", "pieces": [{"t0": 0, "t1": 0.5, "coeffs": [[-1, 1], [-1, 1]]}, {"t0": 0.5, "t1": 1, "coeffs": [[0, 1], [0, 1]]}]}"#).unwrap();
    let (code, _, err) = run(&["verify", "--scene", &scene("illustrative-3"), "--trajectory", t.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("jumps"), "{err}");
}
