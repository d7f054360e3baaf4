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

mod layered;
mod mc_checker;
mod rrt;
mod sampling;
#[cfg(any(test, feature = "test-support"))]
pub mod testing;

pub use layered::{LayeredParams, LayeredRrt};
pub use mc_checker::{McChecker, McCheckerParams};
pub use rrt::{RrtParams, StaticRrt};
pub use sampling::StripeSampler;

use crate::contour::RiskLevel;
use crate::scene::{Piece, Scene, Trajectory};
use serde::Serialize;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
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

/// The verdict of a motion checker on one piece.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Accepted (proven safe for a sound checker).
    Accepted,
    /// Rejected (proven unsafe, or undecided: never accepted).
    Rejected,
}

/// Decides whether trajectory pieces are acceptable. Must be thread safe.
pub trait MotionChecker: Send + Sync {
    /// Name for reports (`sos`, `exact`, `monte-carlo`).
    fn name(&self) -> &str;
    /// Whether an acceptance is a proof (false for the Monte Carlo baseline).
    fn sound(&self) -> bool;
    /// Judges one piece against every obstacle (and the workspace).
    fn check(&self, piece: &Piece) -> Motion;
    /// Judges a single point at time `t` (start and goal).
    fn check_point(&self, x: &[f64], t: f64) -> Motion;
    /// Builds whatever the checker caches before the first check (a certifier's
    /// covers and index), stopping early when `term` expires. Planners call it once at
    /// the start of `solve`; checking without it works (and builds on first use).
    fn prepare(&self, _term: &Termination) {}
}

/// Counters and time of a checker, shared by planners.
#[derive(Debug, Default)]
pub struct CheckCounter {
    checked: AtomicU64,
    accepted: AtomicU64,
    nanos: AtomicU64,
}

impl CheckCounter {
    /// Runs and counts one check.
    pub fn check(&self, c: &dyn MotionChecker, piece: &Piece) -> Motion {
        let t = Instant::now();
        let m = c.check(piece);
        self.nanos.fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
        self.checked.fetch_add(1, Ordering::Relaxed);
        if m == Motion::Accepted {
            self.accepted.fetch_add(1, Ordering::Relaxed);
        }
        m
    }
    /// (checked, accepted, seconds).
    pub fn totals(&self) -> (u64, u64, f64) {
        (
            self.checked.load(Ordering::Relaxed),
            self.accepted.load(Ordering::Relaxed),
            self.nanos.load(Ordering::Relaxed) as f64 * 1e-9,
        )
    }
}

/// When to stop: a deadline, a cancellation flag, and (for deterministic tests) an
/// iteration budget. Planners poll [`Termination::should_stop`] every iteration.
#[derive(Clone, Debug)]
pub struct Termination {
    deadline: Option<Instant>,
    cancel: Arc<AtomicBool>,
    budget: Option<Arc<AtomicU64>>,
}

impl Termination {
    /// Never stops by itself.
    pub fn never() -> Self {
        Termination { deadline: None, cancel: Arc::new(AtomicBool::new(false)), budget: None }
    }
    /// Stops after `d` from now.
    pub fn after(d: Duration) -> Self {
        Termination { deadline: Instant::now().checked_add(d), ..Self::never() }
    }
    /// Uses this cancellation flag as well.
    pub fn with_cancel(mut self, cancel: Arc<AtomicBool>) -> Self {
        self.cancel = cancel;
        self
    }
    /// Stops after `n` polls (deterministic tests, no sleeping).
    pub fn with_budget(mut self, n: u64) -> Self {
        self.budget = Some(Arc::new(AtomicU64::new(n)));
        self
    }
    /// The earlier of this deadline and `d` from now.
    pub fn earliest(mut self, d: Duration) -> Self {
        let other = Instant::now().checked_add(d);
        self.deadline = match (self.deadline, other) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self
    }
    /// The cancellation flag (set it to stop the planner).
    pub fn cancel_flag(&self) -> Arc<AtomicBool> {
        self.cancel.clone()
    }
    /// Whether cancellation was requested.
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
    /// Whether to stop now (deadline passed, cancelled, or budget spent). Consumes one
    /// unit of the budget.
    pub fn should_stop(&self) -> bool {
        if self.cancelled() {
            return true;
        }
        if let Some(b) = &self.budget {
            if b.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |v| v.checked_sub(1)).is_err() {
                return true;
            }
        }
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }
    /// Whether the deadline passed or the flag is set (does not consume the budget).
    pub fn expired(&self) -> bool {
        self.cancelled() || self.deadline.is_some_and(|d| Instant::now() >= d)
    }
    /// Time left before the deadline (`None` without one).
    pub fn remaining(&self) -> Option<Duration> {
        self.deadline.map(|d| d.saturating_duration_since(Instant::now()))
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
    #[error("{which}: {point:?} is not in the safe set of the Δ-risk contours at t = {t} (its risk bound exceeds Δ, or it touches a contour)")]
    UnsafeEndpoint {
        /// `start` or `goal`.
        which: String,
        /// The point.
        point: Vec<f64>,
        /// The time.
        t: f64,
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

/// Checks start and goal: inside the workspace and strictly inside every Δ-contour.
pub fn check_endpoints(p: &Problem, checker: &dyn MotionChecker) -> Result<(), PlanError> {
    p.validate()?;
    for (which, x, t) in [("start", &p.start, p.horizon.0), ("goal", &p.goal, p.horizon.1)] {
        if checker.check_point(x, t) != Motion::Accepted {
            return Err(PlanError::UnsafeEndpoint { which: which.into(), point: x.clone(), t });
        }
    }
    Ok(())
}

/// Euclidean distance.
pub fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}

/// The RRT-SOS planner a problem calls for: the time-layered planner when an obstacle
/// moves or `pieces` is given, else the static tree (with the improve step if asked).
/// Parameters default to the scene's `planner.rrt_sos` block. The improve step does
/// not exist for the layered planner: asking for it there is an error.
pub fn rrt_planner(p: &Problem, pieces: Option<usize>, improve: bool) -> Result<Box<dyn Planner>, PlanError> {
    let block = p.scene.file.planner.as_ref().and_then(|b| b.get("rrt_sos"));
    if pieces.is_some() || p.is_dynamic() {
        if improve {
            return Err(PlanError::InvalidOption {
                option: "improve".into(),
                message: "applies to static scenes only; the layered planner has no improve step".into(),
            });
        }
        let mut params = LayeredParams::from_scene_block(block);
        if let Some(s) = pieces {
            params.pieces = s;
        }
        Ok(Box::new(LayeredRrt::new(params)))
    } else {
        let mut params = RrtParams::from_scene_block(block);
        params.improve = improve;
        Ok(Box::new(StaticRrt::new(params)))
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
