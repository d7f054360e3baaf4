//! Planning (layer L3): one planner interface, OMPL-like, so planners are
//! interchangeable and testable alone.
//!
//! - [`Problem`]: the problem definition (scene, start, goal, horizon, Δ, seed).
//! - [`MotionChecker`]: decides whether a trajectory piece is acceptable — the
//!   continuous-time certifier of eq. (15) for RRT-SOS, or a sampling judge for the
//!   Monte Carlo baseline (which is marked unsound).
//! - [`Termination`]: deadline and cancellation flag, polled often.
//! - [`Planner::solve`] returns a [`PlanOutcome`] (status, trajectory, stats) or a
//!   typed [`PlanError`] for bad requests.

mod connect;
mod layered;
mod mc_checker;
mod moment;
mod rrt;
mod sampling;
pub mod scale;
pub mod smooth;
#[cfg(any(test, feature = "test-support"))]
pub mod testing;
mod tvsos;

pub use connect::{ConnectParams, ConnectRrt};
pub use layered::{LayeredParams, LayeredRrt};
pub use mc_checker::{McChecker, McCheckerParams};
pub use moment::{extract_atoms, MomentForm, MomentParams, MomentPlanner};
pub use rrt::{RrtParams, StaticRrt};
pub use sampling::StripeSampler;
pub use tvsos::{TvSos, TvSosParams};

pub use crate::motion::{dist, CheckCounter, Motion, MotionChecker, Termination};

use crate::contour::RiskLevel;
use crate::scene::{Piece, Scene, Trajectory};
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;
use thiserror::Error;

/// A planning problem, immutable while a planner runs.
#[derive(Clone, Debug)]
pub struct Problem {
    /// The scene with its cached contours.
    pub scene: Arc<Scene>,
    /// x(t0).
    pub start: Vec<f64>,
    /// x(tf).
    pub goal: Vec<f64>,
    /// `[t0, tf]`.
    pub horizon: (f64, f64),
    /// Risk level Δ (exact, validated).
    pub delta: RiskLevel,
    /// Seed of the planner's RNG.
    pub seed: u64,
}

impl Problem {
    /// The scene's own start, goal, horizon and Δ.
    pub fn from_scene(scene: Arc<Scene>, seed: u64) -> Result<Problem, PlanError> {
        let (Some(start), Some(goal)) = (scene.start.clone(), scene.goal.clone()) else {
            return Err(PlanError::InvalidRequest {
                field: "start".into(),
                message: format!("scene '{}' has no start and goal (a contour-only scene)", scene.name),
            });
        };
        Ok(Problem { horizon: scene.horizon, delta: scene.risk.clone(), start, goal, scene, seed })
    }

    /// Whether any obstacle moves.
    pub fn is_dynamic(&self) -> bool {
        self.scene.obstacles.iter().any(|o| o.contour.is_dynamic())
    }

    /// Checks the request: dimensions, workspace, a non-empty horizon (Δ is a
    /// [`RiskLevel`], valid by construction).
    pub fn validate(&self) -> Result<(), PlanError> {
        let s = &self.scene;
        if !self.horizon.0.is_finite() || !self.horizon.1.is_finite() || self.horizon.0 >= self.horizon.1 {
            return Err(PlanError::InvalidRequest { field: "horizon".into(), message: "needs finite t0 < tf".into() });
        }
        for (name, p) in [("start", &self.start), ("goal", &self.goal)] {
            if p.len() != s.dim {
                return Err(PlanError::InvalidRequest {
                    field: name.into(),
                    message: format!("needs {} coordinates, got {}", s.dim, p.len()),
                });
            }
            if p.iter().any(|v| !v.is_finite()) || !s.workspace.contains(p) {
                return Err(PlanError::OutsideWorkspace { which: name.into(), point: p.clone() });
            }
        }
        Ok(())
    }
}

/// How a planner ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlanStatus {
    /// A trajectory from start to goal.
    Exact,
    /// The deadline passed first.
    DeadlineReached,
    /// Cancelled.
    Cancelled,
    /// The planner's own limits (iterations, attempts) were spent.
    Exhausted,
}

/// What a planner reports about its run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct PlanStats {
    /// Wall time of `solve`, seconds.
    pub planning_time_s: f64,
    /// Time until the first feasible path, seconds.
    pub time_to_feasible_s: Option<f64>,
    /// Time spent in the improve step, seconds.
    pub improve_time_s: f64,
    /// Sampling iterations.
    pub iterations: u64,
    /// Vertices in the tree (all layers).
    pub vertices: u64,
    /// Pieces sent to the motion checker.
    pub edges_checked: u64,
    /// Pieces it accepted.
    pub edges_accepted: u64,
    /// Time inside the motion checker, seconds.
    pub checker_time_s: f64,
    /// Restarts (layered planner).
    pub attempts: u64,
    /// Length of the returned path.
    pub path_length: Option<f64>,
    /// Length before the improve step.
    pub feasible_path_length: Option<f64>,
    /// The motion checker used.
    pub checker: String,
    /// Seed.
    pub seed: u64,
    /// Pieces of the layered planner's successful rung (or the last tried).
    #[serde(default)]
    pub pieces: Option<usize>,
    /// What shortcutting and blending did.
    #[serde(default)]
    pub smoothing: Option<smooth::SmoothStats>,
    /// The risk level Δᵢ of each obstacle in a joint risk mode (obstacle id, Δᵢ).
    #[serde(default)]
    pub risk_allocation: Option<Vec<(String, f64)>>,
    /// The SDPs of an optimisation planner (sizes of the last one built, totals of
    /// all solves).
    #[serde(default)]
    pub sdp: Option<SdpStats>,
    /// The steps of an optimisation planner's retry ladder, in order.
    #[serde(default)]
    pub ladder: Vec<LadderStep>,
    /// The average-risk bound of the standard SOS planner's trajectory: per obstacle,
    /// the largest Cantelli bound of the time-averaged moments over its pieces
    /// (Section V-A.2, a weak guarantee reported beside the certified one).
    #[serde(default)]
    pub average_risk: Option<Vec<(String, f64)>>,
    /// The final check of a certified plan (docs/design.md §5.12); `None` for an
    /// uncertified planner or without a trajectory.
    #[serde(default)]
    pub final_check: Option<FinalCheckStats>,
}

/// What the final check of a certified plan cost and found (docs/design.md §5.12).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct FinalCheckStats {
    /// Wall time of the final checks, seconds (included in `planning_time_s`).
    pub seconds: f64,
    /// Pieces checked.
    pub pieces: usize,
    /// Trajectories the planners' checker accepted and the verify path did not: each
    /// is an internal error (a bug), logged; the plan was made again without the fast
    /// path.
    pub disagreements: u32,
}

/// Sizes and solver totals of an optimisation planner's SDPs.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct SdpStats {
    /// Variables of the last SDP built.
    pub variables: usize,
    /// Constraint rows of the last SDP built.
    pub rows: usize,
    /// PSD constraints of the last SDP built (Gram blocks and affine blocks).
    pub psd_cones: usize,
    /// Largest PSD side of the last SDP built.
    pub largest_psd: usize,
    /// Solves, in all.
    pub solves: u64,
    /// Interior-point iterations, in all.
    pub ipm_iterations: u64,
    /// Time inside the solver, seconds.
    pub solver_time_s: f64,
    /// Time building models and setting up solvers, seconds.
    pub setup_time_s: f64,
}

/// One step of an optimisation planner's retry ladder.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct LadderStep {
    /// Pieces.
    pub pieces: usize,
    /// Seed of the initial point.
    pub seed: u64,
    /// `η` of the tightened risk level `Δ_opt = η·Δ`.
    pub eta: f64,
    /// Convex–concave iterations run.
    pub iterations: usize,
    /// The last Dirac gap `Σ (E[z²] − E[z]²)` (normalised units).
    pub dirac_gap: Option<f64>,
    /// Started from the default RRT-SOS planner's path (else the perturbed straight line).
    #[serde(default)]
    pub from_rrt: bool,
    /// How it ended (`certified`, or why not).
    pub outcome: String,
}

/// Why a planner returned no trajectory (a typed outcome, not an error).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NoPlanReason {
    /// The goal is farther than `max_speed` allows over the horizon (shown at once,
    /// or for the shortest path found).
    OutOfReach {
        /// Distance (or path length) to cover.
        distance: f64,
        /// The speed limit.
        max_speed: f64,
        /// The horizon's duration.
        duration: f64,
    },
    /// The planner's own limits were spent.
    Exhausted {
        /// Sampling iterations.
        iterations: u64,
        /// Edges checked.
        edges_checked: u64,
        /// Layered pieces tried (the ladder), if any.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pieces_tried: Vec<usize>,
        /// An optimisation planner's ladder, step by step.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        ladder: Vec<LadderStep>,
    },
    /// The time limit passed first.
    DeadlineReached {
        /// Sampling iterations.
        iterations: u64,
        /// Edges checked.
        edges_checked: u64,
        /// Layered pieces tried (the ladder), if any.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pieces_tried: Vec<usize>,
        /// An optimisation planner's ladder, step by step.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        ladder: Vec<LadderStep>,
    },
    /// Cancelled.
    Cancelled,
    /// The planned trajectory failed the final check (docs/design.md §5.12) and could
    /// not be planned again: it is not a valid trajectory of the problem (non-finite
    /// numbers, pieces that do not meet, endpoints missed — numeric limits of the
    /// planner), or even the plan made without the fast path was not proven. An
    /// internal error, never returned as certified.
    FinalCheckFailed {
        /// What failed.
        why: String,
    },
}

impl NoPlanReason {
    /// The reason for an unsuccessful status.
    pub fn from_status(status: PlanStatus, stats: &PlanStats, term: &Termination) -> Self {
        let (iterations, edges_checked) = (stats.iterations, stats.edges_checked);
        match status {
            PlanStatus::Cancelled => NoPlanReason::Cancelled,
            _ if term.cancelled() => NoPlanReason::Cancelled,
            PlanStatus::DeadlineReached => NoPlanReason::DeadlineReached {
                iterations,
                edges_checked,
                pieces_tried: Vec::new(),
                ladder: Vec::new(),
            },
            _ => NoPlanReason::Exhausted { iterations, edges_checked, pieces_tried: Vec::new(), ladder: Vec::new() },
        }
    }

    /// One line for messages.
    pub fn message(&self) -> String {
        match self {
            NoPlanReason::OutOfReach { distance, max_speed, duration } => format!(
                "the goal is out of reach: {distance:.6} to cover in {duration} at max_speed {max_speed} (at most {:.6})",
                max_speed * duration
            ),
            NoPlanReason::Exhausted { iterations, edges_checked, pieces_tried, ladder } => format!(
                "no plan within the planner's limits ({iterations} iterations, {edges_checked} edges checked{}{})",
                ladder_text(pieces_tried),
                steps_text(ladder)
            ),
            NoPlanReason::DeadlineReached { iterations, edges_checked, pieces_tried, ladder } => format!(
                "no plan within the time limit ({iterations} iterations, {edges_checked} edges checked{}{})",
                ladder_text(pieces_tried),
                steps_text(ladder)
            ),
            NoPlanReason::Cancelled => "the plan was cancelled".into(),
            NoPlanReason::FinalCheckFailed { why } => {
                format!("internal error: the planned trajectory failed the final check: {why} (reported)")
            }
        }
    }
}

fn steps_text(l: &[LadderStep]) -> String {
    if l.is_empty() {
        return String::new();
    }
    let steps: Vec<String> =
        l.iter().map(|s| format!("{} pieces, seed {}, η {}: {}", s.pieces, s.seed, s.eta, s.outcome)).collect();
    format!("; ladder: {}", steps.join("; "))
}

fn ladder_text(p: &[usize]) -> String {
    if p.is_empty() {
        String::new()
    } else {
        format!(", pieces tried {p:?}")
    }
}

/// The result of a planner run.
#[derive(Clone, Debug)]
pub struct PlanOutcome {
    /// How it ended.
    pub status: PlanStatus,
    /// The trajectory (with `Exact`).
    pub trajectory: Option<Trajectory>,
    /// Whether every piece was accepted by a sound checker.
    pub certified: bool,
    /// Statistics.
    pub stats: PlanStats,
    /// Tree edges, for figures.
    pub tree: Vec<(Vec<f64>, Vec<f64>)>,
    /// Why there is no trajectory (`None` with one).
    pub reason: Option<NoPlanReason>,
}

impl PlanOutcome {
    /// An outcome without a trajectory.
    pub fn no_plan(status: PlanStatus, stats: PlanStats, reason: NoPlanReason) -> Self {
        PlanOutcome { status, trajectory: None, certified: false, stats, tree: Vec::new(), reason: Some(reason) }
    }
}

/// A bad request (the caller's fault); "no plan found" is an outcome, not an error.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PlanError {
    /// A malformed request field.
    #[error("{field}: {message}")]
    InvalidRequest {
        /// Field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// Start or goal outside the workspace.
    #[error("{which}: {point:?} is outside the workspace")]
    OutsideWorkspace {
        /// `start` or `goal`.
        which: String,
        /// The point.
        point: Vec<f64>,
    },
    /// Start or goal not inside the Δ-risk contour of every obstacle.
    #[error("{which}: {point:?} is not in the safe set of the Δ-risk contour of obstacle '{obstacle}' at t = {t} (its risk bound exceeds Δ, or it touches the contour)")]
    UnsafeEndpoint {
        /// `start` or `goal`.
        which: String,
        /// The point.
        point: Vec<f64>,
        /// The time.
        t: f64,
        /// The obstacle whose contour it is not inside (empty when unknown).
        obstacle: String,
    },
    /// Planner options out of range.
    #[error("invalid planner option {option}: {message}")]
    InvalidOption {
        /// Option name.
        option: String,
        /// What is wrong.
        message: String,
    },
}

/// A planner. Each `solve` starts afresh: the same problem (and seed) gives the same
/// outcome however often it is called.
pub trait Planner: Send {
    /// Name (`rrt-sos`, `mc-rrt`, ...).
    fn name(&self) -> &'static str;
    /// Plans, polling `term`.
    fn solve(&mut self, p: &Problem, checker: &dyn MotionChecker, term: &Termination)
        -> Result<PlanOutcome, PlanError>;
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

/// Options every RRT planner takes from a request.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanOptions {
    /// Pieces of the layered planner (`Some` forces it; `None`: the ladder 2, 4, 8, …
    /// on moving-obstacle scenes).
    pub pieces: Option<usize>,
    /// The improve step of the paper's static planner.
    pub improve: bool,
    /// Speed limit (request, else the scene's `planner.max_speed`).
    pub max_speed: Option<f64>,
    /// Acceleration limit for smoothing (request, else the scene's `planner.max_accel`).
    pub max_accel: Option<f64>,
    /// Shortcut and blend the result (the default planners only).
    pub smooth: bool,
}

/// The planner a problem calls for. `paper`: the paper's RRT-SOS (static tree, or the
/// time-layered tree when an obstacle moves or `pieces` is given), parameters from the
/// scene's `planner.rrt_sos` block or scale-free defaults. Otherwise the default: the
/// connect planner on static scenes, the layered planner with the ladder and local
/// sampling on moving ones; both smoothed unless asked not to.
pub fn rrt_planner(p: &Problem, paper: bool, o: &PlanOptions) -> Result<Box<dyn Planner>, PlanError> {
    let block = p.scene.file.planner.as_ref();
    let rrt_block = block.and_then(|b| b.rrt_sos.as_ref());
    let max_speed = o.max_speed.or(block.and_then(|b| b.max_speed));
    let max_accel = o.max_accel.or(block.and_then(|b| b.max_accel));
    for (name, v) in [("max_speed", max_speed), ("max_accel", max_accel)] {
        if v.is_some_and(|v| !(v > 0.0 && v.is_finite())) {
            return Err(PlanError::InvalidOption { option: name.into(), message: "must be a positive number".into() });
        }
    }
    let scale = scale::Scale::of(p);
    let layered = o.pieces.is_some() || p.is_dynamic();
    if o.improve && (layered || !paper) {
        return Err(PlanError::InvalidOption {
            option: "improve".into(),
            message: "applies to the paper's static planner only (rrt-sos-paper on a static scene); the default planner shortcuts its path instead".into(),
        });
    }
    if layered {
        let mut params = if paper { LayeredParams::paper(rrt_block, &scale) } else { LayeredParams::fast(&scale) };
        if o.pieces.is_some() {
            params.pieces = o.pieces;
        }
        params.max_speed = max_speed;
        params.max_accel = max_accel;
        params.smooth = o.smooth && !paper;
        Ok(Box::new(LayeredRrt::new(params)))
    } else if paper {
        let mut params = RrtParams::paper(rrt_block, &scale);
        params.improve = o.improve;
        params.max_speed = max_speed;
        Ok(Box::new(StaticRrt::new(params)))
    } else {
        Ok(Box::new(ConnectRrt {
            params: ConnectParams { smooth: o.smooth, max_speed, max_accel, ..Default::default() },
        }))
    }
}

/// Index of the point of `verts` nearest to `q` (linear scan; 0 when empty).
pub fn nearest(verts: &[Vec<f64>], q: &[f64]) -> usize {
    let mut best = (f64::INFINITY, 0);
    for (i, v) in verts.iter().enumerate() {
        let d = dist(v, q);
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// Straight pieces through `points` at constant speed over `[t0, tf]`.
pub fn constant_speed(points: &[Vec<f64>], horizon: (f64, f64)) -> Vec<Piece> {
    let lens: Vec<f64> = points.windows(2).map(|w| dist(&w[0], &w[1])).collect();
    let total: f64 = lens.iter().sum();
    let n = lens.len();
    let mut times = Vec::with_capacity(n + 1);
    times.push(horizon.0);
    let mut acc = 0.0;
    for (i, l) in lens.iter().enumerate() {
        acc += l;
        let t = if i + 1 == n {
            horizon.1
        } else if total > 0.0 {
            horizon.0 + (horizon.1 - horizon.0) * acc / total
        } else {
            horizon.0 + (horizon.1 - horizon.0) * (i + 1) as f64 / n as f64
        };
        times.push(t);
    }
    // Guard against zero-length time steps from rounding: keep times strictly increasing.
    for i in 1..times.len() {
        if times[i] <= times[i - 1] {
            times[i] = times[i - 1].next_up();
        }
    }
    points.windows(2).enumerate().map(|(i, w)| Piece::segment(&w[0], &w[1], times[i], times[i + 1])).collect()
}

/// Fills an optimisation planner's stats from its counters at the end of its ladder.
pub(crate) fn fill_ladder_stats(
    stats: &mut PlanStats,
    counter: &CheckCounter,
    sdp: SdpStats,
    t_start: Instant,
    ladder: &[LadderStep],
) {
    let (checked, accepted, secs) = counter.totals();
    stats.edges_checked = checked;
    stats.edges_accepted = accepted;
    stats.checker_time_s = secs;
    stats.iterations = sdp.solves;
    stats.attempts = ladder.len() as u64;
    stats.sdp = Some(sdp);
    stats.planning_time_s = t_start.elapsed().as_secs_f64();
    stats.ladder = ladder.to_vec();
}

/// The outcome of an optimisation planner's ladder (tv-sos, moment): the certified pieces
/// found, or the typed reason — cancelled, the deadline (`stopped`), or the ladder
/// exhausted — with the ladder's log. `stats` has every counter filled in already.
pub(crate) fn ladder_outcome(
    found: Option<Vec<Piece>>,
    mut stats: PlanStats,
    sound: bool,
    term: &Termination,
    stopped: bool,
    ladder: Vec<LadderStep>,
) -> PlanOutcome {
    match found {
        Some(pieces) => {
            stats.time_to_feasible_s = Some(stats.planning_time_s);
            stats.pieces = Some(pieces.len());
            let len = trajectory_length(&pieces);
            stats.path_length = Some(len);
            stats.feasible_path_length = Some(len);
            PlanOutcome {
                status: PlanStatus::Exact,
                trajectory: Some(Trajectory::new(pieces)),
                certified: sound,
                stats,
                tree: Vec::new(),
                reason: None,
            }
        }
        None => {
            let (iterations, edges_checked) = (stats.iterations, stats.edges_checked);
            let pieces_tried: Vec<usize> = ladder.iter().map(|s| s.pieces).collect();
            let (status, reason) = if term.cancelled() {
                (PlanStatus::Cancelled, NoPlanReason::Cancelled)
            } else if stopped {
                (
                    PlanStatus::DeadlineReached,
                    NoPlanReason::DeadlineReached { iterations, edges_checked, pieces_tried, ladder },
                )
            } else {
                (PlanStatus::Exhausted, NoPlanReason::Exhausted { iterations, edges_checked, pieces_tried, ladder })
            };
            PlanOutcome::no_plan(status, stats, reason)
        }
    }
}

/// Length of a trajectory: exact for straight pieces, from 64 chords per piece for
/// curved ones (a lower bound that converges quadratically; for reports only).
pub(crate) fn trajectory_length(pieces: &[Piece]) -> f64 {
    pieces
        .iter()
        .map(|pc| {
            if pc.degree() <= 1 {
                return dist(&pc.at(pc.t0), &pc.at(pc.t1));
            }
            const CHORDS: usize = 64;
            let at = |k: usize| pc.at(pc.t0 + (pc.t1 - pc.t0) * k as f64 / CHORDS as f64);
            (0..CHORDS).map(|k| dist(&at(k), &at(k + 1))).sum::<f64>()
        })
        .sum()
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
    if let Some(r) = connect::out_of_reach(p, max_speed) {
        stats.planning_time_s = t_start.elapsed().as_secs_f64();
        return Ok(Begin::Answered(PlanOutcome::no_plan(PlanStatus::Exhausted, stats, r)));
    }
    checker.prepare(term);
    Ok(Begin::Plan(stats))
}

/// Relative rounding allowance of [`within_speed`]'s bound on a curved piece, applied to
/// the magnitudes `Σ_k k·|c_k|·(|m| + r)^(k−1)` that the piece's expansion in absolute time
/// works with (docs/design.md §6.8). Re-expanding a coordinate about `m` sums at most 9
/// terms of at most 10 roundings each; the bound's own powers, products and sums and the
/// final norm add fewer than 30 more for degree ≤ 8 and up to 20 coordinates: fewer than 60
/// roundings of relative size ε/2 in all, which `64·ε` covers with room. Without it the
/// expansion in absolute time, which cancels heavily for a short piece far from t = 0,
/// could hide speed.
pub const SPEED_BOUND_ROUNDING: f64 = 64.0 * f64::EPSILON;

/// Sub-intervals of [`within_speed`]'s bound on a piece of degree ≥ 3.
pub const SPEED_SUBINTERVALS: usize = 64;

/// The coefficients of `x(m + s)` in `s`, for `x(t) = Σ_k row[k]·t^k` (a Taylor shift in
/// floating point: `e_j = Σ_{k ≥ j} C(k, j)·row[k]·m^(k−j)`; the binomials are exact).
pub(crate) fn taylor_shift(row: &[f64], m: f64) -> Vec<f64> {
    (0..row.len())
        .map(|j| {
            let (mut binom, mut pow, mut sum) = (1.0, 1.0, 0.0);
            for (k, &c) in row.iter().enumerate().skip(j) {
                sum += binom * c * pow;
                // C(k + 1, j) = C(k, j)·(k + 1)/(k + 1 − j), an integer
                binom = binom * (k + 1) as f64 / (k + 1 - j) as f64;
                pow *= m;
            }
            sum
        })
        .collect()
}

/// An upper bound on the speed `|ẋ(t)|` of a piece for `|t − m| ≤ r`: each coordinate
/// re-expanded about `m` as `Σ_j e_j (t − m)^j` has `|ẋ| ≤ Σ_j j·|e_j|·r^(j−1)`, plus
/// [`SPEED_BOUND_ROUNDING`] times the magnitudes of the expansion; the coordinates'
/// bounds are combined by the Euclidean norm.
fn speed_bound(pc: &Piece, m: f64, r: f64) -> f64 {
    let scale = m.abs() + r;
    pc.coeffs
        .iter()
        .map(|row| {
            let e = taylor_shift(row, m);
            let tight: f64 = e.iter().enumerate().skip(1).map(|(j, c)| j as f64 * c.abs() * r.powi(j as i32 - 1)).sum();
            let magnitude: f64 =
                row.iter().enumerate().skip(1).map(|(k, c)| k as f64 * c.abs() * scale.powi(k as i32 - 1)).sum();
            let b = tight + SPEED_BOUND_ROUNDING * magnitude;
            b * b
        })
        .sum::<f64>()
        .sqrt()
}

/// Whether a piece's speed stays within `v` (docs/design.md §6.8; every planner's speed
/// check, and every piece smoothing returns under a speed limit):
/// - a straight piece by its chord, `|x(t1) − x(t0)| ≤ v·(t1 − t0)` in floating point;
/// - a piece of degree 2 (a blend) by its end velocities: its velocity is affine in t, so
///   its speed is convex and largest at an end — exact up to [`SPEED_BOUND_ROUNDING`];
/// - a piece of higher degree (an eased part) by the bound of `speed_bound` on each of
///   [`SPEED_SUBINTERVALS`] sub-intervals, expanded about its centre — conservative (by
///   less than 10⁻³ of the peak for the cubic eases smoothing makes: a piece it rejects
///   may in truth be within the limit).
pub fn within_speed(pc: &Piece, v: f64) -> bool {
    match pc.degree() {
        0 | 1 => dist(&pc.at(pc.t0), &pc.at(pc.t1)) <= v * (pc.t1 - pc.t0),
        2 => [pc.t0, pc.t1].iter().all(|&t| speed_bound(pc, t, 0.0) <= v),
        _ => {
            let h = (pc.t1 - pc.t0) / SPEED_SUBINTERVALS as f64;
            (0..SPEED_SUBINTERVALS).all(|k| {
                let (a, b) = (
                    pc.t0 + h * k as f64,
                    if k + 1 == SPEED_SUBINTERVALS { pc.t1 } else { pc.t0 + h * (k + 1) as f64 },
                );
                let m = a + (b - a) * 0.5;
                // the sub-intervals cover [t0, t1]: r reaches both computed ends
                speed_bound(pc, m, (m - a).max(b - m)) <= v
            })
        }
    }
}

/// Solver settings of an optimisation planner's SDPs at tolerance `tol` (gap and
/// feasibility): no single solve may outlast the plan's time limit, so each gets what
/// remains of it (at least 1 ms; Clarabel checks it between iterations).
pub(crate) fn solver_settings(tol: f64, term: &Termination) -> crate::sdp::SdpSettings {
    let time_limit = term.remaining().map_or(f64::INFINITY, |d| d.as_secs_f64().max(1e-3));
    crate::sdp::SdpSettings { tol_gap_abs: tol, tol_gap_rel: tol, tol_feas: tol, time_limit, ..Default::default() }
}
