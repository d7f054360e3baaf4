//! Scale-free defaults (docs/design.md §6.7): every length a planner uses is derived
//! from the problem — the workspace extent, the start–goal distance, the number of
//! obstacles — and every time from the horizon, so that a scene and its copy scaled,
//! shifted and with its horizon shifted behave alike in their own units. The paper's
//! unit-sized scenes get the paper's values (`rlim = 1` and stripes `0.1 … 1` on the
//! 2-wide workspace of illustrative-3). A scene's `planner.rrt_sos` block overrides.

use crate::{dist, Problem};

/// Lengths of one problem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// Largest side of the workspace box.
    pub side: f64,
    /// Diagonal of the workspace box.
    pub diagonal: f64,
    /// Distance from start to goal.
    pub start_goal: f64,
    /// Duration of the horizon.
    pub duration: f64,
    /// Number of obstacles.
    pub obstacles: usize,
    /// Spatial dimension.
    pub dim: usize,
}

impl Scale {
    /// The lengths of `p`.
    pub fn of(p: &Problem) -> Scale {
        let ws = &p.scene.workspace;
        let sides: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(l, u)| u - l).collect();
        Scale {
            side: sides.iter().cloned().fold(0.0, f64::max),
            diagonal: sides.iter().map(|s| s * s).sum::<f64>().sqrt(),
            start_goal: dist(&p.start, &p.goal),
            duration: p.horizon.1 - p.horizon.0,
            obstacles: p.scene.obstacles.len(),
            dim: p.scene.dim,
        }
    }

    /// The paper's steering step `rlim` in these units: half the largest side (1 on the
    /// paper's 2-wide workspaces).
    pub fn paper_step(&self) -> f64 {
        0.5 * self.side
    }

    /// The paper's stripe half-widths `0.1:0.1:1` in these units (`side·(0.05 … 0.5)`).
    pub fn paper_static_widths(&self) -> Vec<f64> {
        (1..=10).map(|k| self.side * 0.05 * k as f64).collect()
    }

    /// The paper's layered stripe half-widths `0.1:0.1:2.1` in these units.
    pub fn paper_layered_widths(&self) -> Vec<f64> {
        (1..=21).map(|k| self.side * 0.05 * k as f64).collect()
    }

    /// The connect planner's step: the diagonal over `max(4, 2·N^(1/n))` — about the
    /// spacing of N obstacles spread over the workspace, so that an edge meets a few
    /// obstacles at most however many there are.
    pub fn connect_step(&self) -> f64 {
        let per_axis = (self.obstacles.max(1) as f64).powf(1.0 / self.dim.max(1) as f64);
        self.diagonal / (2.0 * per_axis).max(4.0)
    }
}
