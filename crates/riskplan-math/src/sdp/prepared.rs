//! A set-up solver re-solved after changing `b` or `q` (the iterated SDPs of §8.4).

use super::*;
use clarabel::solver::{DefaultSolver, IPSolver};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A set-up Clarabel solver for one [`Model`] (see [`Model::prepare`]). Every
/// [`Prepared::solve`] starts from Clarabel's default initial point, but Clarabel
/// keeps some internal state between solves, so a re-solve agrees with a fresh
/// solve of the updated model only to solver tolerance, not bit for bit. After an
/// `Err` the solver may be unusable; drop it.
pub struct Prepared {
    pub(super) solver: DefaultSolver<f64>,
    pub(super) n: usize,
    pub(super) m: usize,
}

impl fmt::Debug for Prepared {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Prepared").field("n", &self.n).field("m", &self.m).finish()
    }
}

impl Prepared {
    /// Number of variables.
    pub fn num_vars(&self) -> usize {
        self.n
    }

    /// Number of rows.
    pub fn num_rows(&self) -> usize {
        self.m
    }

    /// Replaces the right-hand side `b` (one entry per row, in the model's row order:
    /// an equality's `rhs`, an affine expression's constant, …, exactly as the model
    /// stored it; see [`Model::rhs`]).
    pub fn update_b(&mut self, b: &[f64]) -> Result<(), SdpError> {
        if b.len() != self.m {
            return Err(SdpError::BadConeSize(format!("b has {} entries, model has {} rows", b.len(), self.m)));
        }
        if b.iter().any(|v| !v.is_finite()) {
            return Err(SdpError::NonFinite("right-hand side"));
        }
        let solver = &mut self.solver;
        guarded(|| solver.update_b(&b.to_vec()).map_err(|e| SdpError::Setup(e.to_string())))
    }

    /// Replaces the objective vector `q` (one entry per variable).
    pub fn update_q(&mut self, q: &[f64]) -> Result<(), SdpError> {
        if q.len() != self.n {
            return Err(SdpError::BadConeSize(format!("q has {} entries, model has {} variables", q.len(), self.n)));
        }
        if q.iter().any(|v| !v.is_finite()) {
            return Err(SdpError::NonFinite("objective"));
        }
        let solver = &mut self.solver;
        guarded(|| solver.update_q(&q.to_vec()).map_err(|e| SdpError::Setup(e.to_string())))
    }

    /// Stops every later solve between two interior-point iterations once `stop` is
    /// set (Clarabel's termination callback): the solve then ends with
    /// [`SdpStatus::CallbackTerminated`]. How a plan's cancel flag reaches the solver.
    pub fn stop_when(&mut self, stop: Arc<AtomicBool>) {
        self.solver.set_termination_callback(move |_| stop.load(Ordering::Relaxed));
    }

    /// Solves (from Clarabel's default start).
    pub fn solve(&mut self) -> Result<SdpSolution, SdpError> {
        let solver = &mut self.solver;
        guarded(|| {
            solver.solve();
            let sol = &solver.solution;
            Ok(SdpSolution {
                status: sol.status.into(),
                x: sol.x.clone(),
                z: sol.z.clone(),
                s: sol.s.clone(),
                obj_primal: sol.obj_val,
                obj_dual: sol.obj_val_dual,
                iterations: sol.iterations,
                solve_time: sol.solve_time,
            })
        })
    }
}
