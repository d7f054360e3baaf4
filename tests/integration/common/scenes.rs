//! The repository's scene files and the test tiers' sizes: shared by the integration
//! tests of the root package and of `riskplan-app` (each includes this file).

use riskplan_scene::Scene;
use std::path::PathBuf;

/// The repository's root: the first ancestor of this crate's folder that holds `scenes/`.
pub fn repo() -> PathBuf {
    let here = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    here.ancestors().find(|p| p.join("scenes").is_dir()).unwrap_or(here).to_path_buf()
}

/// The reference scenes with a start and a goal.
pub const PLANNING_SCENES: [&str; 6] = [
    "illustrative-3",
    "illustrative-4",
    "example-b-lane-change",
    "example-c-delivery",
    "example-d1-cluttered-2d",
    "example-d2-cluttered-3d",
];

/// The reference scenes: the repository's `scenes/` (the paper's experiments).
/// Missing scenes fail the tests: they are required.
pub fn reference_dir() -> PathBuf {
    repo().join("scenes")
}

/// Whether this run is the full tier (`RISKPLAN_TEST_TIER=full`, set by
/// `scripts/test.sh`) rather than the quick edit-loop tier (`scripts/quick.sh`).
pub fn full_tier() -> bool {
    std::env::var("RISKPLAN_TEST_TIER").is_ok_and(|v| v == "full")
}

/// A test size: `quick` in the quick tier, `full` in the full tier; an explicit
/// `RISKPLAN_<name>` (e.g. `RISKPLAN_DIFF_CASES=1000`) overrides both.
pub fn size(name: &str, quick: usize, full: usize) -> usize {
    std::env::var(format!("RISKPLAN_{name}")).ok().and_then(|v| v.parse().ok()).unwrap_or(if full_tier() {
        full
    } else {
        quick
    })
}

/// Every reference scene file, sorted by name.
pub fn reference_files() -> Vec<PathBuf> {
    let dir = reference_dir();
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("reference scenes not found at {}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    v.sort();
    assert!(v.len() >= 10, "expected the 10 reference scenes in {}", dir.display());
    v
}

/// Loads one reference scene by stem (`illustrative-3`).
pub fn scene(name: &str) -> Scene {
    let p = reference_dir().join(format!("{name}.json"));
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    Scene::from_json(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}
