//! Shared helpers of the integration tests.
#![allow(dead_code)]

/// The benches' scene families (`disks_scene`: n disks at constant density), shared with
/// the tests that need a crowded scene (the module's `dead_code` allowance covers it).
#[path = "../../../benches/common/mod.rs"]
pub mod growth;
#[path = "scenes.rs"]
mod scenes;
pub use scenes::*;
#[cfg(all(feature = "service", feature = "cli"))]
pub mod server;

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
