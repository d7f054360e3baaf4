//! Shared by the benches: loading a reference scene.

use riskplan::scene::Scene;

/// A reference scene of the repository's `scenes/` by stem (`illustrative-3`).
pub fn reference_scene(stem: &str) -> Scene {
    Scene::from_json(&reference_text(stem)).expect("valid scene")
}

/// The text of a reference scene file.
pub fn reference_text(stem: &str) -> String {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    std::fs::read_to_string(format!("{dir}/{stem}.json")).expect("reference scene")
}
