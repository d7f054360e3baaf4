//! # riskplan-testkit
//!
//! What tests, fuzzers and benches need and the product never ships, moved out of the
//! `riskplan` library:
//!
//! - [`fuzzing`]: the fuzz targets of `fuzz/` (cargo-fuzz), also replayed on stable by
//!   riskplan's integration tests (`tests/integration/fuzz_replay.rs`);
//! - [`testgen`]: seeded random univariate polynomials with known answers, for the
//!   differential tests of the exact and SOS certifiers;
//! - [`runner`]: the robustness suite's runner (oracle judgement, plan, Monte Carlo
//!   audit, exact-versus-SOS counts, summary table) over scenes from
//!   [`riskplan_oracle`], and the `robustness` binary that runs it (feature `bench`,
//!   on by default):
//!
//! ```sh
//! cargo run --release -p riskplan-testkit --bin robustness -- --count 120 --suite-seed 1 --out bench-robustness.jsonl
//! ```
//!
//! It uses riskplan's layer crates through their public APIs (the service's messages and
//! handlers without the transport). riskplan's crates list this crate as a
//! dev-dependency only (their integration tests and benches), so a release build never
//! contains it.
#![warn(missing_docs)]

pub mod fuzzing;
pub mod runner;
pub mod testgen;

pub use riskplan_oracle;
