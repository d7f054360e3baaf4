//! A prepared plan run to its outcome: the planner's search, then the final check of
//! what it certified (docs/design.md §5.12) with the whole-path bound (§5.14), and the
//! re-plan when the check refuses the trajectory.

use crate::acceptance::{accept, Acceptance, Plan};
use crate::verify::{FinalFailure, SceneKernel};
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_plan::{
    FinalCheckStats, MotionChecker, NoPlanReason, PlanError, PlanOptions, PlanOutcome, PlanStatus, Planner,
    PlannerKind, Problem, RiskMode, Setup, Termination,
};

/// A request made ready to run: the problem, the planner and its motion checker.
pub struct PreparedPlan {
    /// The problem (scene, endpoints, horizon, Δ, seed).
    pub problem: Problem,
    /// The planner.
    pub planner: Box<dyn Planner>,
    /// The motion checker the planner consults.
    pub checker: Box<dyn MotionChecker>,
    /// The risk level of each obstacle in a joint risk mode (`None`: per obstacle).
    pub allocation: Option<Vec<(String, f64)>>,
    /// The risk level Δᵢ of each obstacle: what the final check proves.
    pub deltas: Vec<RiskLevel>,
    /// The scene's kernel: what its checkers and the final check cache.
    pub kernel: SceneKernel,
    /// What Δ bounds (`trajectory`: the final check also proves the whole-path bound).
    pub risk_mode: RiskMode,
    /// The bounds the checker and the final check may use.
    pub bounds: BoundChoice,
    /// The planner's kind and options (to build it again should its output need a re-plan).
    pub kind: PlannerKind,
    /// The options the planner was built with.
    pub options: PlanOptions,
}

impl PreparedPlan {
    /// Runs the planner until it finishes or `term` says stop. A certified trajectory
    /// is called certified only after it passed the final check (docs/design.md §5.12):
    /// the verify path, piece by piece, every obstacle. Should the check reject a
    /// trajectory the planner's checker accepted — a bug of the fast path — the
    /// disagreement is counted in `stats.final_check`, and the plan is made again in
    /// the remaining time with a checker without the fast path.
    pub fn solve(&mut self, term: &Termination) -> Result<PlanOutcome, PlanError> {
        let started = std::time::Instant::now();
        let mut out = self.planner.solve(&self.problem, self.checker.as_ref(), term)?;
        let mut fc = FinalCheckStats::default();
        while let Some(traj) = out.trajectory.as_ref().filter(|_| out.certified) {
            let plan = Plan {
                problem: &self.problem,
                kernel: &self.kernel,
                deltas: &self.deltas,
                bounds: self.bounds,
                risk_mode: self.risk_mode,
                checker: self.checker.as_ref(),
            };
            let why = match accept(plan, traj, &out, term, &mut fc) {
                Acceptance::Accepted { whole_path_risk } => {
                    out.stats.whole_path_risk = whole_path_risk;
                    break;
                }
                Acceptance::OverBudget { why, whole_path_risk } => {
                    out.stats.whole_path_risk = Some(whole_path_risk);
                    why
                }
                Acceptance::Interrupted => {
                    let status = if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached };
                    let reason = NoPlanReason::from_status(status, &out.stats, term);
                    out = PlanOutcome::no_plan(status, out.stats, reason);
                    break;
                }
                Acceptance::Refused(failure) => match self.replan(failure, &mut fc, term)? {
                    Ok(again) => {
                        out = again;
                        continue;
                    }
                    Err(why) => why,
                },
            };
            out = PlanOutcome::no_plan(PlanStatus::Exhausted, out.stats, NoPlanReason::FinalCheckFailed { why });
        }
        if out.certified || fc.pieces > 0 {
            out.stats.final_check = Some(fc);
        }
        out.stats.planning_time_s = started.elapsed().as_secs_f64();
        out.stats.risk_allocation = self.allocation.clone();
        Ok(out)
    }

    /// The re-plan after the final check refused a trajectory, once per cause
    /// (docs/design.md §5.12): an invalid trajectory (a bug of the planner's
    /// post-processing) is planned again without smoothing, whose straight pieces between
    /// certified waypoints always are valid; a piece the fast path accepted and the
    /// verify path does not prove is planned again with [`riskplan_plan::fallback_checker`],
    /// without the fast path. `Ok(Err(why))`: the cause met again, the plan fails.
    fn replan(
        &mut self,
        failure: FinalFailure,
        fc: &mut FinalCheckStats,
        term: &Termination,
    ) -> Result<Result<PlanOutcome, String>, PlanError> {
        match failure {
            FinalFailure::Invalid(why) => {
                fc.invalid += 1;
                if fc.invalid > 1 || !self.options.kinematics.smooth {
                    return Ok(Err(why));
                }
                self.options.kinematics.smooth = false;
                self.planner = self.kind.build(&self.setup())?.planner;
            }
            FinalFailure::NotProven(piece) => {
                fc.disagreements += 1;
                if fc.disagreements > 1 {
                    return Ok(Err(format!("piece {piece} is not proven safe, even planned without the fast path")));
                }
                self.checker = riskplan_plan::fallback_checker(&self.setup());
            }
        }
        Ok(Ok(self.planner.solve(&self.problem, self.checker.as_ref(), term)?))
    }

    /// What the planner is built from.
    fn setup(&self) -> Setup<'_> {
        Setup { problem: &self.problem, kernel: &self.kernel, deltas: &self.deltas, options: &self.options }
    }
}
