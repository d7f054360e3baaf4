//! # riskplan
//!
//! Continuous-time risk-bounded trajectory planning with *certified* risk
//! contours, after Jasour, Han and Williams, "Convex Risk Bounded Continuous-Time
//! Trajectory Planning in Uncertain Nonconvex Environments" (RSS 2021).
//!
//! An obstacle is the set `{x : P(x, ω, t) ≥ 0}` with uncertain parameters ω. From
//! the moments of ω the polynomials E\[P\] and E\[P²\] in (x, t) give, for a risk
//! level Δ, the Cantelli inner approximation of the Δ-risk contour (eqs. 10, 12):
//!
//! ```text
//! Ĉ^Δ = { x : E\[P\]² − (1−Δ)·E\[P²\] ≥ 0,  −E\[P\] ≥ 0 }
//! ```
//!
//! Every point of Ĉ^Δ has probability of collision with that obstacle at most Δ
//! (Theorem 1). The guarantee is **per obstacle and per instant**; with several
//! obstacles the total probability of collision can reach (number of obstacles)·Δ.
//!
//! ## The API
//!
//! What a user of the library needs is re-exported here, flat: a [`Scene`] (from its
//! JSON, scene format v1) and its [`Trajectory`]; a [`PlanRequest`] naming a
//! [`PlannerKind`], a [`RiskLevel`] and a [`RiskMode`], run to a [`PlanOutcome`] (or a
//! typed [`PlanError`]); [`verify()`] with its [`VerifyReport`] and the Monte Carlo
//! [`audit_trajectory`]; a [`SceneKernel`] to share what checkers cache across plans and
//! verifications of one scene. The Zenoh service and its Rust client are [`service`]
//! (feature `service`), the command line `cli` (feature `cli`).
//!
//! ```
//! use riskplan::{verify, Method, PlanRequest, PlannerKind, RiskLevel, Scene, SceneKernel};
//! use std::sync::Arc;
//! let text = std::fs::read_to_string("scenes/illustrative-3.json").unwrap();
//! // the scene with what its checkers cache, shared by the plan and the verification
//! let kernel = SceneKernel::from(Arc::new(Scene::from_json(&text).unwrap()));
//! let delta = RiskLevel::from_f64(0.05).unwrap();
//! let request = PlanRequest { planner: PlannerKind::RrtSos, delta: Some(delta), ..Default::default() };
//! let (problem, outcome) = request.run(&kernel, None).unwrap();
//! if let Some(trajectory) = &outcome.trajectory {
//!     let report = verify(&kernel, trajectory, &problem.delta, Method::Exact, &Default::default());
//!     assert!(report.safe);
//! }
//! ```
//!
//! ## Layers
//!
//! Bottom to top (docs/architecture.md; `tests/integration/architecture.rs` fails on
//! any import that runs upward or loops): `poly` → `moments`, `sdp` → `contour`, `relax`
//! → `mc` → `scene` → `motion` → `certify` → `plan`, `verify` → `app` → `service`,
//! `viz` → `cli`. The core (below `app`) does no I/O and has no async code. The modules
//! are internal: public (for the tests, benches and the testkit) only with the feature
//! `test-support`, which a release build never has.
//!
//! Section numbers (§) in the doc comments refer to `docs/design.md`, the project's
//! design document; equation numbers refer to the paper.
#![warn(missing_docs)]

/// Declares the internal modules: `pub(crate)`, public with the feature
/// `test-support` (the tests, benches, the testkit and the fuzz targets). Without it,
/// what only those use is unused here, so `dead_code` and `unused_imports` are not
/// reported for it; the `test-support` build (`cargo clippy --all-features`, the quick
/// tier's core clippy) still reports both.
macro_rules! internal {
    ($($(#[$attr:meta])* $name:ident;)*) => {
        $(
            $(#[$attr])*
            #[cfg(feature = "test-support")]
            pub mod $name;
            $(#[$attr])*
            #[cfg(not(feature = "test-support"))]
            #[allow(dead_code, unused_imports)]
            pub(crate) mod $name;
        )*
    };
}

internal! {
    app;
    certify;
    contour;
    mc;
    moments;
    motion;
    plan;
    poly;
    relax;
    scene;
    sdp;
    verify;
    #[cfg(feature = "cli")]
    viz;
    #[cfg(any(feature = "cli", feature = "proto"))]
    names;
}

#[cfg(feature = "cli")]
pub mod cli;
#[cfg(feature = "proto")]
pub mod service;

pub use crate::app::{PlanRequest, PreparedPlan, DEFAULT_TIME_LIMIT};
pub use crate::certify::scene::{Method, SceneKernel};
pub use crate::certify::sos::SosSettings;
pub use crate::contour::{RiskContour, RiskLevel, RiskLevelError};
pub use crate::motion::Termination;
pub use crate::plan::rrt::smooth::SmoothStats;
pub use crate::plan::{
    FinalCheckStats, Kinematics, LadderStep, NoPlanReason, PlanError, PlanOutcome, PlanStats, PlanStatus, PlannerKind,
    Problem, RiskMode, SdpStats, UnknownName,
};
pub use crate::scene::{
    Obstacle, Param, Piece, Scene, SceneError, SceneErrorKind, SceneFile, Trajectory, TrajectoryError, Workspace,
};
pub use crate::verify::{
    audit_trajectory, verify, verify_until, Audit, AuditOptions, ConstraintReport, Exceedance, MethodReport,
    ObstacleReport, PieceReport, VerifyReport,
};
