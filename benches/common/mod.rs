//! Shared by the benches: loading a reference scene.

use riskplan_scene::Scene;

/// A reference scene of the repository's `scenes/` by stem (`illustrative-3`).
pub fn reference_scene(stem: &str) -> Scene {
    Scene::from_json(&reference_text(stem)).expect("valid scene")
}

/// The text of a reference scene file.
pub fn reference_text(stem: &str) -> String {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    std::fs::read_to_string(format!("{dir}/{stem}.json")).expect("reference scene")
}

/// The growth family: `n` uncertain disks at constant density (workspace
/// side `10·√n`), seeded, start and goal at opposite corners. Each disk has a radius
/// uncertain by a uniform scale and a centre uncertain by a normal offset; disks that
/// would cover the corners are moved. Returns scene JSON.
#[allow(dead_code)]
pub fn disks_scene(n: usize, seed: u64) -> String {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let side = 10.0 * (n as f64).sqrt();
    let mut params = serde_json::Map::new();
    let mut obstacles = Vec::new();
    let mut k = 0;
    while obstacles.len() < n {
        let (cx, cy): (f64, f64) = (rng.random_range(0.0..side), rng.random_range(0.0..side));
        let r: f64 = rng.random_range(0.8..1.6);
        let near = |x: f64, y: f64| ((cx - x).powi(2) + (cy - y).powi(2)).sqrt() < r + 3.0;
        if near(0.5, 0.5) || near(side - 0.5, side - 0.5) {
            continue;
        }
        k += 1;
        params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
        params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
        let (cx, cy, r) = ((cx * 100.0).round() / 100.0, (cy * 100.0).round() / 100.0, (r * 100.0).round() / 100.0);
        obstacles.push(serde_json::json!({
            "id": format!("disk{k}"),
            "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - {cy})^2"),
        }));
    }
    serde_json::json!({
        "format": "riskplan-scene/1",
        "name": format!("disks-{n}"),
        "dim": 2,
        "workspace": {"lower": [0, 0], "upper": [side, side]},
        "horizon": [0, 1],
        "risk": 0.05,
        "params": params,
        "obstacles": obstacles,
        "start": [0.5, 0.5],
        "goal": [side - 0.5, side - 0.5],
    })
    .to_string()
}
