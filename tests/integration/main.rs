//! The integration tests, as one binary (one link of the dependency graph).
//!
//! Sizes: the differential and random-segment tests run small by default (the quick
//! tier, `scripts/quick.sh`); `RISKPLAN_TEST_TIER=full` (set by `scripts/test.sh`, which
//! CI runs) gives them their full sizes. See `common::tier`.

mod common;

mod architecture;
mod bounds_oracle;
mod certify_differential;
mod certify_exact;
#[cfg(feature = "cli")]
mod cli_core;
#[cfg(feature = "cli")]
mod cli_first_hour;
#[cfg(feature = "cli")]
mod cli_plan;
#[cfg(feature = "cli")]
mod figures;
mod fuzz_replay;
#[cfg(feature = "service")]
mod proto_examples;
mod reference_scenes;
#[cfg(all(feature = "service", feature = "cli"))]
mod service_failover;
#[cfg(all(feature = "service", feature = "cli"))]
mod service_first_hour;
#[cfg(all(feature = "service", feature = "cli"))]
mod service_metrics;
#[cfg(all(feature = "service", feature = "cli"))]
mod service_shutdown;
#[cfg(all(feature = "service", feature = "cli"))]
mod service_warm_up;
