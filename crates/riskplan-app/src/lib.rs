//! The application layer (above the planners, below every front end): one typed
//! plan request, turned into a problem, a planner and a motion checker in one
//! place. The CLI, the service, the bench and the tests all go through
//! [`PlanRequest`], so a planner added here is available to each of them at once.
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan-service`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan_service::ServiceError;
//! ```

pub mod crowd;
pub mod names;
pub mod verify;

mod acceptance;
mod allocate;
mod prepared;
mod request;
mod warm;

/// The git commit this build was made from (`build.rs`: `RISKPLAN_GIT_COMMIT` from the
/// build's environment, else `git rev-parse HEAD`, else "unknown"): the service's
/// `riskplan_build_info` metric and the bench's records carry it.
pub const GIT_COMMIT: &str = env!("RISKPLAN_GIT_COMMIT");

pub use acceptance::{FINAL_CHECK_GRACE, WHOLE_PATH_BESIDE_MIN_OBSTACLES, WHOLE_PATH_SLACK_SHARE};
pub use allocate::allocate;
pub use prepared::PreparedPlan;
pub use request::{no_plan_reason, time_limit, PlanRequest, RecedingRequest, DEFAULT_TIME_LIMIT};
pub use riskplan_plan::{PlannerKind, RiskMode, UnknownName};
pub use warm::{warm_up, WarmUp};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::verify::SceneKernel;
    use riskplan_plan::{PlanError, PlanOutcome};
    use riskplan_scene::Scene;
    use std::sync::Arc;
    use std::time::Duration;

    #[test]
    fn planner_names_round_trip_and_unknown_names_are_typed_errors() {
        for k in PlannerKind::ALL {
            assert_eq!(k.as_str().parse::<PlannerKind>(), Ok(k));
        }
        let e = "rrt".parse::<PlannerKind>().unwrap_err();
        let names: Vec<&str> = PlannerKind::ALL.iter().map(|k| k.as_str()).collect();
        assert_eq!(e.to_string(), format!("unknown planner 'rrt' ({})", names.join(", ")));
        assert!(e.to_string().contains("tv-sos"), "{e}");
    }

    /// `n` uncertain disks (radius scaled by U(0.9, 1.1), centre shifted by N(0, 0.05)) on
    /// a lattice-like spread in a square 10·√n wide, start and goal in opposite corners.
    fn disks(n: usize) -> Arc<Scene> {
        let side = 10.0 * (n as f64).sqrt();
        let mut params = serde_json::Map::new();
        let mut obstacles = Vec::new();
        for k in 0..n {
            let u = |a: u64| ((k as u64 * a + 7) % 1000) as f64 / 1000.0;
            let (cx, cy, r) = (5.0 + u(377) * (side - 10.0), 5.0 + u(613) * (side - 10.0), 0.8 + 0.8 * u(271));
            params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
            params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
            obstacles.push(serde_json::json!({"id": format!("disk{k}"),
                "poly": format!("({r:.2}*s{k})^2 - (x1 - {cx:.2} - d{k})^2 - (x2 - {cy:.2})^2")}));
        }
        let json = serde_json::json!({"format": "riskplan-scene/1", "name": "disks", "dim": 2,
            "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
            "params": params, "obstacles": obstacles, "start": [0.5, 0.5], "goal": [side - 0.5, side - 0.5]});
        Arc::new(Scene::from_json(&json.to_string()).unwrap())
    }

    #[test]
    fn a_warm_up_builds_what_a_plan_would() {
        let scene = disks(24);
        let deltas = vec![scene.risk.clone(); scene.obstacles.len()];
        // the oracle: what a default plan on a fresh kernel leaves built
        let planned = SceneKernel::new(scene.clone());
        assert!(!planned.is_warm(&deltas));
        let (_, cold) = PlanRequest::default().run(&planned, None).unwrap();
        assert!(cold.certified);
        assert!(planned.is_warm(&deltas), "a plan builds all of it: the oracle must hold");
        // a warm-up stopped at once builds none of it, and says so
        let stopped = SceneKernel::new(scene.clone());
        assert_eq!(warm_up(&stopped, &|| true), WarmUp::Stopped);
        assert!(!stopped.is_warm(&deltas));
        // a warm-up builds all of it, and the plan on the warm kernel is the same plan
        let warmed = SceneKernel::new(scene.clone());
        assert_eq!(warm_up(&warmed, &|| false), WarmUp::Done);
        assert!(warmed.is_warm(&deltas));
        // ... and what plans build per obstacle where their edges go, for every obstacle
        // (the cold plan built it for some only)
        let n = scene.obstacles.len();
        let some = planned.obstacles_built(true);
        assert!(some > 0 && some < n, "{some} of {n}: the plan's edges do not go everywhere");
        assert_eq!(warmed.obstacles_built(true), n);
        let (_, warm) = PlanRequest::default().run(&warmed, None).unwrap();
        let pieces = |o: &PlanOutcome| o.trajectory.as_ref().map(|t| t.pieces.clone());
        assert_eq!(pieces(&warm), pieces(&cold));
        assert_eq!(warm.stats.whole_path_risk, cold.stats.whole_path_risk);
    }

    /// How far the sum of a window's sub-intervals, each converted to seconds on its own,
    /// may exceed the window's own conversion: a few roundings of `as_secs_f64` (about
    /// 10⁻¹⁶ s each here), far below any interval measured.
    const SECONDS_ROUNDING: f64 = 1e-12;

    #[test]
    fn a_plans_phase_times_are_parts_of_its_totals() {
        // 64 obstacles: the whole-path bound runs beside the verify path; 8: after it
        for n in [WHOLE_PATH_BESIDE_MIN_OBSTACLES, 8] {
            let (_, out) = PlanRequest::default().run(SceneKernel::new(disks(n)), None).unwrap();
            assert!(out.certified, "{n} disks: {:?}", out.reason);
            let st = &out.stats;
            let sm = st.smoothing.as_ref().expect("a default plan is smoothed");
            let parts = [sm.shortcut_seconds, sm.reduction_seconds, sm.blend_seconds];
            assert!(parts.iter().all(|&t| t > 0.0), "{n} disks: {sm:?}");
            assert!(parts.iter().sum::<f64>() <= st.improve_time_s + SECONDS_ROUNDING, "{n} disks: {sm:?} {st:?}");
            let fc = st.final_check.as_ref().expect("a certified plan's final check");
            assert!(fc.verify_seconds > 0.0 && fc.whole_path_seconds > 0.0, "{n} disks: {fc:?}");
            assert!(fc.verify_seconds <= fc.seconds + SECONDS_ROUNDING, "{n} disks: {fc:?}");
            // (after the check, on a small scene, the bound is the rest of the final check)
            if n < WHOLE_PATH_BESIDE_MIN_OBSTACLES {
                assert!(fc.verify_seconds + fc.whole_path_seconds <= fc.seconds + SECONDS_ROUNDING, "{fc:?}");
            }
            assert!(st.improve_time_s + fc.seconds <= st.planning_time_s + SECONDS_ROUNDING, "{n} disks: {st:?}");
        }
    }

    #[test]
    fn time_limits_must_be_positive_and_finite() {
        assert_eq!(time_limit(1.5), Ok(Duration::from_millis(1500)));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e300] {
            assert!(matches!(time_limit(bad), Err(PlanError::InvalidRequest { .. })), "{bad}");
        }
    }
}
