//! The acceptance of a certified trajectory: its final check on the verify path
//! (docs/design.md §5.12), and for a plan that passes it the whole-path bound (§5.14),
//! computed beside the check on crowded scenes.

use crate::verify::{final_check, plan_whole_path_risk, FinalFailure, Interrupted, SceneKernel, WholePathWork};
use riskplan_certify::whole_path::CellEffort;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_plan::{FinalCheckStats, MotionChecker, PlanOutcome, PlanStatus, Problem, RiskMode, Termination};
use riskplan_scene::Trajectory;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The share of Δ by which the whole-path bound a plan reports may exceed, summed over the
/// obstacles, what the partition would give with unlimited boxes (docs/design.md §5.14):
/// an obstacle's partition stops once its undecided probability is below this share of Δ
/// over the number of obstacles whose reach the plan enters (the others need no
/// partition). Without it an obstacle at 10⁻⁹ beside the plan would be refined to 10⁻¹²
/// (its whole box budget) for a sum of 10⁻⁴.
pub const WHOLE_PATH_SLACK_SHARE: f64 = 0.01;

/// How long the final check of a plan found in time may run past the plan's deadline
/// (docs/design.md §5.12): well inside the 100 ms within which plans answer after
/// their limit; a check still running then ends the plan as `deadline_reached`.
pub const FINAL_CHECK_GRACE: Duration = Duration::from_millis(50);

/// Fewest obstacles for which a plan computes its whole-path bound beside its final check
/// (`rayon::join`, docs/design.md §5.12, §5.14): on crowded scenes the two take about as
/// long each; on small scenes both take microseconds and handing the bound to another
/// thread would cost more than it saves.
pub const WHOLE_PATH_BESIDE_MIN_OBSTACLES: usize = 64;

/// What the acceptance of a certified trajectory found.
pub(crate) enum Acceptance {
    /// Passed the final check; the whole-path bound when one is computed.
    Accepted {
        /// The bound (`None`: none computed, or none reached in time outside trajectory mode).
        whole_path_risk: Option<f64>,
    },
    /// Passed the final check, but in trajectory mode its whole-path bound exceeds Δ.
    OverBudget {
        /// Why, in one line.
        why: String,
        /// The bound.
        whole_path_risk: f64,
    },
    /// Refused by the final check.
    Refused(FinalFailure),
    /// `term` ended the check (or, in trajectory mode, the bound) first.
    Interrupted,
}

/// What the acceptance of a trajectory reads of the plan that made it.
pub(crate) struct Plan<'a> {
    /// The problem.
    pub problem: &'a Problem,
    /// The scene's kernel.
    pub kernel: &'a SceneKernel,
    /// The risk level Δᵢ of each obstacle.
    pub deltas: &'a [RiskLevel],
    /// The bounds the check may use.
    pub bounds: BoundChoice,
    /// What Δ bounds.
    pub risk_mode: RiskMode,
    /// The planner's checker (its whole-path sum, in trajectory mode).
    pub checker: &'a dyn MotionChecker,
}

/// Checks `traj`, the certified outcome `out` of `plan`'s planner, and bounds its whole
/// path; counts the check's work in `fc`.
pub(crate) fn accept(
    plan: Plan<'_>,
    traj: &Trajectory,
    out: &PlanOutcome,
    term: &Termination,
    fc: &mut FinalCheckStats,
) -> Acceptance {
    let stop = || term.expired_by(FINAL_CHECK_GRACE);
    // a receding plan that ends short of the goal (`progress`) ends anywhere
    let goal = (out.status != PlanStatus::Progress).then_some(plan.problem.goal.as_slice());
    let ends = (plan.problem.start.as_slice(), goal);
    let t_start = plan.problem.horizon.0;
    // (receding plans outside trajectory mode carry no whole-path bound)
    let wants_whole = !(plan.problem.receding && plan.risk_mode != RiskMode::Trajectory);
    let crowded = plan.kernel.scene().obstacles.len() >= WHOLE_PATH_BESIDE_MIN_OBSTACLES;
    let delta = plan.problem.delta.floor_f64();
    // (outside trajectory mode, only when every obstacle admits the partition: the moment
    // envelopes' exact arithmetic can take seconds)
    let budgeted = plan.risk_mode == RiskMode::Trajectory;
    let slack = WHOLE_PATH_SLACK_SHARE * delta;
    let work = wants_whole
        .then(|| WholePathWork::new(plan.kernel.clone(), traj.pieces.clone(), CellEffort::PLAN, slack, budgeted));
    // the whole-path bound at the plan's effort runs beside the check on crowded scenes,
    // and is abandoned if the check refuses the plan
    let abandon = AtomicBool::new(false);
    let (kernel, deltas, bounds) = (plan.kernel, plan.deltas, plan.bounds);
    let check = || {
        let c = final_check(kernel, traj, ends, t_start, deltas, bounds, &stop);
        if !matches!(&c, Ok(c) if c.failure.is_none()) {
            abandon.store(true, Ordering::Relaxed);
        }
        c
    };
    let check = match &work {
        Some(w) if crowded => {
            rayon::join(check, || w.run(&|| abandon.load(Ordering::Relaxed) || term.expired_by(FINAL_CHECK_GRACE))).0
        }
        _ => check(),
    };
    let check = match check {
        Ok(c) => c,
        Err(Interrupted) => return Acceptance::Interrupted,
    };
    fc.seconds += check.seconds;
    fc.verify_seconds += check.seconds;
    fc.pieces += check.pieces;
    if let Some(failure) = check.failure {
        return Acceptance::Refused(failure);
    }
    let Some(work) = work else { return Acceptance::Accepted { whole_path_risk: None } };
    let t_wp = std::time::Instant::now();
    // the plan's effort first (begun beside the check on crowded scenes: joined here); in
    // trajectory mode a bound above Δ is tried again with the report's (ten times the boxes)
    let mut wp = work.finish(&stop);
    if budgeted && wp.as_ref().is_ok_and(|b| b.is_some_and(|b| b > delta)) {
        wp = plan_whole_path_risk(plan.kernel, &traj.pieces, CellEffort::REPORT, 0.0, budgeted, &stop);
    }
    // in trajectory mode the planner's own sum over the pieces (what it kept within Δ) is
    // a bound too: the smaller one decides
    if budgeted {
        let sum = plan.checker.path_risk_sum(&traj.pieces, &stop);
        wp = wp.map(|b| Some(b.map_or(sum, |b| b.min(sum))));
    }
    let here = t_wp.elapsed().as_secs_f64();
    fc.whole_path_seconds = work.seconds().max(here);
    fc.seconds += here;
    match wp {
        Ok(Some(b)) if budgeted && !(b <= delta && b < 1.0) => Acceptance::OverBudget {
            why: format!("the whole-path bound {b:.4e} of the plan exceeds Δ = {delta}"),
            whole_path_risk: b,
        },
        Ok(whole_path_risk) => Acceptance::Accepted { whole_path_risk },
        Err(Interrupted) if budgeted => Acceptance::Interrupted,
        // out of time for a report: the plan stands without it
        Err(Interrupted) => Acceptance::Accepted { whole_path_risk: None },
    }
}
