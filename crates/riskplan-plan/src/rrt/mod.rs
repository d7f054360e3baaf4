//! The RRT planners (docs/design.md §6): the default RRT-SOS — the connect planner
//! (`connect.rs`) on static scenes, the time-layered tree with the piece ladder
//! (`layered.rs`) on moving ones, then certified shortcutting and C¹ corner blends
//! (`smooth.rs`) — and the paper's RRT-SOS as published (`paper_static.rs`, or the
//! layered tree with the paper's stripes), with the stripe sampler (`sampling.rs`) and
//! the scene's length scales (`scale.rs`).

mod connect;
mod layered;
mod paper_static;
mod sampling;
pub mod scale;
pub mod smooth;

pub use connect::{ConnectParams, ConnectRrt};
pub use layered::{LayeredParams, LayeredRrt};
pub use paper_static::{RrtParams, StaticRrt};
pub use sampling::StripeSampler;

use crate::{Built, Kinematics, PaperRun, PlanError, PlanOptions, Planner, PlannerSpec, Problem, RiskMode, Setup};
use riskplan_certify::checker::SceneCertifier;
use riskplan_scene::Scene;

/// `rrt-sos`, the default: every edge certified by the scene certifier with its
/// covers and fast path.
pub static DEFAULT: PlannerSpec = PlannerSpec {
    certified: true,
    build: |s| build(s, false),
    paper_runs: |_| vec![PaperRun { label: "rrt-sos", improve: false, paper_key: None }],
};

/// `rrt-sos-paper`: the paper's RRT-SOS as published.
pub static PAPER: PlannerSpec = PlannerSpec {
    certified: true,
    build: |s| build(s, true),
    paper_runs: |scene: &Scene| {
        if scene.obstacles.iter().any(|o| o.is_dynamic()) {
            vec![PaperRun { label: "rrt-sos-paper", improve: false, paper_key: Some("rrt_sos") }]
        } else {
            vec![
                PaperRun { label: "rrt-sos-paper", improve: false, paper_key: Some("rrt_sos_feasible") },
                PaperRun { label: "rrt-sos-paper --improve", improve: true, paper_key: Some("rrt_sos_optimal") },
            ]
        }
    },
};

fn build(s: &Setup<'_>, paper: bool) -> Result<Built, PlanError> {
    let mut checker =
        SceneCertifier::with_deltas(s.kernel, s.deltas.to_vec(), s.options.certifier).with_bounds(s.options.bounds);
    if let Some(budget) = path_budget(s.problem, s.options) {
        checker = checker.with_path_risk(budget * PATH_RISK_NEGLIGIBLE_SHARE);
    }
    Ok(Built { planner: rrt_planner(s.problem, paper, s.options)?, checker: Box::new(checker) })
}

/// A piece's whole-path bound below this share of Δ is not refined further while planning
/// (its partition stops): 10⁻⁴ of the budget per obstacle and piece leaves the budget
/// to the pieces that pass near obstacles.
pub const PATH_RISK_NEGLIGIBLE_SHARE: f64 = 1e-4;

/// The whole-path budget of a `risk_mode: trajectory` request: Δ rounded down to a float
/// (the planners compare sums of upper bounds with it); `None` in the other modes.
pub fn path_budget(p: &Problem, o: &PlanOptions) -> Option<f64> {
    (o.risk_mode == RiskMode::Trajectory).then(|| p.delta.floor_f64())
}

/// The planner a problem calls for. `paper`: the paper's RRT-SOS (static tree, or the
/// time-layered tree when an obstacle moves or `pieces` is given), parameters from the
/// scene's `planner.rrt_sos` block or scale-free defaults. Otherwise the default: the
/// connect planner on static scenes, the layered planner with the ladder and local
/// sampling on moving ones; both smoothed unless asked not to.
pub fn rrt_planner(p: &Problem, paper: bool, o: &PlanOptions) -> Result<Box<dyn Planner>, PlanError> {
    let block = p.scene.file.planner.as_ref();
    let rrt_block = block.and_then(|b| b.rrt_sos.as_ref());
    let kinematics = o.kinematics.or_block(block)?;
    let scale = scale::Scale::of(p);
    let layered = o.pieces.is_some() || p.is_dynamic();
    let budget = path_budget(p, o);
    if budget.is_some() && paper {
        return Err(PlanError::InvalidOption {
            option: "risk_mode".into(),
            message: "trajectory is planned by the default rrt-sos (the paper's planner bounds each instant only)"
                .into(),
        });
    }
    if o.improve && (layered || !paper) {
        return Err(PlanError::InvalidOption {
            option: "improve".into(),
            message: "applies to the paper's static planner only (rrt-sos-paper on a static scene); the default planner shortcuts its path instead".into(),
        });
    }
    if layered {
        let mut params = if paper { LayeredParams::paper(rrt_block, &scale) } else { LayeredParams::fast(&scale) };
        if o.pieces.is_some() {
            params.pieces = o.pieces;
        }
        params.kinematics = Kinematics { smooth: kinematics.smooth && !paper, ..kinematics };
        params.path_budget = budget;
        Ok(Box::new(LayeredRrt::new(params)))
    } else if paper {
        let mut params = RrtParams::paper(rrt_block, &scale);
        params.improve = o.improve;
        params.kinematics = Kinematics { max_accel: None, smooth: false, ..kinematics };
        Ok(Box::new(StaticRrt::new(params)))
    } else {
        Ok(Box::new(ConnectRrt { params: ConnectParams { kinematics, path_budget: budget, ..Default::default() } }))
    }
}
