//! The motion-checker vocabulary shared by the planners and the certifiers (OMPL's
//! `MotionValidator` and `PlannerTerminationCondition`, docs/architecture.md): a
//! [`MotionChecker`] judges trajectory pieces, [`Motion`] is its verdict,
//! [`CheckCounter`] counts its calls, and [`Termination`] says when to stop.
//!
//! It sits below both `plan` (which consults checkers) and `certify` (whose scene
//! certifier is one), so that neither has to import the other.

use crate::Piece;
use riskplan_math::moments::cdf::add_up;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

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
    /// The checking work done so far, in units that grow with what a check examines (the
    /// scene certifier: one per piece and one per obstacle decided), or `None` when the
    /// checker does not count it. Deterministic — unlike time — so that planners can share
    /// a budget of work between their phases and stay reproducible by seed
    /// (docs/design.md §6.8).
    fn work(&self) -> Option<u64> {
        None
    }
    /// A certified upper bound of the probability that the piece meets any obstacle at
    /// some time of its interval, ω drawn once (docs/design.md §5.14), when the checker
    /// budgets whole paths (`risk_mode: trajectory`); `None` otherwise. Planners add
    /// these up along a path (Boole) and keep the sum within Δ. `stop` is asked between
    /// steps (`None` when it said yes: the caller counts the piece as 1).
    fn path_risk(&self, _piece: &Piece, _stop: &dyn Fn() -> bool) -> Option<f64> {
        None
    }
    /// The sum over `pieces` of their whole-path bounds ([`MotionChecker::path_risk`], 1
    /// for a piece it gives none), each addition rounded up: what a path spends of a
    /// whole-path budget (Boole's inequality, docs/design.md §5.14).
    fn path_risk_sum(&self, pieces: &[Piece], stop: &dyn Fn() -> bool) -> f64 {
        pieces.iter().fold(0.0, |acc, pc| add_up(acc, self.path_risk(pc, stop).unwrap_or(1.0)))
    }
    /// A cheap guess that [`MotionChecker::check`] would reject `piece` (docs/design.md
    /// §6.8): post-processing does not try a shortcut so guessed. Never an acceptance —
    /// whatever it answers, every piece returned is still checked — so a wrong guess can
    /// only leave a path longer. `false` when the checker has no guess.
    fn likely_rejected(&self, _piece: &Piece) -> bool {
        false
    }
    /// The obstacle whose contour excludes `x` at time `t`, if the checker knows.
    fn blocking_obstacle(&self, _x: &[f64], _t: f64) -> Option<String> {
        None
    }
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
    /// The checker's work so far ([`MotionChecker::work`]), or the checks counted here when
    /// it does not count its work.
    pub fn work(&self, c: &dyn MotionChecker) -> u64 {
        c.work().unwrap_or_else(|| self.checked.load(Ordering::Relaxed))
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
    /// Whether the flag is set or the deadline passed more than `grace` ago (for work
    /// that finishes a result found in time, such as the final check of a plan).
    pub fn expired_by(&self, grace: Duration) -> bool {
        self.cancelled() || self.deadline.is_some_and(|d| Instant::now() >= d + grace)
    }
    /// Time left before the deadline (`None` without one).
    pub fn remaining(&self) -> Option<Duration> {
        self.deadline.map(|d| d.saturating_duration_since(Instant::now()))
    }
}

/// Euclidean distance.
pub fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}
