//! The application layer's integration tests, as one binary: plans of every planner
//! through `PlanRequest`, checked against an independent oracle, and `verify` at the
//! kernel's speed.
//!
//! Sizes: the differential and random-segment tests run small by default (the quick
//! tier, `scripts/quick.sh`); `RISKPLAN_TEST_TIER=full` (set by `scripts/test.sh`, which
//! CI runs) gives them their full sizes. See `common::size`.

mod common;

mod certify_scenes;
mod crowd;
mod extreme_scales;
mod optimisation_planners;
mod plan_quality;
mod plan_scenes;
mod smooth_limits;
mod tight_bounds;
mod trajectory_mode;
mod verify_fast;
mod whole_path;
