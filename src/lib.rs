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
//! The library is a workspace whose crates are its layers (docs/architecture.md), bottom
//! to top: `riskplan-math` (polynomials, moments, SDP, contours, relaxations, Monte Carlo)
//! → `riskplan-scene` (scenes, trajectories, the planner–checker vocabulary) →
//! `riskplan-certify` (eq. 15 deciders, covers, the whole-path bound, the scene
//! certifier) → `riskplan-plan` (the planners) → `riskplan-app` (plan requests,
//! verification reports, the final check) → `riskplan-service` (the Zenoh service) → this
//! crate (the CLI and figures). A crate sees only the crates below it: an upward `use`
//! does not compile. The layers below the service do no I/O and have no async code.
//!
//! Section numbers (§) in the doc comments refer to `docs/design.md`, the project's
//! design document; equation numbers refer to the paper.
#![warn(missing_docs)]

#[cfg(feature = "cli")]
pub mod cli;
#[cfg(feature = "cli")]
pub mod viz;
/// The Zenoh service and its Rust client (crate `riskplan-service`).
#[cfg(feature = "proto")]
pub use riskplan_service as service;

pub use riskplan_app::verify::{
    audit_trajectory, verify, verify_until, Audit, AuditOptions, ConstraintReport, Exceedance, MethodReport,
    ObstacleReport, PieceReport, VerifyReport,
};
pub use riskplan_app::{PlanRequest, PreparedPlan, DEFAULT_TIME_LIMIT};
pub use riskplan_certify::checker::{Method, SceneKernel};
pub use riskplan_certify::positivity::sos::SosSettings;
pub use riskplan_math::contour::{RiskContour, RiskLevel, RiskLevelError};
pub use riskplan_plan::rrt::smooth::SmoothStats;
pub use riskplan_plan::{
    FinalCheckStats, Kinematics, LadderStep, NoPlanReason, PlanError, PlanOutcome, PlanStats, PlanStatus, PlannerKind,
    Problem, RiskMode, SdpStats, UnknownName,
};
pub use riskplan_scene::motion::Termination;
pub use riskplan_scene::{
    Obstacle, Param, Piece, Scene, SceneError, SceneErrorKind, SceneFile, Trajectory, TrajectoryError, Workspace,
};
