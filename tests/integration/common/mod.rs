//! Shared helpers of the integration tests.
#![allow(dead_code)]

/// The benches' scene families (`disks_scene`: n disks at constant density), shared with
/// the tests that need a crowded scene (the module's `dead_code` allowance covers it).
#[path = "../../../benches/common/mod.rs"]
pub mod growth;
pub mod oracle;
#[cfg(all(feature = "service", feature = "cli"))]
pub mod server;

use riskplan_scene::Scene;
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

/// The reference scenes: the repository's `scenes/` (the paper's experiments).
/// Missing scenes fail the tests: they are required.
pub fn reference_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
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

/// The `riskplan` binary built for these tests.
#[cfg(feature = "cli")]
pub fn bin() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_riskplan"))
}

/// Runs the `riskplan` binary with `args` (OpenBLAS on one thread): (exit status, stdout,
/// stderr).
#[cfg(feature = "cli")]
pub fn run(args: &[&str]) -> (i32, String, String) {
    let out = bin().env("OPENBLAS_NUM_THREADS", "1").args(args).output().expect("run riskplan");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// The path of a reference scene file by stem, as a command-line argument.
pub fn scene_arg(name: &str) -> String {
    reference_dir().join(format!("{name}.json")).to_string_lossy().into()
}
