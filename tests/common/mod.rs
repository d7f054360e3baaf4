//! Shared helpers of the integration tests.
#![allow(dead_code)]

use riskplan::scene::Scene;
use std::path::PathBuf;

/// The reference scenes with a start and a goal.
pub const PLANNING_SCENES: [&str; 6] = [
    "illustrative-3",
    "illustrative-4",
    "example-b-lane-change",
    "example-c-delivery",
    "example-d1-cluttered-2d",
    "example-d2-cluttered-3d",
];

/// The reference scenes (`shared/reference/scenes` beside the repository, or
/// `RISKPLAN_REFERENCE_SCENES`). Missing scenes fail the tests: they are required.
pub fn reference_dir() -> PathBuf {
    if let Ok(d) = std::env::var("RISKPLAN_REFERENCE_SCENES") {
        return PathBuf::from(d);
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/reference/scenes")
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

/// The `riskplan` binary built for these tests.
pub fn bin() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_riskplan"))
}
