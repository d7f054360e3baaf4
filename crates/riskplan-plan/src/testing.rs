//! The conformance harness every planner must pass (after OMPL's `PlannerTest`):
//! solve, solve again with the same seed and get the same trajectory; an
//! already-expired termination and a set cancel flag return promptly without a
//! plan; every returned trajectory is continuous, starts at the start at t0, ends
//! at the goal at tf, and every piece is accepted by the checker (if it is sound).

use super::{dist, Motion, MotionChecker, PlanStatus, Planner, Problem, Termination};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Tolerance for "the trajectory starts at the start / ends at the goal": the
/// returned pieces are rounded floats of segments through those points.
pub const ENDPOINT_TOLERANCE: f64 = 1e-9;

/// Runs the conformance checks; panics with a message on the first failure.
/// `budget` bounds the planning time of each solve.
pub fn conformance(planner: &mut dyn Planner, p: &Problem, checker: &dyn MotionChecker, budget: Duration) {
    let name = planner.name();
    let out = planner.solve(p, checker, &Termination::after(budget)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(out.status, PlanStatus::Exact, "{name}: no plan on a solvable problem ({:?})", out.stats);
    let traj = out.trajectory.clone().expect("Exact comes with a trajectory");
    let pieces = &traj.pieces;
    assert!(
        (pieces[0].t0 - p.horizon.0).abs() < 1e-12 && (pieces[pieces.len() - 1].t1 - p.horizon.1).abs() < 1e-12,
        "{name}: horizon"
    );
    assert!(dist(&pieces[0].at(pieces[0].t0), &p.start) < ENDPOINT_TOLERANCE, "{name}: does not start at the start");
    let last = &pieces[pieces.len() - 1];
    assert!(dist(&last.at(last.t1), &p.goal) < ENDPOINT_TOLERANCE, "{name}: does not end at the goal");
    let diag = dist(&p.scene.workspace.lower, &p.scene.workspace.upper);
    traj.validate(p.scene.dim, p.horizon, diag).unwrap_or_else(|e| panic!("{name}: invalid trajectory: {e}"));
    // A sound checker must accept every returned piece as it is. A sampling checker
    // judges a piece at sampled waypoints, so the same segment re-timed (a shortcut
    // judged over the horizon, returned over a sub-interval) is sampled at other points
    // and may be judged otherwise: its verdicts are not stable, and are not asked for.
    if checker.sound() {
        for pc in pieces {
            assert_eq!(checker.check(pc), Motion::Accepted, "{name}: a returned piece is not accepted: {pc:?}");
        }
    }
    assert_eq!(out.certified, checker.sound(), "{name}: certified flag");
    // Same seed, same plan.
    let again = planner.solve(p, checker, &Termination::after(budget)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(again.trajectory, out.trajectory, "{name}: same seed gave a different plan");
    // An expired termination returns at once without a plan.
    let expired =
        planner.solve(p, checker, &Termination::never().with_budget(0)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(expired.trajectory.is_none() || expired.stats.iterations == 0, "{name}: ignored an expired termination");
    // A set cancel flag is honoured.
    let flag = Arc::new(AtomicBool::new(false));
    flag.store(true, Ordering::Relaxed);
    let cancelled =
        planner.solve(p, checker, &Termination::never().with_cancel(flag)).unwrap_or_else(|e| panic!("{name}: {e}"));
    if cancelled.trajectory.is_none() {
        assert_eq!(cancelled.status, PlanStatus::Cancelled, "{name}: cancel");
    }
}

/// The conformance checks of a planner that answers a problem without a plan (a
/// planner known not to solve it within `budget`): the answer is typed (exhausted or
/// the deadline, with a reason) and not called certified, the same seed gives the same
/// status, and an expired termination and a set cancel flag are honoured as in
/// [`conformance`]. Panics with a message on the first failure.
pub fn conformance_without_plan(planner: &mut dyn Planner, p: &Problem, checker: &dyn MotionChecker, budget: Duration) {
    let name = planner.name();
    let out = planner.solve(p, checker, &Termination::after(budget)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(out.trajectory.is_none(), "{name}: planned a problem it is listed as not solving: use `conformance`");
    assert!(
        matches!(out.status, PlanStatus::Exhausted | PlanStatus::DeadlineReached) && out.reason.is_some(),
        "{name}: no plan without a typed reason ({:?}, {:?})",
        out.status,
        out.reason
    );
    assert!(!out.certified, "{name}: no plan, yet certified");
    if out.status == PlanStatus::Exhausted {
        let again = planner.solve(p, checker, &Termination::after(budget)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(again.status, out.status, "{name}: same seed gave a different answer");
    }
    let expired =
        planner.solve(p, checker, &Termination::never().with_budget(0)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(expired.trajectory.is_none() || expired.stats.iterations == 0, "{name}: ignored an expired termination");
    let flag = Arc::new(AtomicBool::new(true));
    let cancelled =
        planner.solve(p, checker, &Termination::never().with_cancel(flag)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(cancelled.status, PlanStatus::Cancelled, "{name}: cancel");
}

/// The largest speed of the pieces at 4096 evenly spaced times each: an oracle for the
/// speed limit that shares no code with `within_speed` (a sampled peak is at most the
/// true one).
pub fn sampled_peak_speed(pieces: &[riskplan_scene::Piece]) -> f64 {
    const SAMPLES: usize = 4096;
    pieces
        .iter()
        .flat_map(|p| {
            (0..=SAMPLES).map(move |k| {
                let t = p.t0 + (p.t1 - p.t0) * k as f64 / SAMPLES as f64;
                // dx/dt term by term (Σ k·c_k·t^(k−1)), not the planners' Horner form
                p.coeffs
                    .iter()
                    .map(|c| {
                        c.iter().enumerate().skip(1).map(|(k, &v)| k as f64 * v * t.powi(k as i32 - 1)).sum::<f64>()
                    })
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt()
            })
        })
        .fold(0.0, f64::max)
}
