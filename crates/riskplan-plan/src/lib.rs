//! Planning (layer L3): one planner interface, OMPL-like, so planners are
//! interchangeable and testable alone (docs/architecture.md).
//!
//! - [`Problem`] (`problem.rs`): the problem definition (scene, start, goal, horizon,
//!   Δ, seed).
//! - [`MotionChecker`]: decides whether a trajectory piece is acceptable — the
//!   continuous-time certifier of eq. (15), or a sampling judge for the Monte Carlo
//!   baseline (which is marked unsound).
//! - [`Termination`]: deadline and cancellation flag, polled often.
//! - [`Planner::solve`] returns a [`PlanOutcome`] (`outcome.rs`: status, trajectory,
//!   stats) or a typed [`PlanError`] for bad requests.
//! - [`PlannerKind`]: every planner a request can name, each with its
//!   [`PlannerSpec`] — how to build it and its checker from a [`Setup`].
//!
//! The planners live in folders: `rrt/` (the default and the paper's RRT-SOS, with
//! smoothing, sampling and scale), `mc_rrt/` (the Monte Carlo baseline), `opt/` (the
//! optimisation planners' shared ladder, `tv_sos/` and `moment/`). A new planner is a
//! folder here and one entry in [`PlannerKind`].
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan-app`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan_app::PlanRequest;
//! ```

mod outcome;
mod path;
mod problem;

pub mod mc_rrt;
pub mod opt;
pub mod receding;
pub mod rrt;
pub mod testing;

pub use mc_rrt::{McChecker, McCheckerParams};
pub use opt::moment::{MomentForm, MomentParams, MomentPlanner};
pub use opt::tv_sos::{TvSos, TvSosParams};
pub use opt::RungFailure;
pub use outcome::{
    FinalCheckStats, LadderStep, NoPlanReason, PlanError, PlanOutcome, PlanStats, PlanStatus, Progress, SdpStats,
};
pub use path::{constant_speed, nearest, within_speed, SPEED_BOUND_ROUNDING, SPEED_SUBINTERVALS};
pub(crate) use path::{taylor_shift, trajectory_length};
pub use problem::Problem;
pub use rrt::{
    rrt_planner, scale, smooth, ConnectParams, ConnectRrt, LayeredParams, LayeredRrt, RrtParams, StaticRrt,
    StripeSampler,
};

pub use riskplan_scene::motion::{dist, CheckCounter, Motion, MotionChecker, Termination};

use riskplan_certify::checker::{Method, SceneKernel};
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_scene::{PlannerBlock, Scene};
use std::fmt;
use std::str::FromStr;
use std::time::Instant;
use thiserror::Error;

/// A planner. Each `solve` starts afresh: the same problem (and seed) gives the same
/// outcome however often it is called.
pub trait Planner: Send {
    /// Name (`rrt-sos`, `mc-rrt`, ...).
    fn name(&self) -> &'static str;
    /// Plans, polling `term`.
    fn solve(&mut self, p: &Problem, checker: &dyn MotionChecker, term: &Termination)
        -> Result<PlanOutcome, PlanError>;
}

/// The planners a request can name. Each entry's `PlannerSpec` (in its folder) says
/// how to build it; adding a planner is its folder and one entry here
/// (docs/architecture.md). On the wire and in the JSON Schemas it is its
/// [`as_str`](PlannerKind::as_str) name ([`riskplan_scene::closed_set!`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum PlannerKind {
    /// The default: every edge certified in continuous time (eq. 15) — bidirectional
    /// RRT on static scenes, the time-layered tree with the piece ladder on moving
    /// ones — then certified shortcutting and C¹ corner blends.
    #[default]
    RrtSos,
    /// The paper's RRT-SOS as published (static tree with widening stripes, or the
    /// time-layered tree), for reproducing the paper's numbers; straight pieces.
    RrtSosPaper,
    /// The Monte Carlo baseline: the default planner's search with the paper's
    /// sampling edge check (K scenarios × W waypoints per edge): uncertified, its plans
    /// say `certified: false`.
    McRrt,
    /// The paper's time-varying SOS planner (Section V-B): a moment relaxation over
    /// straight pieces with convex–concave rank iterations, every piece of the
    /// read-out certified; a retry ladder (seeds, iterations, pieces, tighter Δ_opt).
    TvSos,
    /// The paper's standard SOS planner with average risk (Section V-A.2): Lasserre's
    /// moment relaxation over piecewise-linear trajectories, atoms extracted, every
    /// piece of an atom's trajectory certified against the per-instant Δ.
    Moment,
    /// The standard SOS planner over one polynomial trajectory of degree `d` (the
    /// scene's `planner.standard_sos.polynomial_trajectory_degree`, else 2).
    MomentPoly,
    /// Receding-horizon planning from the robot's current state (docs/design.md §6.9):
    /// what a receding request runs.
    Receding,
}

impl PlannerKind {
    /// Every planner, in the order help texts list them.
    pub const ALL: [PlannerKind; 7] = [
        PlannerKind::RrtSos,
        PlannerKind::RrtSosPaper,
        PlannerKind::McRrt,
        PlannerKind::TvSos,
        PlannerKind::Moment,
        PlannerKind::MomentPoly,
        PlannerKind::Receding,
    ];

    /// The name on the command line and on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            PlannerKind::RrtSos => "rrt-sos",
            PlannerKind::RrtSosPaper => "rrt-sos-paper",
            PlannerKind::McRrt => "mc-rrt",
            PlannerKind::TvSos => "tv-sos",
            PlannerKind::Moment => "moment",
            PlannerKind::MomentPoly => "moment-poly",
            PlannerKind::Receding => "receding",
        }
    }

    /// Whether this planner's plans are certified (its checker is sound).
    pub fn certifies(self) -> bool {
        self.spec().certified
    }

    /// How this planner is built, and what it is.
    pub fn spec(self) -> &'static PlannerSpec {
        match self {
            PlannerKind::RrtSos => &rrt::DEFAULT,
            PlannerKind::RrtSosPaper => &rrt::PAPER,
            PlannerKind::McRrt => &mc_rrt::SPEC,
            PlannerKind::TvSos => &opt::tv_sos::SPEC,
            PlannerKind::Moment => &opt::moment::PIECEWISE_LINEAR,
            PlannerKind::MomentPoly => &opt::moment::POLYNOMIAL,
            PlannerKind::Receding => &receding::SPEC,
        }
    }

    /// The planner and its motion checker for `setup`, every option checked (typed
    /// errors).
    pub fn build(self, setup: &Setup<'_>) -> Result<Built, PlanError> {
        (self.spec().build)(setup)
    }
}

riskplan_scene::closed_set!(PlannerKind, "PlannerKind");

impl fmt::Display for PlannerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for PlannerKind {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        PlannerKind::ALL.into_iter().find(|k| k.as_str() == s).ok_or_else(|| UnknownName {
            what: "planner",
            name: s.to_string(),
            expected: PlannerKind::ALL.map(|k| k.as_str()).join(", "),
        })
    }
}

/// What a planner is and how it is built: one per [`PlannerKind`], defined in the
/// planner's folder.
pub struct PlannerSpec {
    /// Whether its plans are certified (its checker is sound).
    pub certified: bool,
    /// The planner and its checker for a request.
    pub build: fn(&Setup<'_>) -> Result<Built, PlanError>,
    /// The runs of the paper's benchmark table on a scene (`riskplan bench`): none when
    /// the paper did not run this planner there.
    pub paper_runs: fn(&Scene) -> Vec<PaperRun>,
}

/// One row of the paper's benchmark table (`riskplan bench --suite paper`).
#[derive(Clone, Debug, PartialEq)]
pub struct PaperRun {
    /// The row's label (`rrt-sos-paper --improve`).
    pub label: &'static str,
    /// The improve step.
    pub improve: bool,
    /// The key of the paper's time in the scene's `expected.run_time_s`, if any.
    pub paper_key: Option<&'static str>,
}

/// Everything a planner is built from: the problem, the scene's kernel, the risk level
/// of each obstacle and the request's options.
pub struct Setup<'a> {
    /// The problem.
    pub problem: &'a Problem,
    /// The scene's kernel (what certifying checkers cache).
    pub kernel: &'a SceneKernel,
    /// The risk level Δᵢ of each obstacle.
    pub deltas: &'a [RiskLevel],
    /// The request's options.
    pub options: &'a PlanOptions,
}

impl Setup<'_> {
    /// The scene's `planner` block, if any.
    pub fn block(&self) -> Option<&PlannerBlock> {
        self.problem.scene.file.planner.as_ref()
    }

    /// The kinematics of this plan: the request's, else the scene's block's — merged
    /// here once, for every planner (each checks the limits it uses, in its own order).
    pub fn kinematics(&self) -> Kinematics {
        self.options.kinematics.merged(self.block())
    }
}

/// The checker a plan is made again with when its final check refuses a piece the
/// planner's checker accepted (docs/design.md §5.12): the exact decision with the plan's
/// bounds and risk levels, without the fast path, and in trajectory mode with the
/// plan's whole-path budget. Every certifying planner's checker is a scene certifier, so
/// this one replaces it for any of them.
pub fn fallback_checker(s: &Setup<'_>) -> Box<dyn MotionChecker> {
    let mut checker =
        riskplan_certify::checker::SceneCertifier::with_deltas(s.kernel, s.deltas.to_vec(), Method::Exact)
            .with_bounds(s.options.bounds)
            .without_fast_path();
    if let Some(budget) = rrt::path_budget(s.problem, s.options) {
        checker = checker.with_path_risk(budget * rrt::PATH_RISK_NEGLIGIBLE_SHARE);
    }
    Box::new(checker)
}

/// A planner with the motion checker it consults.
pub struct Built {
    /// The planner.
    pub planner: Box<dyn Planner>,
    /// Its motion checker.
    pub checker: Box<dyn MotionChecker>,
}

/// What Δ bounds (docs/design.md §3.6). On the wire: its [`as_str`](RiskMode::as_str) name
/// ([`riskplan_scene::closed_set!`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum RiskMode {
    /// The paper's: the probability of colliding with each obstacle, at each instant, is
    /// at most Δ.
    #[default]
    PerObstacle,
    /// The probability of colliding with any obstacle at each instant is at most Δ:
    /// obstacle `i` gets Δᵢ with Σ Δᵢ = Δ (Boole's inequality), Δᵢ = Δ/N.
    JointUniform,
    /// As `JointUniform`, with Δ split by need: each obstacle first gets what the start
    /// and the goal need (1.01 × its Cantelli bound there), the rest by weight
    /// `1/(1 + d/L)`, `d` the distance of the obstacle's proven cover from the
    /// start–goal line, `L` the workspace's largest side: more for the obstacles that
    /// constrain the path.
    JointWeighted,
    /// Δ bounds the probability of meeting any obstacle at any time along the whole plan,
    /// ω drawn once (docs/design.md §5.14): the default planners keep the accumulated
    /// whole-path bound of each partial path (the sum of its edges' bounds, Boole) and
    /// accept an edge only within Δ; shortcuts keep the sum within Δ, and blends are kept
    /// only when the smoothed plan's bound is; every plan's pooled bound is proven ≤ Δ by
    /// the final check. Each obstacle's per-instant constraint at Δ is still certified
    /// (it is implied: P(x(t) in Oᵢ) ≤ P(∃ t, i : x(t) in Oᵢ) ≤ Δ).
    Trajectory,
}

impl RiskMode {
    /// Every mode.
    pub const ALL: [RiskMode; 4] =
        [RiskMode::PerObstacle, RiskMode::JointUniform, RiskMode::JointWeighted, RiskMode::Trajectory];
    /// The name on the command line and on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            RiskMode::PerObstacle => "per-obstacle",
            RiskMode::JointUniform => "joint",
            RiskMode::JointWeighted => "joint-weighted",
            RiskMode::Trajectory => "trajectory",
        }
    }
}

riskplan_scene::closed_set!(RiskMode, "RiskMode");

impl FromStr for RiskMode {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        RiskMode::ALL.into_iter().find(|k| k.as_str() == s).ok_or_else(|| UnknownName {
            what: "risk_mode",
            name: s.to_string(),
            expected: RiskMode::ALL.map(|k| k.as_str()).join(", "),
        })
    }
}

/// A name that is not one of the accepted ones.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("unknown {what} '{name}' ({expected})")]
pub struct UnknownName {
    /// What was named (`planner`).
    pub what: &'static str,
    /// The name given.
    pub name: String,
    /// The accepted names.
    pub expected: String,
}

/// The robot's kinematic limits and whether to smooth: one value for every planner,
/// merged once from the request and the scene's `planner` block
/// ([`Kinematics::or_block`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Kinematics {
    /// Speed limit (workspace units per time unit); `None`: none.
    pub max_speed: Option<f64>,
    /// Acceleration limit of the corner blends; `None`: none.
    pub max_accel: Option<f64>,
    /// Shortcut and blend the plan (the default planners only).
    pub smooth: bool,
}

impl Kinematics {
    /// Smoothing on, no limits.
    pub const SMOOTH: Kinematics = Kinematics { max_speed: None, max_accel: None, smooth: true };

    /// These values, each limit not given taken from the scene's block (unchecked: see
    /// [`Kinematics::or_block`]).
    pub fn merged(self, block: Option<&PlannerBlock>) -> Kinematics {
        Kinematics {
            max_speed: self.max_speed.or(block.and_then(|b| b.max_speed)),
            max_accel: self.max_accel.or(block.and_then(|b| b.max_accel)),
            smooth: self.smooth,
        }
    }

    /// [`Kinematics::merged`], both limits checked (positive and finite: typed errors).
    pub fn or_block(self, block: Option<&PlannerBlock>) -> Result<Kinematics, PlanError> {
        let k = self.merged(block);
        k.validate()?;
        Ok(k)
    }

    /// Checks both limits: positive and finite when given.
    pub fn validate(&self) -> Result<(), PlanError> {
        for (name, v) in [("max_speed", self.max_speed), ("max_accel", self.max_accel)] {
            if v.is_some_and(|v| !(v > 0.0 && v.is_finite())) {
                return Err(PlanError::InvalidOption {
                    option: name.into(),
                    message: "must be a positive number".into(),
                });
            }
        }
        Ok(())
    }
}

/// The options a request gives every planner (each takes what applies to it and
/// refuses, with a typed error, what does not).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanOptions {
    /// Pieces of the layered planner (`Some` forces it; `None`: the ladder 2, 4, 8, …
    /// on moving-obstacle scenes); the first rung of the optimisation planners.
    pub pieces: Option<usize>,
    /// The improve step of the paper's static planner.
    pub improve: bool,
    /// The request's kinematics (before the scene's block fills what it leaves out).
    pub kinematics: Kinematics,
    /// How certifying checkers certify.
    pub certifier: Method,
    /// What Δ bounds.
    pub risk_mode: RiskMode,
    /// Which risk bounds may prove an edge (docs/design.md §5.13).
    pub bounds: BoundChoice,
}

/// Checks start and goal: inside the workspace and strictly inside every Δ-contour;
/// an unsafe endpoint names the obstacle (from the checker) and the time.
pub fn check_endpoints(p: &Problem, checker: &dyn MotionChecker) -> Result<(), PlanError> {
    p.validate()?;
    for (which, x, t) in [("start", &p.start, p.horizon.0), ("goal", &p.goal, p.horizon.1)] {
        if checker.check_point(x, t) != Motion::Accepted {
            let obstacle = checker.blocking_obstacle(x, t).unwrap_or_default();
            return Err(PlanError::UnsafeEndpoint { which: which.into(), point: x.clone(), t, obstacle });
        }
    }
    Ok(())
}

/// Checks a receding-horizon problem's start: the request's position inside the
/// workspace and strictly inside every Δ-contour at `t_now` (an error naming the field
/// `position` and the obstacle otherwise); the goal inside the workspace (it need not be
/// safe at the window's end: the plan may end elsewhere).
pub fn check_endpoints_receding(p: &Problem, checker: &dyn MotionChecker) -> Result<(), PlanError> {
    p.validate().map_err(|e| match e {
        PlanError::OutsideWorkspace { which, point } if which == "start" => {
            PlanError::OutsideWorkspace { which: "position".into(), point }
        }
        other => other,
    })?;
    let (x, t) = (&p.start, p.horizon.0);
    if checker.check_point(x, t) != Motion::Accepted {
        let obstacle = checker.blocking_obstacle(x, t).unwrap_or_default();
        return Err(PlanError::UnsafeEndpoint { which: "position".into(), point: x.clone(), t, obstacle });
    }
    Ok(())
}

/// Refuses a scene with moving obstacles (the static planners' edges are judged over
/// the whole horizon, which is sound only when nothing moves).
pub fn static_only(p: &Problem) -> Result<(), PlanError> {
    if p.is_dynamic() {
        return Err(PlanError::InvalidOption {
            option: "planner".into(),
            message: "the scene has moving obstacles: use the layered (dynamic) planner".into(),
        });
    }
    Ok(())
}

/// How a planner's `solve` begins: planning, or already answered.
pub(crate) enum Begin {
    /// Go on, with these fresh statistics.
    Plan(PlanStats),
    /// The answer is known before any search (the goal is out of reach).
    Answered(PlanOutcome),
}

/// The start every planner shares: the endpoints checked (typed errors), fresh
/// statistics, the speed limit's reach decided at once, then the checker prepared
/// (under `term`). Each planner validates its own parameters first.
pub(crate) fn begin(
    p: &Problem,
    checker: &dyn MotionChecker,
    term: &Termination,
    max_speed: Option<f64>,
    t_start: Instant,
) -> Result<Begin, PlanError> {
    check_endpoints(p, checker)?;
    let mut stats = PlanStats { checker: checker.name().to_string(), seed: p.seed, ..Default::default() };
    if let Some(r) = out_of_reach(p, max_speed) {
        stats.planning_time_s = t_start.elapsed().as_secs_f64();
        return Ok(Begin::Answered(PlanOutcome::no_plan(PlanStatus::Exhausted, stats, r)));
    }
    checker.prepare(term);
    Ok(Begin::Plan(stats))
}

/// The typed answer for a goal farther than the speed limit can reach over the
/// horizon (the straight line's length over its duration), decided before any search.
pub fn out_of_reach(p: &Problem, max_speed: Option<f64>) -> Option<NoPlanReason> {
    let v = max_speed?;
    let d = dist(&p.start, &p.goal);
    let duration = p.horizon.1 - p.horizon.0;
    (d > v * duration).then_some(NoPlanReason::OutOfReach { distance: d, max_speed: v, duration })
}
