//! Solver settings, statuses and solutions (§4.4, §4.5).

use super::*;
use clarabel::solver::{DefaultSettings, SolverStatus};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Default gap and feasibility tolerance (Clarabel's own default). Tighter makes
/// the returned point more accurate (and the solve slower); it proves nothing either
/// way — callers re-check.
pub const DEFAULT_TOL: f64 = 1e-8;

/// Default iteration limit (Clarabel's own default). Hitting it gives
/// [`SdpStatus::MaxIterations`], never a usable point.
pub const DEFAULT_MAX_ITER: u32 = 200;

/// Solver settings. Defaults: [`DEFAULT_TOL`], [`DEFAULT_MAX_ITER`], no
/// time limit, presolve and chordal decomposition **off** (they only cost time on the
/// small dense problems of this crate and forbid data updates), equilibration on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SdpSettings {
    /// Absolute duality-gap tolerance.
    pub tol_gap_abs: f64,
    /// Relative duality-gap tolerance.
    pub tol_gap_rel: f64,
    /// Feasibility tolerance.
    pub tol_feas: f64,
    /// Iteration limit.
    pub max_iter: u32,
    /// Time limit in seconds (`f64::INFINITY`: none).
    pub time_limit: f64,
    /// Clarabel's presolve.
    pub presolve: bool,
    /// Clarabel's chordal decomposition of PSD cones.
    pub chordal_decomposition: bool,
    /// Clarabel's Ruiz equilibration.
    pub equilibrate: bool,
}

impl Default for SdpSettings {
    fn default() -> Self {
        SdpSettings {
            tol_gap_abs: DEFAULT_TOL,
            tol_gap_rel: DEFAULT_TOL,
            tol_feas: DEFAULT_TOL,
            max_iter: DEFAULT_MAX_ITER,
            time_limit: f64::INFINITY,
            presolve: false,
            chordal_decomposition: false,
            equilibrate: true,
        }
    }
}

impl SdpSettings {
    pub(super) fn to_clarabel(&self) -> Result<DefaultSettings<f64>, SdpError> {
        for (v, name) in [
            (self.tol_gap_abs, "tol_gap_abs must be finite and > 0"),
            (self.tol_gap_rel, "tol_gap_rel must be finite and > 0"),
            (self.tol_feas, "tol_feas must be finite and > 0"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(SdpError::BadSettings(name));
            }
        }
        if self.time_limit.is_nan() || self.time_limit <= 0.0 {
            return Err(SdpError::BadSettings("time_limit must be > 0"));
        }
        Ok(DefaultSettings {
            tol_gap_abs: self.tol_gap_abs,
            tol_gap_rel: self.tol_gap_rel,
            tol_feas: self.tol_feas,
            max_iter: self.max_iter,
            time_limit: self.time_limit,
            verbose: false,
            presolve_enable: self.presolve,
            chordal_decomposition_enable: self.chordal_decomposition,
            equilibrate_enable: self.equilibrate,
            ..DefaultSettings::default()
        })
    }
}

/// Solver status, mirroring Clarabel's `SolverStatus`. Only [`SdpStatus::Solved`] and
/// [`SdpStatus::AlmostSolved`] come with a usable point; even then the point is just a
/// floating-point approximation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SdpStatus {
    /// The solver did not run.
    Unsolved,
    /// Converged to the requested tolerances.
    Solved,
    /// Converged to reduced tolerances.
    AlmostSolved,
    /// Certificate of primal infeasibility.
    PrimalInfeasible,
    /// Certificate of dual infeasibility (primal unbounded).
    DualInfeasible,
    /// Primal infeasibility to reduced tolerances.
    AlmostPrimalInfeasible,
    /// Dual infeasibility to reduced tolerances.
    AlmostDualInfeasible,
    /// Iteration limit.
    MaxIterations,
    /// Time limit.
    MaxTime,
    /// Numerical failure.
    NumericalError,
    /// No progress.
    InsufficientProgress,
    /// A callback stopped the solver.
    CallbackTerminated,
}

impl SdpStatus {
    /// Whether the status comes with an (approximate) optimal point.
    pub fn has_solution(self) -> bool {
        matches!(self, SdpStatus::Solved | SdpStatus::AlmostSolved)
    }
}

impl From<SolverStatus> for SdpStatus {
    fn from(s: SolverStatus) -> Self {
        match s {
            SolverStatus::Unsolved => SdpStatus::Unsolved,
            SolverStatus::Solved => SdpStatus::Solved,
            SolverStatus::AlmostSolved => SdpStatus::AlmostSolved,
            SolverStatus::PrimalInfeasible => SdpStatus::PrimalInfeasible,
            SolverStatus::DualInfeasible => SdpStatus::DualInfeasible,
            SolverStatus::AlmostPrimalInfeasible => SdpStatus::AlmostPrimalInfeasible,
            SolverStatus::AlmostDualInfeasible => SdpStatus::AlmostDualInfeasible,
            SolverStatus::MaxIterations => SdpStatus::MaxIterations,
            SolverStatus::MaxTime => SdpStatus::MaxTime,
            SolverStatus::NumericalError => SdpStatus::NumericalError,
            SolverStatus::InsufficientProgress => SdpStatus::InsufficientProgress,
            SolverStatus::CallbackTerminated => SdpStatus::CallbackTerminated,
        }
    }
}

impl fmt::Display for SdpStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// What [`Model::solve`] returns.
#[derive(Clone, Debug, PartialEq)]
pub struct SdpSolution {
    /// Solver status.
    pub status: SdpStatus,
    /// Primal variables, indexed by [`Var::index`].
    pub x: Vec<f64>,
    /// Duals, one per row in the order rows were added (`Aᵀz + q = 0`, `z ∈ K*`).
    pub z: Vec<f64>,
    /// Slacks `s = b − Ax`, one per row.
    pub s: Vec<f64>,
    /// Primal objective `qᵀx`.
    pub obj_primal: f64,
    /// Dual objective.
    pub obj_dual: f64,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Time in seconds as reported by Clarabel (its own timers).
    pub solve_time: f64,
}

impl SdpSolution {
    /// Value of a variable.
    pub fn value(&self, v: Var) -> f64 {
        self.x.get(v.0).copied().unwrap_or(f64::NAN)
    }
    /// Duals of a row range (empty if out of range).
    pub fn duals(&self, rows: Rows) -> &[f64] {
        self.z.get(rows.range()).unwrap_or(&[])
    }
}
