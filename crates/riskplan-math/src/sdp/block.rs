//! PSD constraints of a model: Gram blocks and affine PSD constraints, and the cone
//! forms they are handed to Clarabel in (§4.2, §4.3).

use super::*;
use serde::{Deserialize, Serialize};

/// How a PSD constraint of side `N` is handed to Clarabel. All forms are exactly
/// equivalent to `M ⪰ 0`; the small ones avoid Clarabel's dense PSD-cone machinery
/// (eigen-decompositions and BLAS calls every iteration), which dominates the cost of
/// the tiny SDPs of eq. (15).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum PsdForm {
    /// `PSDTriangleConeT(N)`, rows `svec(M)` (√2 off the diagonal): any `N`.
    Triangle,
    /// `N = 2`: `(M00 + M11, M00 − M11, 2·M01) ∈ SOC(3)`, which holds iff
    /// `M00, M11 ≥ 0` and `M00·M11 ≥ M01²`, i.e. iff `M ⪰ 0`.
    Soc,
    /// `N = 1`: one nonnegative row `M00 ≥ 0`.
    Nonneg,
}

/// The cone rows of one PSD constraint `M ⪰ 0` (from [`Model::add_gram`] or
/// [`Model::add_psd_affine`]), with its [`PsdForm`]. In every form the duals `z` of
/// the rows and the dual matrix `Z` returned by [`PsdBlock::dual_matrix`] satisfy
/// `zᵀs = ⟨Z, M⟩` and `Z ⪰ 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PsdBlock {
    pub(super) rows: Rows,
    pub(super) side: usize,
    pub(super) form: PsdForm,
}

impl PsdBlock {
    /// The cone rows.
    pub fn rows(&self) -> Rows {
        self.rows
    }
    /// Matrix side `N`.
    pub fn side(&self) -> usize {
        self.side
    }
    /// How the constraint was encoded.
    pub fn form(&self) -> PsdForm {
        self.form
    }

    /// Decodes a matrix from per-row values `v` (duals `z` or slacks `s`). For the
    /// triangle the rows are a scaled svec; for the SOC form `(a+c, a−c, 2b)` the
    /// slack decodes to `[[a, b], [b, c]]` and the dual `(z0, z1, z2)` to
    /// `[[z0+z1, z2], [z2, z0−z1]]` (so that `zᵀs = ⟨Z, M⟩`).
    fn decode(&self, v: &[f64], dual: bool) -> Option<Vec<Vec<f64>>> {
        let v = v.get(self.rows.range())?;
        match self.form {
            PsdForm::Triangle => unpack_svec(v),
            PsdForm::Nonneg => Some(vec![vec![v[0]]]),
            PsdForm::Soc => {
                let (a, c, b) = if dual {
                    (v[0] + v[1], v[0] - v[1], v[2])
                } else {
                    (0.5 * (v[0] + v[1]), 0.5 * (v[0] - v[1]), 0.5 * v[2])
                };
                Some(vec![vec![a, b], vec![b, c]])
            }
        }
    }

    /// The dual matrix `Z ⪰ 0` from the dual vector `z` of a solution.
    pub fn dual_matrix(&self, z: &[f64]) -> Option<Vec<Vec<f64>>> {
        self.decode(z, true)
    }

    /// The slack matrix `M(x)` from the slack vector `s` of a solution.
    pub fn slack_matrix(&self, s: &[f64]) -> Option<Vec<Vec<f64>>> {
        self.decode(s, false)
    }
}

/// A PSD Gram block `Q ⪰ 0` of a [`Model`] (pattern 1, docs/design.md §4.2).
///
/// Its `N(N+1)/2` variables hold the raw upper-triangle entries `Q_ij`, `i ≤ j`, in
/// svec order (`svec_index(i, j)`); its cone rows are described by [`GramBlock::psd`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GramBlock {
    pub(super) first: usize,
    pub(super) side: usize,
    pub(super) psd: PsdBlock,
}

impl GramBlock {
    /// Matrix side `N`.
    pub fn side(&self) -> usize {
        self.side
    }

    /// The variable holding the raw entry `Q_ij` (`(i, j)` in either order).
    ///
    /// # Panics
    /// If `i` or `j` is not below [`GramBlock::side`] (a caller bug, not input).
    pub fn var(&self, i: usize, j: usize) -> Var {
        assert!(i < self.side && j < self.side, "Gram index out of range");
        Var(self.first + svec_index(i, j))
    }

    /// Coefficient multiplier of raw entry `(i, j)` in a full symmetric sum
    /// `Σ_ij c Q_ij` with `c_ij = c_ji`: 1 on the diagonal, 2 off it.
    pub fn sym_factor(i: usize, j: usize) -> f64 {
        if i == j {
            1.0
        } else {
            2.0
        }
    }

    /// The cone rows of `Q ⪰ 0`.
    pub fn psd(&self) -> PsdBlock {
        self.psd
    }

    /// The raw upper-triangle values from a primal vector, in svec order.
    pub fn raw<'a>(&self, x: &'a [f64]) -> Option<&'a [f64]> {
        x.get(self.first..self.first + svec_len(self.side))
    }

    /// The full symmetric matrix `Q` from a primal vector.
    pub fn matrix(&self, x: &[f64]) -> Option<Vec<Vec<f64>>> {
        unpack_upper(self.raw(x)?)
    }

    /// The dual matrix `Z ⪰ 0` of the block's cone.
    pub fn dual_matrix(&self, z: &[f64]) -> Option<Vec<Vec<f64>>> {
        self.psd.dual_matrix(z)
    }
}
