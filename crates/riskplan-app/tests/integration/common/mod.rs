//! Shared helpers of the application layer's integration tests: the reference scenes and
//! test sizes (the root package's file, included), the benches' scene families, and the
//! independent oracle.
#![allow(dead_code)]

/// The benches' scene families (`disks_scene`: n disks at constant density), shared with
/// the tests that need a crowded scene (the module's `dead_code` allowance covers it).
#[path = "../../../../../benches/common/mod.rs"]
pub mod growth;
pub mod oracle;
#[path = "../../../../../tests/integration/common/scenes.rs"]
mod scenes;
pub use scenes::*;
