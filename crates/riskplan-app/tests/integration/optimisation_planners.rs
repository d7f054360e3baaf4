//! The paper's optimisation planners. Every plan is re-verified by both certification
//! methods, by the independent exact oracle (the contours evaluated in rationals at
//! many times of every piece) and by a seeded Monte Carlo audit (the probability of
//! collision with each obstacle at each audited point ≤ Δ at 99 %).

use crate::common;
use crate::common::oracle;
use riskplan_app::verify::{audit_trajectory, verify, AuditOptions, Method};
use riskplan_app::{PlanRequest, PlannerKind};
use riskplan_plan::{NoPlanReason, PlanError};
use riskplan_scene::{Scene, Trajectory};
use std::sync::Arc;
use std::time::Duration;

/// Checks a certified plan with everything that does not share the planner's code.
fn reverify(s: &Scene, t: &Trajectory, what: &str) {
    let report = verify(s, t, &s.risk, Method::Both, &Default::default());
    assert!(report.safe, "{what}: verify --method both rejects the plan: {report:?}");
    oracle::check_trajectory(s, &t.pieces, &s.risk).unwrap_or_else(|e| panic!("{what}: oracle: {e}"));
    let opts = AuditOptions { times_per_piece: 40, samples: 4000, seed: 7, ..AuditOptions::default() };
    let a = audit_trajectory(s, t, s.risk_f64(), &opts).unwrap();
    assert!(!a.exceeds(), "{what}: Monte Carlo risk above Δ: {:?}", a.exceedances);
}

fn tv_sos(seed: u64) -> PlanRequest {
    PlanRequest { planner: PlannerKind::TvSos, seed, time_limit: Duration::from_secs(30), ..PlanRequest::default() }
}

/// `tv-sos` returns certified plans on the paper's time-varying SOS examples, for
/// several seeds, each re-verified.
#[test]
fn tv_sos_plans_are_certified_and_reverified() {
    for name in ["illustrative-3", "illustrative-4", "example-b-lane-change", "example-c-delivery"] {
        let s = Arc::new(common::scene(name));
        for seed in 1..=3 {
            let (_, out) = tv_sos(seed).run(s.clone(), None).unwrap();
            let t = out.trajectory.unwrap_or_else(|| panic!("{name} seed {seed}: no plan: {:?}", out.reason));
            assert!(out.certified);
            let sdp = out.stats.sdp.as_ref().expect("SDP stats");
            assert!(sdp.solves >= 1 && sdp.variables > 0 && sdp.rows > 0 && sdp.psd_cones > 0);
            assert_eq!(out.stats.ladder.last().map(|l| l.outcome.as_str()), Some("certified"));
            println!(
                "{name} seed {seed}: {:.1} ms, {} solves, length {:.4}",
                out.stats.planning_time_s * 1e3,
                sdp.solves,
                out.stats.path_length.unwrap()
            );
            reverify(&s, &t, &format!("{name} seed {seed}"));
        }
    }
}

/// Off the paper's tv-sos examples: the cluttered static scene (8 uncertain disks), where
/// two pieces sampled from the RRT path cut its corners. The corner-started rung (one
/// piece per segment of the unsmoothed RRT path) gives a certified plan, re-verified.
#[test]
fn tv_sos_plans_the_cluttered_static_scene() {
    let s = Arc::new(common::scene("example-d1-cluttered-2d"));
    let (_, out) = tv_sos(1).run(s.clone(), None).unwrap();
    let t = out.trajectory.unwrap_or_else(|| panic!("no plan: {:?}", out.reason));
    assert!(out.certified);
    assert!(out.stats.ladder.iter().any(|l| l.pieces > 2), "{:?}", out.stats.ladder);
    reverify(&s, &t, "example-d1 tv-sos seed 1");
}

/// When no plan can be certified — illustrative-3 with a speed limit that leaves only
/// the straight line, which crosses the obstacle — the outcome is a typed no-plan
/// carrying the ladder's log, never an uncertified plan.
#[test]
fn tv_sos_never_returns_an_uncertified_plan() {
    let s = Arc::new(common::scene("illustrative-3"));
    let req = PlanRequest { max_speed: Some(2.0 * 2f64.sqrt() * 1.001), ..tv_sos(1) };
    let (_, out) = req.run(s.clone(), None).unwrap();
    assert!(out.trajectory.is_none() && !out.certified, "{:?}", out.stats);
    let ladder = match out.reason {
        Some(NoPlanReason::Exhausted { ladder, .. }) | Some(NoPlanReason::DeadlineReached { ladder, .. }) => ladder,
        other => panic!("unexpected reason {other:?}"),
    };
    assert!(ladder.len() >= 3, "the ladder's log is reported: {ladder:?}");
    assert!(ladder.iter().all(|l| l.outcome != "certified"));
}

/// The `tv-sos` path on illustrative-3 is within 3 % of the length of the best RRT-SOS
/// path (the paper's planner with its improve step: Dijkstra over every certified pair
/// of tree vertices).
#[test]
fn tv_sos_path_is_within_three_percent_of_the_improved_rrt_path() {
    let s = Arc::new(common::scene("illustrative-3"));
    let improved = PlanRequest {
        planner: PlannerKind::RrtSosPaper,
        improve: true,
        time_limit: Duration::from_secs(120),
        ..PlanRequest::default()
    };
    let (_, out) = improved.run(s.clone(), None).unwrap();
    let best = out.stats.path_length.expect("improved path");
    for seed in 1..=5 {
        let (_, out) = tv_sos(seed).run(s.clone(), None).unwrap();
        let len = out.stats.path_length.unwrap_or_else(|| panic!("seed {seed}: no plan: {:?}", out.reason));
        println!("seed {seed}: tv-sos {len:.4} vs improved RRT-SOS {best:.4}");
        assert!(len <= 1.03 * best, "seed {seed}: {len} > 1.03 × {best}");
    }
}

/// Options that do not apply to `tv-sos` are refused with typed errors.
#[test]
fn tv_sos_bad_options_get_typed_errors() {
    let s = Arc::new(common::scene("illustrative-3"));
    for (req, option) in [
        (PlanRequest { improve: true, ..tv_sos(1) }, "improve"),
        (PlanRequest { max_accel: Some(1.0), ..tv_sos(1) }, "max_accel"),
        (PlanRequest { pieces: Some(0), ..tv_sos(1) }, "pieces"),
        (PlanRequest { pieces: Some(1000), ..tv_sos(1) }, "pieces"),
        (PlanRequest { max_speed: Some(-1.0), ..tv_sos(1) }, "max_speed"),
    ] {
        match req.run(s.clone(), None) {
            Err(PlanError::InvalidOption { option: o, .. }) => assert_eq!(o, option),
            other => panic!("{option}: expected InvalidOption, got {other:?}"),
        }
    }
    // a speed limit below what the distance needs: a typed out-of-reach no-plan
    let (_, out) = PlanRequest { max_speed: Some(1.0), ..tv_sos(1) }.run(s, None).unwrap();
    assert!(matches!(out.reason, Some(NoPlanReason::OutOfReach { .. })), "{:?}", out.reason);
}

/// A speed limit that allows the plan is kept by every piece.
#[test]
fn tv_sos_keeps_a_speed_limit() {
    let s = Arc::new(common::scene("illustrative-3"));
    let v = 3.3;
    let (_, out) = PlanRequest { max_speed: Some(v), ..tv_sos(1) }.run(s.clone(), None).unwrap();
    let t = out.trajectory.unwrap_or_else(|| panic!("no plan: {:?}", out.reason));
    for p in &t.pieces {
        let len = riskplan_plan::dist(&p.at(p.t0), &p.at(p.t1));
        assert!(len <= v * (p.t1 - p.t0) * (1.0 + 1e-12), "piece speed {} > {v}", len / (p.t1 - p.t0));
    }
    reverify(&s, &t, "illustrative-3 with max_speed");
}

fn moment(planner: PlannerKind, seed: u64) -> PlanRequest {
    PlanRequest { planner, seed, time_limit: Duration::from_secs(30), ..PlanRequest::default() }
}

/// `moment` (the standard SOS planner with average risk) returns a certified plan on
/// illustrative-3, re-verified by both methods, the exact oracle and Monte Carlo; the
/// average-risk values are reported and the SDP stats filled in.
#[test]
fn moment_plans_are_certified_and_reverified() {
    let s = Arc::new(common::scene("illustrative-3"));
    for seed in 1..=3 {
        let (_, out) = moment(PlannerKind::Moment, seed).run(s.clone(), None).unwrap();
        let t = out.trajectory.unwrap_or_else(|| panic!("seed {seed}: no plan: {:?}", out.reason));
        assert!(out.certified);
        let sdp = out.stats.sdp.as_ref().expect("SDP stats");
        assert!(sdp.solves >= 1 && sdp.variables > 0 && sdp.psd_cones > 0);
        let avg = out.stats.average_risk.as_ref().expect("average risk reported");
        assert_eq!(avg.len(), 1);
        assert!(avg[0].1 >= 0.0 && avg[0].1 <= 0.1 * (1.0 + 1e-6), "{avg:?}");
        println!(
            "seed {seed}: {:.1} ms, {} solves, length {:.4}, ladder {:?}",
            out.stats.planning_time_s * 1e3,
            sdp.solves,
            out.stats.path_length.unwrap(),
            out.stats.ladder.iter().map(|l| (l.pieces, l.eta, l.outcome.clone())).collect::<Vec<_>>()
        );
        reverify(&s, &t, &format!("moment seed {seed}"));
    }
}

/// The paper's own problem (average risk at Δ, η = 1) is the first rung, and its
/// atoms are judged per instant like any other trajectory: whatever the ladder ends
/// with, nothing uncertified is returned; a plan that comes back is re-verified.
#[test]
fn moment_poly_is_certified_or_says_why() {
    let s = Arc::new(common::scene("illustrative-3"));
    let req = PlanRequest { time_limit: Duration::from_secs(10), ..moment(PlannerKind::MomentPoly, 1) };
    let (_, out) = req.run(s.clone(), None).unwrap();
    assert_eq!(out.stats.ladder.first().map(|l| l.eta), Some(1.0), "{:?}", out.stats.ladder);
    match &out.trajectory {
        Some(t) => {
            assert!(out.certified);
            assert!(t.pieces.len() == 1 && t.pieces[0].degree() >= 2, "one polynomial piece: {t:?}");
            reverify(&s, t, "moment-poly");
        }
        None => {
            assert!(!out.certified);
            // the ladder ran out, or the time limit came first (higher orders are slow)
            assert!(
                matches!(out.reason, Some(NoPlanReason::Exhausted { .. } | NoPlanReason::DeadlineReached { .. })),
                "{:?}",
                out.reason
            );
        }
    }
}

/// Options that do not apply to the moment planners are refused with typed errors.
#[test]
fn moment_bad_options_get_typed_errors() {
    let s = Arc::new(common::scene("illustrative-3"));
    for (req, option) in [
        (PlanRequest { improve: true, ..moment(PlannerKind::Moment, 1) }, "improve"),
        (PlanRequest { max_accel: Some(1.0), ..moment(PlannerKind::Moment, 1) }, "max_accel"),
        (PlanRequest { pieces: Some(0), ..moment(PlannerKind::Moment, 1) }, "pieces"),
        (PlanRequest { pieces: Some(1000), ..moment(PlannerKind::Moment, 1) }, "pieces"),
        (PlanRequest { pieces: Some(2), ..moment(PlannerKind::MomentPoly, 1) }, "pieces"),
        (PlanRequest { max_speed: Some(f64::NAN), ..moment(PlannerKind::Moment, 1) }, "max_speed"),
    ] {
        match req.run(s.clone(), None) {
            Err(PlanError::InvalidOption { option: o, .. }) => assert_eq!(o, option),
            other => panic!("{option}: expected InvalidOption, got {other:?}"),
        }
    }
    let (_, out) = PlanRequest { max_speed: Some(1.0), ..moment(PlannerKind::Moment, 1) }.run(s, None).unwrap();
    assert!(matches!(out.reason, Some(NoPlanReason::OutOfReach { .. })), "{:?}", out.reason);
}

/// The optimisation planners pass the conformance harness every planner passes
/// (determinism per seed, expired and cancelled terminations, continuity, endpoints,
/// every piece accepted by the sound checker).
#[test]
fn optimisation_planners_pass_the_conformance_harness() {
    use riskplan_app::verify::SceneCertifier;
    use riskplan_plan::testing::conformance;
    use riskplan_plan::{MomentParams, MomentPlanner, Problem, TvSos, TvSosParams};
    for name in ["illustrative-3", "illustrative-4"] {
        let s = Arc::new(common::scene(name));
        let p = Problem::from_scene(s.clone(), 3).unwrap();
        let cert = SceneCertifier::new(s.clone(), p.delta.clone(), Method::Exact);
        let block = s.file.planner.as_ref();
        let mut tv = TvSos::new(TvSosParams::paper(block.and_then(|b| b.time_varying_sos.as_ref())));
        conformance(&mut tv, &p, &cert, Duration::from_secs(60));
        if name == "illustrative-3" {
            let mut m = MomentPlanner::new(MomentParams::paper(block.and_then(|b| b.standard_sos.as_ref())));
            conformance(&mut m, &p, &cert, Duration::from_secs(60));
        }
    }
}

/// A plan's cancel flag reaches the solver (docs/architecture.md): moment-poly's
/// SDPs on illustrative-3 take seconds each, and a plan cancelled 0.3 s in answers
/// `cancelled` sooner than one of its solves takes on average (measured on the same plan
/// run uncancelled in this test, so a slow machine moves both). Without the callback
/// (`stop_when` in `plan/opt/mod.rs`) the plan would run its solve to the end, seconds
/// after the cancel.
#[test]
fn a_cancelled_plan_stops_inside_a_solve() {
    use std::sync::atomic::{AtomicBool, Ordering};
    let s = Arc::new(common::scene("illustrative-3"));
    let req = PlanRequest { time_limit: Duration::from_secs(4), ..moment(PlannerKind::MomentPoly, 1) };
    let (_, full) = req.run(s.clone(), None).unwrap();
    let sdp = full.stats.sdp.clone().expect("SDP statistics");
    let per_solve = sdp.solver_time_s / sdp.solves.max(1) as f64;
    assert!(per_solve > 0.2, "the test needs solves of at least 0.2 s, got {per_solve} s");
    let flag = Arc::new(AtomicBool::new(false));
    let setter = {
        let flag = flag.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            flag.store(true, Ordering::Relaxed);
            std::time::Instant::now()
        })
    };
    let req = PlanRequest { time_limit: Duration::from_secs(60), ..moment(PlannerKind::MomentPoly, 1) };
    let (_, out) = req.run(s, Some(flag)).unwrap();
    let returned = std::time::Instant::now();
    let cancelled_at = setter.join().unwrap();
    assert_eq!(out.status, riskplan_plan::PlanStatus::Cancelled, "{:?}", out.reason);
    let late = returned.duration_since(cancelled_at).as_secs_f64();
    assert!(late < per_solve, "returned {late} s after the cancel; a solve takes {per_solve} s on average");
}
