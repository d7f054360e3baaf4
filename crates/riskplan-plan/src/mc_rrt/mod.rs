//! `mc-rrt`, the Monte Carlo baseline (docs/design.md §6.7): the default planner's
//! search (`crate::rrt`) with the paper's sampling edge check (`checker.rs`).
//! Uncertified: its plans say `certified: false`.

mod checker;

pub use checker::{McChecker, McCheckerParams};

use crate::{rrt_planner, Built, PaperRun, PlanError, PlannerSpec, RiskMode, Setup};

/// `mc-rrt`.
pub static SPEC: PlannerSpec = PlannerSpec {
    certified: false,
    build: |s: &Setup<'_>| {
        let planner = rrt_planner(s.problem, false, s.options)?;
        if s.options.risk_mode != RiskMode::PerObstacle {
            return Err(PlanError::InvalidOption {
                option: "risk_mode".into(),
                message: "mc-rrt checks the paper's per-obstacle risk only".into(),
            });
        }
        let p = s.problem;
        let model = p.scene.mc_model().map_err(|e| PlanError::InvalidOption {
            option: "planner".into(),
            message: format!("mc-rrt needs parameters it can sample: {e}"),
        })?;
        let checker = McChecker::new(model, p.delta.to_f64(), McCheckerParams::default(), p.seed);
        Ok(Built { planner, checker: Box::new(checker) })
    },
    paper_runs: |scene| {
        let dynamic = scene.obstacles.iter().any(|o| o.is_dynamic());
        let key = (!dynamic).then_some("monte_carlo_rrt_feasible");
        vec![PaperRun { label: "mc-rrt", improve: false, paper_key: key }]
    },
};
