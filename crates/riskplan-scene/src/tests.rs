use super::*;

fn base() -> serde_json::Value {
    serde_json::json!({
        "format": "riskplan-scene/1",
        "name": "t",
        "dim": 2,
        "workspace": {"lower": [-1, -1], "upper": [1, 1]},
        "horizon": [0, 1],
        "risk": 0.1,
        "params": {"w": {"dist": "uniform", "low": 0.3, "high": 0.4}},
        "obstacles": [{"id": "disk", "poly": "w^2 - x1^2 - x2^2"}],
        "start": [-1, -1],
        "goal": [1, 1]
    })
}

fn load(v: &serde_json::Value) -> Result<Scene, SceneError> {
    Scene::from_json(&v.to_string())
}

#[test]
fn base_scene_loads_with_exact_moments() {
    let s = load(&base()).unwrap();
    assert_eq!(s.obstacles[0].contour.mean.to_text(&|v| s.vars.name(v)), "37/300 - x1^2 - x2^2");
    assert_eq!(s.risk.rational(), &BigRational::new(1.into(), 10.into()));
    assert_eq!(s.vars.name(3), "w");
}

/// Each kind of broken scene gives one error naming the field.
#[test]
fn broken_scenes_name_the_field() {
    type Edit = fn(&mut serde_json::Value);
    let cases: Vec<(&str, Edit, &str)> = vec![
        ("unknown top-level field", |v| v["colour"] = "red".into(), "unknown field `colour`"),
        ("wrong format", |v| v["format"] = "riskplan-scene/2".into(), "format"),
        ("dim zero", |v| v["dim"] = 0.into(), "dim"),
        ("workspace length", |v| v["workspace"]["lower"] = serde_json::json!([0]), "workspace.lower"),
        ("empty workspace", |v| v["workspace"]["upper"] = serde_json::json!([1, -1]), "workspace.upper[1]"),
        ("horizon reversed", |v| v["horizon"] = serde_json::json!([1, 0]), "horizon"),
        // bounds that are not finite floats, a box whose sides or diagonal overflow, a
        // horizon that is one float
        (
            "workspace bound -1e400",
            |v| v["workspace"]["lower"] = serde_json::json!(["-1e400", -1]),
            "workspace.upper[0]",
        ),
        (
            "workspace side overflows",
            |v| v["workspace"] = serde_json::json!({"lower": [-1e308, -1], "upper": [1e308, 1]}),
            "workspace.upper[0]",
        ),
        (
            "workspace diagonal overflows",
            |v| v["workspace"] = serde_json::json!({"lower": [-8e307, -8e307], "upper": [8e307, 8e307]}),
            "workspace",
        ),
        ("horizon one float", |v| v["horizon"] = serde_json::json!(["1e18", "1000000000000000000.001"]), "horizon"),
        ("risk 1.5", |v| v["risk"] = 1.5.into(), "risk"),
        ("risk as text", |v| v["risk"] = "ten percent".into(), "risk"),
        ("undeclared parameter", |v| v["obstacles"][0]["poly"] = "q^2 - x1^2".into(), "obstacles[0].poly"),
        ("x3 in a 2-D scene", |v| v["obstacles"][0]["poly"] = "w - x3".into(), "obstacles[0].poly"),
        ("poly syntax", |v| v["obstacles"][0]["poly"] = "w^2 - - * x1".into(), "obstacles[0].poly"),
        ("duplicate id", |v| v["obstacles"][1] = v["obstacles"][0].clone(), "obstacles[1].id"),
        ("uniform low ≥ high", |v| v["params"]["w"]["high"] = 0.2.into(), "params.w.high"),
        (
            "negative std",
            |v| v["params"]["w"] = serde_json::json!({"dist": "normal", "mean": 0, "std": -1}),
            "params.w.std",
        ),
        (
            "beta alpha 0",
            |v| v["params"]["w"] = serde_json::json!({"dist": "beta", "alpha": 0, "beta": 2}),
            "params.w.alpha",
        ),
        (
            "weights not summing to 1",
            |v| v["params"]["w"] = serde_json::json!({"dist": "discrete", "values": [0.3, 0.4], "weights": [0.5, 0.6]}),
            "params.w.weights",
        ),
        (
            "too few raw moments",
            |v| v["params"]["w"] = serde_json::json!({"dist": "moments", "raw": [0.35, 0.125]}),
            "params.w",
        ),
        ("unknown distribution", |v| v["params"]["w"]["dist"] = "unifrom".into(), "params.w"),
        ("unknown distribution field", |v| v["params"]["w"]["mean"] = 0.into(), "params.w"),
        ("start outside", |v| v["start"] = serde_json::json!([-2, 0]), "start"),
        (
            "goal without start",
            |v| {
                v.as_object_mut().unwrap().remove("start");
            },
            "start",
        ),
        (
            "reserved parameter name",
            |v| v["params"]["t"] = serde_json::json!({"dist": "uniform", "low": 0, "high": 1}),
            "params.t",
        ),
        (
            "missing obstacles",
            |v| {
                v.as_object_mut().unwrap().remove("obstacles");
            },
            "missing field `obstacles`",
        ),
        ("degree too high", |v| v["obstacles"][0]["poly"] = "w - x1^9".into(), "obstacles[0].poly"),
    ];
    for (what, edit, expect) in cases {
        let mut v = base();
        if what == "duplicate id" {
            v["obstacles"].as_array_mut().unwrap().push(serde_json::Value::Null);
        }
        edit(&mut v);
        let e = load(&v).expect_err(what).to_string();
        assert!(e.contains(expect), "{what}: error '{e}' does not mention '{expect}'");
        assert!(!e.contains('\n'), "{what}: error is not one line: {e}");
    }
    assert!(Scene::from_json("{ not json").unwrap_err().to_string().contains("line 1"));
}

#[test]
fn shared_parameter_is_one_random_variable() {
    let mut v = base();
    v["obstacles"] = serde_json::json!([
        {"id": "a", "poly": "w - 0.35 + 0*x1"},
        {"id": "b", "poly": "w - 0.35 + 0*x2"}
    ]);
    let s = load(&v).unwrap();
    let mc = s.mc_model().unwrap();
    let h = mc.hits(&[vec![0.0, 0.0, 0.0]], 1000, 1);
    // the same draws of w decide both obstacles
    assert_eq!(h[0][0], h[0][1]);
    assert!(h[0][0] > 400 && h[0][0] < 600);
}

/// Valid-looking scenes that would cost seconds to minutes of exact arithmetic are
/// refused with an error naming the field and the limit.
#[test]
fn costly_scenes_are_refused_by_named_limits() {
    let refused = |edit: &dyn Fn(&mut serde_json::Value), field: &str, words: &str| {
        let mut v = base();
        edit(&mut v);
        let Err(e) = load(&v) else { panic!("{field}: the scene was accepted") };
        assert!(e.path.starts_with(field), "{field}: {e}");
        assert!(e.to_string().contains(words), "{field}: {e}");
    };
    // 300 atoms with unrelated rational weights (took 18 s to expand)
    refused(
        &|v| {
            let n = 300;
            let weights: Vec<String> = (0..n).map(|i| format!("1/{}", 2 * n + i)).collect();
            v["params"]["w"] = serde_json::json!({"dist": "discrete", "values": vec![0.35; n], "weights": weights});
        },
        "params.w.values",
        "at most 64 values",
    );
    // 60 atoms, but weights with ever new prime denominators
    refused(
        &|v| {
            let primes: Vec<u64> =
                (1_000_000u64..).filter(|n| (2..*n).take_while(|d| d * d <= *n).all(|d| n % d != 0)).take(60).collect();
            let mut w: Vec<String> = primes.iter().map(|p| format!("1/{p}")).collect();
            w.push("1".into());
            let n = w.len();
            v["params"]["w"] = serde_json::json!({"dist": "discrete", "values": vec![0.35; n], "weights": w});
        },
        "params.w.weights",
        "common denominator",
    );
    refused(
        &|v| v["params"]["w"] = serde_json::json!({"dist": "beta", "alpha": "1e4000", "beta": 2}),
        "params.w",
        "exact-number limits",
    );
    refused(
        &|v| v["params"]["w"] = serde_json::json!({"dist": "moments", "raw": vec![0.1; 100]}),
        "params.w.raw",
        "at most 64 raw moments",
    );
    // 1287 terms: over MAX_TERMS (took 2.3 s to build)
    refused(
        &|v| {
            v["params"]["w2"] = serde_json::json!({"dist": "uniform", "low": 0, "high": 1});
            v["obstacles"][0]["poly"] = "0.00001*(x1+x2+t+w+w2+1)^8 - 1".into();
        },
        "obstacles[0].poly",
        "terms after expansion exceed the limit",
    );
    // many mid-sized obstacles: over the scene's contour budget
    refused(
        &|v| {
            let obs: Vec<_> = (0..12)
                .map(|i| serde_json::json!({"id": format!("o{i}"), "poly": format!("0.00001*(x1+x2+t+w+{})^8 - 1", i + 1)}))
                .collect();
            v["obstacles"] = serde_json::json!(obs);
        },
        "obstacles[",
        "exact term products",
    );
    // nested powers in an obstacle
    refused(&|v| v["obstacles"][0]["poly"] = "(((x1+1)^32)^32)^32".into(), "obstacles[0].poly", "degree");
}
