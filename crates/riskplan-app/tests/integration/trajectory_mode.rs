//! `risk_mode: trajectory` (docs/design.md §5.14): Δ bounds the probability that
//! the plan meets any obstacle at any time, the parameters drawn once. Every plan is checked
//! against a seeded Monte Carlo audit of that whole-path event (`audit_whole_path`: one
//! draw of every parameter per scenario, shared by 100 times per piece and every obstacle;
//! it shares no code with the bound: the scene's sampler and P evaluated at points).
//! Clopper–Pearson ends at 98 % two-sided, i.e. 99 % one-sided.

use crate::common::{scene, size};
use riskplan_app::verify::{audit_whole_path, AuditOptions};
use riskplan_app::{PlanRequest, RiskMode};
use riskplan_math::contour::RiskLevel;
use riskplan_scene::Scene;
use std::sync::Arc;

fn audit_options(seed: u64) -> AuditOptions {
    let samples = size("WHOLE_PATH_SAMPLES", 20_000, 100_000) as u64;
    AuditOptions { times_per_piece: 100, samples, seed, confidence: 0.98 }
}

fn plan(s: &Arc<Scene>, mode: RiskMode, delta: f64) -> riskplan_plan::PlanOutcome {
    let req = PlanRequest {
        risk_mode: mode,
        delta: Some(RiskLevel::from_f64(delta).unwrap()),
        time_limit: std::time::Duration::from_secs(60),
        ..Default::default()
    };
    req.run(s.clone(), None).unwrap().1
}

/// Every reference planning scene at Δ = 0.1 and 0.01 in trajectory mode: a certified
/// plan, its whole-path bound (reported by the final check) ≤ Δ and at least the audit's
/// lower end, and the audit ≤ Δ at 99 % (its upper end). Prints the conservatism (bound ÷
/// estimate; docs/benchmarks.md, "The whole-path bound and trajectory mode").
#[test]
fn reference_scenes_in_trajectory_mode_keep_the_whole_path_within_delta() {
    for name in [
        "illustrative-3",
        "illustrative-4",
        "example-b-lane-change",
        "example-c-delivery",
        "example-d1-cluttered-2d",
        "example-d2-cluttered-3d",
    ] {
        let s = Arc::new(scene(name));
        for delta in [0.1, 0.01] {
            let t = std::time::Instant::now();
            let out = plan(&s, RiskMode::Trajectory, delta);
            let seconds = t.elapsed().as_secs_f64();
            let traj =
                out.trajectory.as_ref().unwrap_or_else(|| panic!("{name} at {delta}: no plan: {:?}", out.reason));
            assert!(out.certified, "{name} at {delta}");
            let bound = out.stats.whole_path_risk.expect("the final check reports the whole-path bound");
            let (_, any) = audit_whole_path(&s, traj, &audit_options(7)).unwrap();
            println!(
                "{name} Δ = {delta}: plan in {seconds:.2} s, {} pieces, whole-path bound {bound:.3e}, audit {:.3e} [{:.3e}, {:.3e}], bound/audit {:.2}",
                traj.pieces.len(),
                any.estimate,
                any.lower,
                any.upper,
                if any.estimate > 0.0 { bound / any.estimate } else { f64::NAN }
            );
            assert!(bound <= delta, "{name} at {delta}: bound {bound}");
            assert!(bound >= any.lower, "{name} at {delta}: bound {bound} below the audit's lower end {}", any.lower);
            assert!(any.upper <= delta, "{name} at {delta}: the audit's upper end {} exceeds Δ", any.upper);
        }
    }
}

/// The constructed scene (tests/scenes/whole_path/bollard-corridor.json): a corridor
/// between two rows of five disks with Gaussian centres. At Δ = 0.3 each disk's
/// per-instant risk on the corridor's axis is certified within Δ, so the paper's mode
/// takes the straight line — which meets some disk in more than 30 % of the scenarios
/// (audited). The trajectory-mode plan keeps its whole-path bound within Δ, and its audit
/// agrees.
#[test]
fn a_corridor_of_uncertain_disks_is_refused_per_path_and_taken_per_instant() {
    let path = crate::common::repo().join("tests/scenes/whole_path/bollard-corridor.json");
    let s = Arc::new(Scene::from_json(&std::fs::read_to_string(&path).unwrap()).unwrap());
    let delta = 0.3;
    let per_instant = plan(&s, RiskMode::PerObstacle, delta);
    let traj = per_instant.trajectory.as_ref().expect("a per-instant plan");
    let (_, any) = audit_whole_path(&s, traj, &audit_options(8)).unwrap();
    println!(
        "per-instant plan: {} pieces, whole-path bound {:?}, audit {:.4} [{:.4}, {:.4}]",
        traj.pieces.len(),
        per_instant.stats.whole_path_risk,
        any.estimate,
        any.lower,
        any.upper
    );
    assert!(any.lower > delta, "the per-instant plan's audited whole-path risk {} is not above Δ", any.estimate);
    let whole = plan(&s, RiskMode::Trajectory, delta);
    let traj = whole.trajectory.as_ref().expect("a trajectory-mode plan");
    let bound = whole.stats.whole_path_risk.expect("reported");
    let (_, any) = audit_whole_path(&s, traj, &audit_options(9)).unwrap();
    println!(
        "trajectory-mode plan: {} pieces, whole-path bound {bound:.4}, audit {:.4} [{:.4}, {:.4}]",
        traj.pieces.len(),
        any.estimate,
        any.lower,
        any.upper
    );
    assert!(bound <= delta && bound >= any.lower, "bound {bound}, audit {any:?}");
    assert!(any.upper <= delta, "the trajectory-mode plan's audit {} exceeds Δ", any.upper);
}

/// The paper's planner does not budget whole paths: a typed refusal.
#[test]
fn the_paper_planner_refuses_trajectory_mode() {
    let s = Arc::new(scene("illustrative-3"));
    let req = PlanRequest {
        planner: riskplan_app::PlannerKind::RrtSosPaper,
        risk_mode: RiskMode::Trajectory,
        ..Default::default()
    };
    match req.run(s, None) {
        Err(riskplan_plan::PlanError::InvalidOption { option, .. }) => assert_eq!(option, "risk_mode"),
        other => panic!("{:?}", other.map(|o| o.1.status)),
    }
}
