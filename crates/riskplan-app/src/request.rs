//! The typed plan request every front end builds (the CLI's flags, the service's wire
//! message, the bench, the tests), the problem it poses on a scene, and the prepared
//! plan it makes: the problem, the planner and its checker, each option checked once.

use crate::allocate::allocate;
use crate::prepared::PreparedPlan;
use crate::verify::{Method, SceneKernel};
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_plan::{
    Built, Kinematics, PlanError, PlanOptions, PlanOutcome, PlannerKind, Problem, RiskMode, Setup, Termination,
};
use riskplan_scene::Scene;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// The time limit of a plan from seconds: positive and finite.
pub fn time_limit(seconds: f64) -> Result<Duration, PlanError> {
    (seconds > 0.0).then(|| Duration::try_from_secs_f64(seconds).ok()).flatten().ok_or_else(|| {
        PlanError::InvalidRequest {
            field: "time_limit".into(),
            message: format!("must be a positive, finite number of seconds, got {seconds}"),
        }
    })
}

/// One plan request, typed and validated: what every front end builds from its input.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanRequest {
    /// Which planner.
    pub planner: PlannerKind,
    /// How RRT-SOS certifies its edges (ignored by the Monte Carlo baseline).
    pub certifier: Method,
    /// Risk level Δ; `None`: the scene's.
    pub delta: Option<RiskLevel>,
    /// Start and goal; `None`: the scene's.
    pub endpoints: Option<(Vec<f64>, Vec<f64>)>,
    /// Seed of the planner's RNG (and of the baseline's scenarios).
    pub seed: u64,
    /// Pieces of the time-layered planner; `Some` forces it.
    pub pieces: Option<usize>,
    /// The improve step of the paper's static planner.
    pub improve: bool,
    /// How long the planner may run.
    pub time_limit: Duration,
    /// Speed limit (`None`: the scene's `planner.max_speed`, if any).
    pub max_speed: Option<f64>,
    /// Acceleration limit for smoothing (`None`: the scene's, if any).
    pub max_accel: Option<f64>,
    /// Shortcut and blend the plan (default planners; on by default).
    pub smooth: bool,
    /// What Δ bounds.
    pub risk_mode: RiskMode,
    /// Which risk bounds may prove safety: `auto` (the tightest sound one) or `cantelli`
    /// (the paper's; docs/design.md §3.7–§3.10, §5.13). `None`: the scene's
    /// `planner.bound`, else `auto` ([`BoundChoice`]).
    pub bound: Option<BoundChoice>,
    /// A receding-horizon request (docs/design.md §6.9): plan from the robot's current
    /// state over a window; `None`: the scene's start at its horizon's start to the goal
    /// at its end.
    pub receding: Option<RecedingRequest>,
}

/// The robot's state and the window of a receding-horizon request (docs/design.md §6.9).
#[derive(Clone, Debug, PartialEq)]
pub struct RecedingRequest {
    /// The current time (inside the scene's horizon).
    pub t_now: f64,
    /// The robot's position at `t_now`.
    pub position: Vec<f64>,
    /// Its velocity at `t_now` (`None`: at rest).
    pub velocity: Option<Vec<f64>>,
    /// The window's length H (> 0): the plan covers `[t_now, t_now + H]`, cut at the
    /// scene's horizon.
    pub horizon: f64,
    /// The goal.
    pub goal: Vec<f64>,
    /// The previous plan, to continue where it still holds.
    pub warm_start: Option<Arc<riskplan_scene::Trajectory>>,
}

/// The time limit of a request that gives none (the service's default).
pub const DEFAULT_TIME_LIMIT: Duration = Duration::from_secs(10);

impl Default for PlanRequest {
    fn default() -> Self {
        PlanRequest {
            planner: PlannerKind::RrtSos,
            certifier: Method::Exact,
            delta: None,
            endpoints: None,
            seed: 1,
            pieces: None,
            improve: false,
            time_limit: DEFAULT_TIME_LIMIT,
            max_speed: None,
            max_accel: None,
            smooth: true,
            risk_mode: RiskMode::PerObstacle,
            bound: None,
            receding: None,
        }
    }
}

impl PlanRequest {
    /// The problem this request poses on `scene`.
    pub fn problem(&self, scene: Arc<Scene>) -> Result<Problem, PlanError> {
        if let Some(r) = &self.receding {
            return self.receding_problem(scene, r);
        }
        let mut p = match &self.endpoints {
            Some((start, goal)) => Problem {
                horizon: scene.horizon,
                delta: scene.risk.clone(),
                start: start.clone(),
                goal: goal.clone(),
                scene,
                seed: self.seed,
                receding: false,
                start_velocity: None,
                warm_start: None,
            },
            None => Problem::from_scene(scene, self.seed)?,
        };
        if let Some(d) = &self.delta {
            p.delta = d.clone();
        }
        Ok(p)
    }

    fn receding_problem(&self, scene: Arc<Scene>, r: &RecedingRequest) -> Result<Problem, PlanError> {
        let bad = |field: &str, message: String| PlanError::InvalidRequest { field: field.into(), message };
        let (h0, h1) = scene.horizon;
        if !(r.t_now >= h0 && r.t_now < h1) {
            return Err(bad("t_now", format!("{} is outside the scene's horizon [{h0}, {h1})", r.t_now)));
        }
        if !(r.horizon > 0.0 && r.horizon.is_finite()) {
            return Err(bad("horizon", format!("must be a positive number of time units, got {}", r.horizon)));
        }
        let end = (r.t_now + r.horizon).min(h1);
        if end <= r.t_now {
            return Err(bad("horizon", format!("the window [{}, {end}] is empty", r.t_now)));
        }
        if let Some(v) = &r.velocity {
            if v.len() != scene.dim || v.iter().any(|c| !c.is_finite()) {
                return Err(bad("velocity", format!("needs {} finite coordinates, got {v:?}", scene.dim)));
            }
        }
        if r.position.len() != scene.dim {
            return Err(bad("position", format!("needs {} coordinates, got {}", scene.dim, r.position.len())));
        }
        Ok(Problem {
            horizon: (r.t_now, end),
            delta: self.delta.clone().unwrap_or_else(|| scene.risk.clone()),
            start: r.position.clone(),
            goal: r.goal.clone(),
            scene,
            seed: self.seed,
            receding: true,
            start_velocity: r.velocity.clone(),
            warm_start: r.warm_start.clone(),
        })
    }

    /// The planner this request runs: a receding request runs the receding-horizon
    /// planner (named or by default), and no other.
    pub fn planner_kind(&self) -> Result<PlannerKind, PlanError> {
        match (&self.receding, self.planner) {
            (Some(_), PlannerKind::RrtSos | PlannerKind::Receding) => Ok(PlannerKind::Receding),
            (Some(_), other) => Err(PlanError::InvalidOption {
                option: "planner".into(),
                message: format!("{other} does not plan receding-horizon requests (use the default, receding)"),
            }),
            (None, PlannerKind::Receding) => Err(PlanError::InvalidOption {
                option: "planner".into(),
                message: "receding needs a receding-horizon request (t_now, position, horizon)".into(),
            }),
            (None, k) => Ok(k),
        }
    }

    /// The problem, the planner and the checker, with every option checked, on a scene
    /// (or its [`SceneKernel`], to share what its checkers cache across plans).
    pub fn prepare(&self, scene: impl Into<SceneKernel>) -> Result<PreparedPlan, PlanError> {
        let kernel = scene.into();
        let problem = self.problem(kernel.scene().clone())?;
        let bound = self.bound_on(kernel.scene());
        let options = PlanOptions {
            pieces: self.pieces,
            improve: self.improve,
            kinematics: Kinematics { max_speed: self.max_speed, max_accel: self.max_accel, smooth: self.smooth },
            certifier: self.certifier,
            risk_mode: self.risk_mode,
            bounds: bound,
        };
        let deltas = allocate(&kernel, &problem, self.risk_mode, bound)?;
        let setup = Setup { problem: &problem, kernel: &kernel, deltas: &deltas, options: &options };
        let kind = self.planner_kind()?;
        let Built { planner, checker } = kind.build(&setup)?;
        let allocation = matches!(self.risk_mode, RiskMode::JointUniform | RiskMode::JointWeighted)
            .then(|| problem.scene.obstacles.iter().zip(&deltas).map(|(o, d)| (o.id.clone(), d.to_f64())).collect());
        Ok(PreparedPlan {
            problem,
            planner,
            checker,
            allocation,
            deltas,
            kernel,
            bounds: bound,
            risk_mode: self.risk_mode,
            kind,
            options,
        })
    }

    /// The bounds this request uses on `scene`: its own, else the scene's
    /// `planner.bound`, else the default (`auto`).
    pub fn bound_on(&self, scene: &Scene) -> BoundChoice {
        self.bound.or_else(|| scene.file.planner.as_ref().and_then(|b| b.bound)).unwrap_or_default()
    }

    /// When to stop: this request's time limit from now, and `cancel` if given.
    pub fn termination(&self, cancel: Option<Arc<AtomicBool>>) -> Termination {
        let t = Termination::after(self.time_limit);
        match cancel {
            Some(c) => t.with_cancel(c),
            None => t,
        }
    }

    /// Prepares and runs the request; returns the problem it solved and the outcome.
    pub fn run(
        &self,
        scene: impl Into<SceneKernel>,
        cancel: Option<Arc<AtomicBool>>,
    ) -> Result<(Problem, PlanOutcome), PlanError> {
        let mut prepared = self.prepare(scene)?;
        let outcome = prepared.solve(&self.termination(cancel))?;
        Ok((prepared.problem, outcome))
    }
}

/// Why an outcome has no trajectory, in one line (for replies and messages).
pub fn no_plan_reason(out: &PlanOutcome, limit: Duration) -> String {
    match &out.reason {
        Some(riskplan_plan::NoPlanReason::DeadlineReached { iterations, edges_checked, pieces_tried, ladder })
            if ladder.is_empty() =>
        {
            format!(
                "no plan within the time limit of {} s ({iterations} iterations, {edges_checked} edges checked{})",
                limit.as_secs_f64(),
                if pieces_tried.is_empty() { String::new() } else { format!(", pieces tried {pieces_tried:?}") }
            )
        }
        Some(r) => r.message(),
        None => format!("no plan ({} iterations, {} edges checked)", out.stats.iterations, out.stats.edges_checked),
    }
}
