//! Shared by the benches: loading a reference scene.

use riskplan::scene::Scene;

/// A reference scene by stem (`RISKPLAN_REFERENCE_SCENES`, else `../shared/reference/scenes`).
pub fn reference_scene(stem: &str) -> Scene {
    Scene::from_json(&reference_text(stem)).expect("valid scene")
}

/// The text of a reference scene file.
pub fn reference_text(stem: &str) -> String {
    let dir = std::env::var("RISKPLAN_REFERENCE_SCENES")
        .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/reference/scenes").to_string());
    std::fs::read_to_string(format!("{dir}/{stem}.json")).expect("reference scene")
}
