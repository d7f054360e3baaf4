//! The optimisation planners (docs/design.md §8): `tv_sos/` (the paper's
//! time-varying SOS planner, Section V-B) and `moment/` (its standard SOS planner,
//! Section V-A.2), and what they share — the problem in normalised coordinates, one
//! ladder of attempts with typed failure reasons and its statistics, and their SDP
//! solves, which stop inside Clarabel when the plan is cancelled or out of time.

pub mod moment;
pub mod tv_sos;

use super::{
    trajectory_length, within_speed, CheckCounter, LadderStep, Motion, MotionChecker, NoPlanReason, PlanError,
    PlanOutcome, PlanStats, PlanStatus, Problem, SdpStats, Termination,
};
use num_rational::BigRational;
use riskplan_math::poly::{rational_to_f64, Poly, QPoly};
use riskplan_math::sdp::{Model, Prepared, SdpError, SdpSettings, SdpStatus};
use riskplan_scene::{Piece, Trajectory};
use std::time::Instant;
use thiserror::Error;

/// The problem in normalised coordinates `ξ = (x − c)/L`, `τ = (t − t0)/(tf − t0)`.
pub(crate) struct Normalised {
    pub(crate) c: Vec<f64>,
    pub(crate) l: f64,
    pub(crate) lo: Vec<f64>,
    pub(crate) hi: Vec<f64>,
    pub(crate) x0: Vec<f64>,
    pub(crate) xt: Vec<f64>,
}

impl Normalised {
    pub(crate) fn new(p: &Problem) -> Normalised {
        let ws = &p.scene.workspace;
        let c: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(a, b)| 0.5 * (a + b)).collect();
        let l = ws.lower.iter().zip(&ws.upper).map(|(a, b)| 0.5 * (b - a)).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let f = |x: &[f64]| x.iter().zip(&c).map(|(v, c)| (v - c) / l).collect::<Vec<f64>>();
        Normalised { lo: f(&ws.lower), hi: f(&ws.upper), x0: f(&p.start), xt: f(&p.goal), c, l }
    }
    pub(crate) fn back(&self, xi: &[f64]) -> Vec<f64> {
        xi.iter().zip(&self.c).map(|(v, c)| c + self.l * v).collect()
    }
}

/// `g(c + L·ξ, t0 + T·τ)` exactly, then rounded: the constraint in normalised
/// coordinates (variables `ξ_1..ξ_n` = 0..n, `τ` = n).
pub(crate) fn normalise_poly(g: &QPoly, nrm: &Normalised, horizon: (f64, f64), dim: usize) -> Option<Poly<f64>> {
    let q = |v: f64| BigRational::from_float(v);
    let l = q(nrm.l)?;
    let mut subs: Vec<QPoly> = Vec::with_capacity(dim + 1);
    for d in 0..dim {
        let mut s = QPoly::constant(q(nrm.c[d])?);
        s.add_term(riskplan_math::poly::Monomial::var_pow(d as u16, 1), l.clone());
        subs.push(s);
    }
    let (t0, t1) = (q(horizon.0)?, q(horizon.1)?);
    let mut s = QPoly::constant(t0.clone());
    s.add_term(riskplan_math::poly::Monomial::var_pow(dim as u16, 1), t1 - t0);
    subs.push(s);
    let r = g.subst(&|v| subs.get(v as usize).cloned());
    Some(r.map_coeffs(rational_to_f64))
}

/// Why one rung of an optimisation planner's ladder found no certified trajectory:
/// typed, so the ladder decides on the kind (an infeasible relaxation ends the
/// tightening of Δ_opt), and shown in the ladder's log by its message.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RungFailure {
    /// The one-piece rung: the straight line is not certified.
    #[error("the straight line is not certified")]
    StraightLine,
    /// The relaxation with this many pieces is infeasible (tv-sos).
    #[error("no {pieces}-piece path: the relaxation is infeasible")]
    InfeasiblePieces {
        /// Pieces of the rung.
        pieces: usize,
    },
    /// The relaxation of this order is infeasible (moment).
    #[error("order {order}: the relaxation is infeasible")]
    InfeasibleOrder {
        /// Relaxation order.
        order: u32,
    },
    /// The solver ended without a point.
    #[error("{}solver status {status:?}", order.map(|o| format!("order {o}: ")).unwrap_or_default())]
    Status {
        /// Relaxation order (moment).
        order: Option<u32>,
        /// The solver's status.
        status: SdpStatus,
    },
    /// The solver failed.
    #[error("solver error: {0}")]
    Solver(String),
    /// A constraint or the solver's output was not finite.
    #[error("non-finite {0}")]
    NonFinite(&'static str),
    /// A piece of the read-out was not certified (tv-sos).
    #[error("piece {0} of the read-out not certified")]
    ReadOut(usize),
    /// The measures did not become points within the iterations (tv-sos).
    #[error("the measures did not converge to points")]
    NotConverged,
    /// The relaxation has more moments than allowed.
    #[error("relaxation too large ({moments} moments, at most {max}, order ≤ {max_order})")]
    TooManyMoments {
        /// Moments needed.
        moments: usize,
        /// The limit.
        max: usize,
        /// Highest order.
        max_order: u32,
    },
    /// The moment matrix is larger than allowed.
    #[error("relaxation too large (moment matrix side {side}, at most {max})")]
    TooLargeSide {
        /// Its side.
        side: usize,
        /// The limit.
        max: usize,
    },
    /// No atom could be read out of the moment matrix at this order (moment).
    #[error("order {order}: {why}")]
    Extraction {
        /// Relaxation order.
        order: u32,
        /// Why.
        why: riskplan_math::relax::ExtractionError,
    },
    /// Atoms were read out, none of their trajectories certified (moment).
    #[error("order {order}: bound {bound:.6}, {atoms} atom(s) extracted, none certified{}",
        if *outside > 0 { format!(" ({outside} leave the workspace)") } else { String::new() })]
    NoAtomCertified {
        /// Relaxation order.
        order: u32,
        /// The relaxation's bound on the objective.
        bound: f64,
        /// Atoms extracted.
        atoms: usize,
        /// Of them, trajectories that visibly leave the workspace.
        outside: usize,
    },
    /// Several in turn (an order raised after the first failed), in order.
    #[error("{}", .0.iter().map(|f| f.to_string()).collect::<Vec<_>>().join("; "))]
    Several(Vec<RungFailure>),
}

impl RungFailure {
    /// Whether the relaxation was infeasible (a tighter Δ_opt only shrinks the
    /// feasible set, so the ladder need not tighten further).
    pub fn infeasible(&self) -> bool {
        match self {
            RungFailure::InfeasiblePieces { .. } | RungFailure::InfeasibleOrder { .. } => true,
            RungFailure::Several(all) => all.last().is_some_and(RungFailure::infeasible),
            _ => false,
        }
    }
}

/// What one rung ended with.
pub(crate) enum Attempt<T> {
    /// A certified trajectory (with what the planner reports beside it).
    Certified(T),
    /// No certified trajectory, and why.
    Failed(RungFailure),
    /// The plan's time is up or it was cancelled.
    Stopped,
}

/// What the ladder does after a rung.
pub(crate) enum Next<T> {
    /// Found: stop climbing.
    Found(T),
    /// Failed: the planner decides where to go on.
    Failed(RungFailure),
    /// Stopped: stop climbing.
    Stop,
}

/// One ladder of attempts (every optimisation planner climbs one): its log, its SDP
/// statistics and its edge-check counter, and the outcome it ends with.
#[derive(Default)]
pub(crate) struct Ladder {
    /// The log, one step per rung.
    pub(crate) steps: Vec<LadderStep>,
    /// SDP statistics over every rung.
    pub(crate) sdp: SdpStats,
    /// Edge checks of the read-outs.
    pub(crate) counter: CheckCounter,
    /// Whether the plan's time ran out (or it was cancelled) before the ladder ended.
    pub(crate) stopped: bool,
}

impl Ladder {
    /// Logs a rung that ended with `attempt` (its step's outcome filled in).
    pub(crate) fn record<T>(&mut self, mut step: LadderStep, attempt: Attempt<T>) -> Next<T> {
        let next = match attempt {
            Attempt::Certified(t) => {
                step.outcome = "certified".into();
                Next::Found(t)
            }
            Attempt::Failed(why) => {
                step.outcome = why.to_string();
                Next::Failed(why)
            }
            Attempt::Stopped => {
                step.outcome = "stopped by the time limit".into();
                self.stopped = true;
                Next::Stop
            }
        };
        self.steps.push(step);
        next
    }

    /// Logs a rung that was skipped before any attempt.
    pub(crate) fn skip(&mut self, mut step: LadderStep, why: &str) {
        step.outcome = why.into();
        self.steps.push(step);
    }

    /// Every piece within the speed limit and accepted by the checker, or the first
    /// that is not.
    pub(crate) fn certify(
        &self,
        pieces: &[Piece],
        max_speed: Option<f64>,
        checker: &dyn MotionChecker,
    ) -> Result<(), usize> {
        match pieces.iter().position(|pc| {
            max_speed.is_some_and(|v| !within_speed(pc, v)) || self.counter.check(checker, pc) != Motion::Accepted
        }) {
            Some(i) => Err(i),
            None => Ok(()),
        }
    }

    /// The ladder's model set up for its solves: statistics of its size, the settings
    /// at tolerance `tol` with what remains of the plan's time, and the plan's cancel
    /// flag wired into the solver (so a cancelled plan stops inside a solve). Each
    /// planner says what a refused set-up means for it (tv-sos: our model's bug,
    /// [`PlanError::SdpModel`]; moment: a failed rung, as before).
    pub(crate) fn prepare(&mut self, model: &Model, tol: f64, term: &Termination) -> Result<Prepared, SdpError> {
        let mut prepared = model.prepare(&solver_settings(tol, term))?;
        prepared.stop_when(term.cancel_flag());
        self.sdp.variables = model.num_vars();
        self.sdp.rows = model.num_rows();
        Ok(prepared)
    }

    /// The outcome: the certified pieces found, or the typed reason — cancelled, the
    /// deadline, or the ladder exhausted — with the ladder's log.
    pub(crate) fn finish(
        self,
        found: Option<Vec<Piece>>,
        mut stats: PlanStats,
        checker: &dyn MotionChecker,
        term: &Termination,
        t_start: Instant,
    ) -> PlanOutcome {
        let (checked, accepted, secs) = self.counter.totals();
        stats.edges_checked = checked;
        stats.edges_accepted = accepted;
        stats.checker_time_s = secs;
        stats.iterations = self.sdp.solves;
        stats.attempts = self.steps.len() as u64;
        stats.sdp = Some(self.sdp);
        stats.planning_time_s = t_start.elapsed().as_secs_f64();
        stats.ladder = self.steps.clone();
        let ladder = self.steps;
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
                    certified: checker.sound(),
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
                } else if self.stopped {
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
}

/// Solver settings of an optimisation planner's SDPs at tolerance `tol` (gap and
/// feasibility): no single solve may outlast the plan's time limit, so each gets what
/// remains of it (at least 1 ms; Clarabel checks it between iterations).
fn solver_settings(tol: f64, term: &Termination) -> SdpSettings {
    let time_limit = term.remaining().map_or(f64::INFINITY, |d| d.as_secs_f64().max(1e-3));
    SdpSettings { tol_gap_abs: tol, tol_gap_rel: tol, tol_feas: tol, time_limit, ..Default::default() }
}

/// The optimisation planners refuse the RRT planners' options (typed errors).
fn refuse_rrt_options(s: &super::Setup<'_>, planner: &str) -> Result<(), PlanError> {
    if s.options.improve {
        return Err(PlanError::InvalidOption {
            option: "improve".into(),
            message: "applies to the paper's static RRT planner only (rrt-sos-paper)".into(),
        });
    }
    if s.options.kinematics.max_accel.is_some() {
        return Err(PlanError::InvalidOption {
            option: "max_accel".into(),
            message: format!("{planner} does not smooth its plan; max_accel applies to rrt-sos"),
        });
    }
    Ok(())
}
