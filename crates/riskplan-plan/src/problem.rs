//! The problem definition every planner takes.

use super::PlanError;
use riskplan_math::contour::RiskLevel;
use riskplan_scene::Scene;
use std::sync::Arc;

/// A planning problem, immutable while a planner runs.
#[derive(Clone, Debug)]
pub struct Problem {
    /// The scene with its cached contours.
    pub scene: Arc<Scene>,
    /// x(t0).
    pub start: Vec<f64>,
    /// x(tf).
    pub goal: Vec<f64>,
    /// `[t0, tf]`.
    pub horizon: (f64, f64),
    /// Risk level Δ (exact, validated).
    pub delta: RiskLevel,
    /// Seed of the planner's RNG.
    pub seed: u64,
    /// A receding-horizon problem (docs/design.md §6.9): `horizon` is the window
    /// `[t_now, t_now + H]`, `start` the robot's position at `t_now`, and the plan may end
    /// short of the goal.
    pub receding: bool,
    /// The robot's velocity at the start (receding problems; `None`: at rest).
    pub start_velocity: Option<Vec<f64>>,
    /// A previous plan to continue from, if it still holds (receding problems).
    pub warm_start: Option<Arc<riskplan_scene::Trajectory>>,
}

impl Problem {
    /// The scene's own start, goal, horizon and Δ.
    pub fn from_scene(scene: Arc<Scene>, seed: u64) -> Result<Problem, PlanError> {
        let (Some(start), Some(goal)) = (scene.start.clone(), scene.goal.clone()) else {
            return Err(PlanError::InvalidRequest {
                field: "start".into(),
                message: format!("scene '{}' has no start and goal (a contour-only scene)", scene.name),
            });
        };
        Ok(Problem {
            horizon: scene.horizon,
            delta: scene.risk.clone(),
            start,
            goal,
            scene,
            seed,
            receding: false,
            start_velocity: None,
            warm_start: None,
        })
    }

    /// Whether any obstacle moves.
    pub fn is_dynamic(&self) -> bool {
        self.scene.obstacles.iter().any(|o| o.is_dynamic())
    }

    /// Checks the request: dimensions, workspace, a non-empty horizon (Δ is a
    /// [`RiskLevel`], valid by construction).
    pub fn validate(&self) -> Result<(), PlanError> {
        let s = &self.scene;
        if !self.horizon.0.is_finite() || !self.horizon.1.is_finite() || self.horizon.0 >= self.horizon.1 {
            return Err(PlanError::InvalidRequest { field: "horizon".into(), message: "needs finite t0 < tf".into() });
        }
        for (name, p) in [("start", &self.start), ("goal", &self.goal)] {
            if p.len() != s.dim {
                return Err(PlanError::InvalidRequest {
                    field: name.into(),
                    message: format!("needs {} coordinates, got {}", s.dim, p.len()),
                });
            }
            if p.iter().any(|v| !v.is_finite()) || !s.workspace.contains(p) {
                return Err(PlanError::OutsideWorkspace { which: name.into(), point: p.clone() });
            }
        }
        Ok(())
    }
}
