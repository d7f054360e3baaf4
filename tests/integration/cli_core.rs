//! The `risk` and `contour` subcommands end to end, and the errors of bad scenes.

use crate::common;

use num_rational::BigRational;
use serde_json::Value;
use std::path::Path;

fn run(args: &[&str]) -> (i32, String, String) {
    let out = common::bin().args(args).output().expect("run riskplan");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn ref_scene(name: &str) -> String {
    common::reference_dir().join(format!("{name}.json")).to_string_lossy().into()
}

fn q(n: i64, d: i64) -> BigRational {
    BigRational::new(n.into(), d.into())
}

#[test]
fn risk_exact_cantelli_value_and_centre() {
    let s = ref_scene("illustrative-1");
    let (code, out, err) = run(&["risk", "--scene", &s, "--point", "0.5", "0.5", "--bound", "cantelli"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    // E[P] = 37/300 − 1/2, E[P²] = 781/50000 − (37/150)(1/2) + 1/4; bound = (E[P²] − E[P]²)/E[P²]
    let m = q(37, 300) - q(1, 2);
    let m2 = q(781, 50000) - q(37, 150) * q(1, 2) + q(1, 4);
    let bound = (&m2 - &m * &m) / &m2;
    let o = &v["obstacles"][0];
    assert_eq!(o["bound_exact"].as_str().unwrap(), bound.to_string());
    assert_eq!(o["bound"].as_f64().unwrap(), riskplan_math::poly::rational_to_f64(&bound));
    assert_eq!(v["max_bound"], o["bound"]);
    // by default (auto) the best bound: zero risk from the support (w ≤ 0.4 < |x| = 0.71),
    // with Cantelli's still listed
    let (_, out, _) = run(&["risk", "--scene", &s, "--point", "0.5", "0.5"]);
    let v: Value = serde_json::from_str(&out).unwrap();
    let o = &v["obstacles"][0];
    assert_eq!(o["best"].as_str(), Some("support"));
    assert_eq!(o["bound_exact"].as_str(), Some("0"));
    assert_eq!(o["bounds"]["cantelli"]["exact"].as_str().unwrap(), bound.to_string());
    let (_, out, _) = run(&["risk", "--scene", &s, "--point", "0", "0"]);
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["obstacles"][0]["bound"].as_f64(), Some(1.0));
}

/// With --mc 100000 the interval contains the true risk. For w ~ U[0.3, 0.4] the true
/// risk at distance r is Prob(w ≥ r) = (0.4 − r)/0.1 on [0.3, 0.4].
#[test]
fn risk_monte_carlo_interval_contains_true_risk() {
    let s = ref_scene("illustrative-1");
    for (x, truth) in [("0.5", 0.0), ("0.38", 0.2), ("0.35", 0.5), ("0.31", 0.9)] {
        let (code, out, err) =
            run(&["risk", "--scene", &s, "--point", x, "0.5/1000000000", "--mc", "100000", "--seed", "3"]);
        assert_eq!(code, 0, "{err}");
        let v: Value = serde_json::from_str(&out).unwrap();
        let mc = &v["obstacles"][0]["mc"];
        let (lo, hi) = (mc["lower"].as_f64().unwrap(), mc["upper"].as_f64().unwrap());
        assert!(lo <= truth && truth <= hi, "x={x}: [{lo}, {hi}] misses {truth}");
        assert_eq!(mc["samples"].as_u64(), Some(100000));
    }
}

fn write(dir: &Path, name: &str, v: &Value) -> String {
    let p = dir.join(name);
    std::fs::write(&p, v.to_string()).unwrap();
    p.to_string_lossy().into()
}

/// At least ten kinds of broken scene: each exits with status 2 and one line on
/// stderr naming the file and what is wrong.
#[test]
fn broken_scenes_exit_2_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let base: Value = serde_json::from_str(&std::fs::read_to_string(ref_scene("illustrative-3")).unwrap()).unwrap();
    type Edit = fn(&mut Value);
    let cases: Vec<(&str, Edit, &str)> = vec![
        ("typo-field", |v| v["horizn"] = serde_json::json!([0, 1]), "unknown field `horizn`"),
        ("bad-format", |v| v["format"] = "riskplan-scene/9".into(), "format"),
        ("bad-dim", |v| v["dim"] = 3.into(), "workspace.lower"),
        ("bad-risk", |v| v["risk"] = 0.into(), "risk"),
        ("bad-horizon", |v| v["horizon"] = serde_json::json!([1, 1]), "horizon"),
        ("undeclared-param", |v| v["obstacles"][0]["poly"] = "r^2 - x1^2 - x2^2".into(), "unknown identifier 'r'"),
        ("poly-syntax", |v| v["obstacles"][0]["poly"] = "w^2 - x1^^2".into(), "obstacles[0].poly: column 10"),
        ("uniform-reversed", |v| v["params"]["w"]["low"] = 0.5.into(), "params.w.high"),
        (
            "negative-std",
            |v| v["params"]["w"] = serde_json::json!({"dist": "normal", "mean": 0.3, "std": -0.1}),
            "params.w.std",
        ),
        (
            "beta-alpha",
            |v| v["params"]["w"] = serde_json::json!({"dist": "beta", "alpha": -1, "beta": 2}),
            "params.w.alpha",
        ),
        (
            "weights",
            |v| v["params"]["w"] = serde_json::json!({"dist": "discrete", "values": [0.3, 0.4], "weights": [0.2, 0.2]}),
            "params.w.weights",
        ),
        (
            "few-moments",
            |v| v["params"]["w"] = serde_json::json!({"dist": "moments", "raw": [0.35, 0.123]}),
            "4 raw moments are needed",
        ),
        ("goal-outside", |v| v["goal"] = serde_json::json!([2, 1]), "goal"),
        (
            "duplicate-id",
            |v| {
                let o = v["obstacles"][0].clone();
                v["obstacles"].as_array_mut().unwrap().push(o);
            },
            "obstacles[1].id",
        ),
        ("wrong-type", |v| v["obstacles"] = "disk".into(), "obstacles"),
    ];
    for (name, edit, expect) in &cases {
        let mut v = base.clone();
        edit(&mut v);
        let path = write(dir.path(), &format!("{name}.json"), &v);
        let (code, _, err) = run(&["risk", "--scene", &path, "--point", "0", "0"]);
        assert_eq!(code, 2, "{name}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{name}: {err}");
        assert!(err.contains(&path) && err.contains(expect), "{name}: '{err}' lacks '{expect}'");
    }
    let path = dir.path().join("garbage.json");
    std::fs::write(&path, "{ this is not json").unwrap();
    let (code, _, err) = run(&["risk", "--scene", path.to_str().unwrap(), "--point", "0", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("line 1"), "{err}");
    let (code, _, err) = run(&["risk", "--scene", "/nonexistent.json", "--point", "0", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("cannot read"), "{err}");
}

#[test]
fn usage_errors_exit_2() {
    let s = ref_scene("illustrative-1");
    for args in [
        vec!["risk", "--scene", &s, "--point", "0"],
        vec!["risk", "--scene", &s, "--point", "a", "b"],
        vec!["risk", "--scene", &s, "--point", "0", "0", "--delta", "1.5"],
        vec!["contour", "--scene", &s, "--out", "/tmp/x.gif"],
        vec!["nonsense"],
    ] {
        let (code, _, err) = run(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(!err.is_empty());
    }
    let (code, out, _) = run(&["--help"]);
    assert_eq!(code, 0);
    assert!(out.contains("risk") && out.contains("contour"));
}

#[test]
fn contour_draws_svg_and_png_and_needs_a_slice_in_3d() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("c.svg");
    let (code, _, err) = run(&[
        "contour",
        "--scene",
        &ref_scene("illustrative-2"),
        "--time",
        "0",
        "0.5",
        "1",
        "--grid",
        "60",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("<svg") && text.contains("t=0.5"));
    let png = dir.path().join("c.png");
    let (code, _, err) = run(&[
        "contour",
        "--scene",
        &ref_scene("example-a2-3d"),
        "--slice",
        "x3=0",
        "--grid",
        "40",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let (code, _, err) = run(&["contour", "--scene", &ref_scene("example-a2-3d"), "--out", png.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("--slice"), "{err}");
}
