//! The application layer (above the planners, below every front end): one typed
//! plan request, turned into a problem, a planner and a motion checker in one
//! place. The CLI, the service, the bench and the tests all go through
//! [`PlanRequest`], so a planner added here is available to each of them at once.

use crate::contour::RiskLevel;
use crate::plan::{
    rrt_planner, McChecker, McCheckerParams, MotionChecker, PlanError, PlanOutcome, PlanStatus, Planner, Problem,
    Termination,
};
use crate::scene::Scene;
use crate::verify::{Method, SceneCertifier};
use std::fmt;
use std::str::FromStr;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;

/// The planners a request can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PlannerKind {
    /// RRT-SOS: every edge certified in continuous time (eq. 15); the static tree on
    /// static scenes, the time-layered tree when an obstacle moves or pieces are given.
    RrtSos,
    /// The paper's Monte Carlo RRT baseline (K scenarios × W waypoints per edge):
    /// uncertified, its plans say `certified: false`.
    McRrt,
}

impl PlannerKind {
    /// Every planner, in the order help texts list them.
    pub const ALL: [PlannerKind; 2] = [PlannerKind::RrtSos, PlannerKind::McRrt];

    /// The name on the command line and on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            PlannerKind::RrtSos => "rrt-sos",
            PlannerKind::McRrt => "mc-rrt",
        }
    }
}

impl fmt::Display for PlannerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A name that is not one of the accepted ones.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("unknown {what} '{name}' ({expected})")]
pub struct UnknownName {
    /// What was named (`planner`).
    pub what: &'static str,
    /// The name given.
    pub name: String,
    /// The accepted names.
    pub expected: String,
}

impl FromStr for PlannerKind {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        PlannerKind::ALL.into_iter().find(|k| k.as_str() == s).ok_or_else(|| UnknownName {
            what: "planner",
            name: s.to_string(),
            expected: PlannerKind::ALL.map(|k| k.as_str()).join(" or "),
        })
    }
}

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
    /// The improve step of the static planner.
    pub improve: bool,
    /// How long the planner may run.
    pub time_limit: Duration,
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
        }
    }
}

/// A request made ready to run: the problem, the planner and its motion checker.
pub struct PreparedPlan {
    /// The problem (scene, endpoints, horizon, Δ, seed).
    pub problem: Problem,
    /// The planner.
    pub planner: Box<dyn Planner>,
    /// The motion checker the planner consults.
    pub checker: Box<dyn MotionChecker>,
}

impl PreparedPlan {
    /// Runs the planner until it finishes or `term` says stop.
    pub fn solve(&mut self, term: &Termination) -> Result<PlanOutcome, PlanError> {
        self.planner.solve(&self.problem, self.checker.as_ref(), term)
    }
}

impl PlanRequest {
    /// The problem this request poses on `scene`.
    pub fn problem(&self, scene: Arc<Scene>) -> Result<Problem, PlanError> {
        let mut p = match &self.endpoints {
            Some((start, goal)) => Problem {
                horizon: scene.horizon,
                delta: scene.risk.clone(),
                start: start.clone(),
                goal: goal.clone(),
                scene,
                seed: self.seed,
            },
            None => Problem::from_scene(scene, self.seed)?,
        };
        if let Some(d) = &self.delta {
            p.delta = d.clone();
        }
        Ok(p)
    }

    /// The problem, the planner and the checker, with every option checked.
    pub fn prepare(&self, scene: Arc<Scene>) -> Result<PreparedPlan, PlanError> {
        let problem = self.problem(scene)?;
        let planner = rrt_planner(&problem, self.pieces, self.improve)?;
        let checker: Box<dyn MotionChecker> = match self.planner {
            PlannerKind::RrtSos => {
                Box::new(SceneCertifier::new(problem.scene.clone(), problem.delta.clone(), self.certifier))
            }
            PlannerKind::McRrt => {
                let model = problem.scene.mc_model().map_err(|e| PlanError::InvalidOption {
                    option: "planner".into(),
                    message: format!("mc-rrt needs parameters it can sample: {e}"),
                })?;
                Box::new(McChecker::new(model, problem.delta.to_f64(), McCheckerParams::default(), self.seed))
            }
        };
        Ok(PreparedPlan { problem, planner, checker })
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
    pub fn run(&self, scene: Arc<Scene>, cancel: Option<Arc<AtomicBool>>) -> Result<(Problem, PlanOutcome), PlanError> {
        let mut prepared = self.prepare(scene)?;
        let outcome = prepared.solve(&self.termination(cancel))?;
        Ok((prepared.problem, outcome))
    }
}

/// Why an outcome has no trajectory, in one line (for replies and messages).
pub fn no_plan_reason(out: &PlanOutcome, limit: Duration) -> String {
    let why = match out.status {
        PlanStatus::DeadlineReached => format!("no plan within the time limit of {} s", limit.as_secs_f64()),
        PlanStatus::Cancelled => "the plan was cancelled".into(),
        PlanStatus::Exhausted | PlanStatus::Exact => "no plan within the planner's iteration limits".into(),
    };
    format!("{why} ({} iterations, {} edges checked)", out.stats.iterations, out.stats.edges_checked)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planner_names_round_trip_and_unknown_names_are_typed_errors() {
        for k in PlannerKind::ALL {
            assert_eq!(k.as_str().parse::<PlannerKind>(), Ok(k));
        }
        let e = "rrt".parse::<PlannerKind>().unwrap_err();
        assert_eq!(e.to_string(), "unknown planner 'rrt' (rrt-sos or mc-rrt)");
    }

    #[test]
    fn time_limits_must_be_positive_and_finite() {
        assert_eq!(time_limit(1.5), Ok(Duration::from_millis(1500)));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e300] {
            assert!(matches!(time_limit(bad), Err(PlanError::InvalidRequest { .. })), "{bad}");
        }
    }
}
