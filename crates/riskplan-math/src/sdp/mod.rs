//! A small conic modelling layer over Clarabel (docs/design.md §4) — the only
//! place in the crate that talks to the solver.
//!
//! Clarabel solves `min qᵀx  s.t.  A x + s = b,  s ∈ K` (we never use the quadratic
//! term `P`), where `K` is a product of cones and the rows of `A` follow the cone
//! order. A [`Model`] collects
//!
//! * scalar variables ([`Model::add_var`]);
//! * **Gram blocks** `Q ⪰ 0` ([`Model::add_gram`], pattern 1, docs/design.md §4.2): one variable per
//!   upper-triangle entry holding the *raw* value `Q_ij` (`i ≤ j`), in Clarabel's svec
//!   order (column-major upper triangle, position `j(j+1)/2 + i`), plus `N(N+1)/2`
//!   PSD rows with `A = −1` (diagonal) or `A = −√2` (off-diagonal) and `b = 0`, so the
//!   slack is `s = svec(Q)`. Sides 1 and 2 use exactly equivalent cheaper cones by
//!   default ([`PsdForm`]: a nonnegative row, a 3-dimensional second-order cone).
//!   When `Q` enters a linear expression as a full symmetric sum
//!   `Σ_ij c_ij Q_ij`, the raw variable `Q_ij` (`i < j`) must get `c_ij + c_ji`
//!   ([`GramBlock::sym_factor`] gives the factor 2 for the common case `c_ij = c_ji`);
//! * **affine PSD constraints** `M0 + Σ_k x_k M_k ⪰ 0` ([`Model::add_psd_affine`],
//!   pattern 2): row `(i, j)` gets `A = −c_ij (M_k)_ij`, `b = c_ij (M0)_ij` with
//!   `c_ij = 1` on the diagonal and `√2` off it;
//! * equality rows, `≤`/`≥`/`≥ 0` rows, second-order cones, and a linear objective.
//!
//! [`Model::solve`] assembles the CSC matrix directly from row-ordered triplets (a
//! stable counting sort by column, no dense intermediate) and returns an
//! [`SdpSolution`]: status, primal `x`, duals `z`, slacks `s`, iterations and time.
//! [`Model::prepare`] keeps the set-up solver for re-solves after changing `b` or `q`.
//!
//! **A solver status is never a verdict.** Callers that need a proof (e.g.
//! `riskplan_certify::positivity::sos`) must re-check the returned point rigorously.
//!
//! Dual sign convention (Clarabel's KKT conditions): `Aᵀz + q = 0` and `z ∈ K*`, with
//! one dual per row in the order the rows were added. For an equality `Σ a x = rhs`
//! the row of `A` is `a` and `b = rhs`.

mod block;
mod model;
mod pack;
mod prepared;
mod settings;
#[cfg(test)]
mod tests;

pub use block::{GramBlock, PsdBlock, PsdForm};
pub use model::{AffineExpr, Model, Rows, Var};
pub use pack::{pack_svec, pack_upper, svec_index, svec_len, svec_side, unpack_svec, unpack_upper, SQRT2};
pub use prepared::Prepared;
pub use settings::{SdpSettings, SdpSolution, SdpStatus, DEFAULT_MAX_ITER, DEFAULT_TOL};

/// Errors of the modelling layer. No input makes this module panic.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SdpError {
    /// A coefficient, constant or setting was NaN or infinite.
    #[error("non-finite number in {0}")]
    NonFinite(&'static str),
    /// A variable handle does not belong to this model.
    #[error("variable {var} out of range (model has {n} variables)")]
    VarOutOfRange {
        /// The offending index.
        var: usize,
        /// Number of variables in the model.
        n: usize,
    },
    /// A cone was given an impossible size.
    #[error("bad cone size: {0}")]
    BadConeSize(String),
    /// A setting is out of its valid range.
    #[error("bad setting: {0}")]
    BadSettings(&'static str),
    /// Clarabel refused the problem data or settings.
    #[error("solver setup failed: {0}")]
    Setup(String),
    /// Clarabel panicked (caught; reported instead of unwinding through the caller).
    #[error("solver panicked: {0}")]
    Panicked(String),
}

/// Runs `f`, turning a panic inside Clarabel into [`SdpError::Panicked`].
fn guarded<T>(f: impl FnOnce() -> Result<T, SdpError>) -> Result<T, SdpError> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(SdpError::Panicked(msg))
        }
    }
}
