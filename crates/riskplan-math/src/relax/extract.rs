//! Reading the atoms out of a flat moment matrix (Henrion–Lasserre 2005): how the
//! standard SOS planner turns the relaxation's solution into candidate trajectories
//! (docs/design.md §8). Like everything in this layer it proves nothing: the planner
//! certifies each atom's trajectory.

use super::MomentVars;
use nalgebra::{DMatrix, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

/// Eigenvalues of the moment matrix below this fraction of the largest count as zero
/// when its numerical rank is taken (the interior-point solution at tolerance
/// `solver_tol` leaves the null directions at about `√tol` relative; 1e-6 is the
/// threshold of Henrion–Lasserre's GloptiPoly).
pub const RANK_REL: f64 = 1e-6;

/// Why a moment matrix gave no atoms.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ExtractionError {
    /// A moment is not finite.
    #[error("the moment matrix is not finite")]
    NonFinite,
    /// Every moment is zero.
    #[error("the moment matrix is zero")]
    Zero,
    /// `rank M_r ≠ rank M_(r−v)`: the relaxation is not exact at this order.
    #[error("not flat: rank M_{order} = {rank}, rank M_{lower_order} = {lower_rank}")]
    NotFlat {
        /// `r`.
        order: u32,
        /// `rank M_r`.
        rank: usize,
        /// `r − v`.
        lower_order: u32,
        /// `rank M_(r−v)`.
        lower_rank: usize,
    },
    /// The column echelon form found fewer basis monomials than the rank.
    #[error("echelon form found {found} of {rank} basis monomials")]
    Echelon {
        /// Pivots found.
        found: usize,
        /// The rank.
        rank: usize,
    },
    /// The monomial table lacks a monomial the procedure needs (an order too low).
    #[error("{0}")]
    Monomials(&'static str),
    /// The Schur decomposition did not converge.
    #[error("no Schur form")]
    NoSchurForm,
    /// The multiplication matrices have complex eigenvalues (no real atoms).
    #[error("complex eigenvalues in the multiplication matrices")]
    Complex,
}

/// The atoms of a flat moment matrix (Henrion–Lasserre 2005), or why there are none.
///
/// 1. `M_r = V Vᵀ` from the eigenvectors of the `ρ` eigenvalues above
///    [`RANK_REL`]·λ_max; flatness `rank M_r = rank M_(r−v)` is checked first;
/// 2. `V` is reduced to column echelon form `U`: its pivot rows are the identity and
///    their monomials `w` a basis, `v_r(z) = U w(z)` at every atom;
/// 3. for each variable `z_ℓ`, the multiplication matrix `N_ℓ` takes as row `j` the row of
///    `U` of the monomial `z_ℓ·w_j`;
/// 4. a random convex combination `Σ λ_ℓ N_ℓ = Q T Qᵀ` (real Schur form);
/// 5. atom `j` has `z_ℓ = q_jᵀ N_ℓ q_j`.
pub fn extract_atoms(
    moments: &MomentVars,
    x: &[f64],
    order: u32,
    v: u32,
    seed: u64,
) -> Result<Vec<Vec<f64>>, ExtractionError> {
    let mono = moments.monomials();
    let nz = mono.nvars();
    let side = mono.count_up_to(order);
    let m = DMatrix::from_fn(side, side, |i, j| mono.product(i, j).map_or(f64::NAN, |k| moments.value(x, k)));
    if m.iter().any(|v| !v.is_finite()) {
        return Err(ExtractionError::NonFinite);
    }
    let rank_of = |a: &DMatrix<f64>| -> (usize, SymmetricEigen<f64, nalgebra::Dyn>) {
        let e = SymmetricEigen::new(a.clone());
        let max = e.eigenvalues.iter().fold(0.0, |m: f64, v| m.max(*v));
        (e.eigenvalues.iter().filter(|&&l| l > RANK_REL * max).count(), e)
    };
    let (rho, eig) = rank_of(&m);
    let low = mono.count_up_to(order.saturating_sub(v));
    let (rho_low, _) = rank_of(&m.view((0, 0), (low, low)).into_owned());
    if rho == 0 {
        return Err(ExtractionError::Zero);
    }
    if rho != rho_low {
        return Err(ExtractionError::NotFlat {
            order,
            rank: rho,
            lower_order: order.saturating_sub(v),
            lower_rank: rho_low,
        });
    }
    // V (side × ρ), columns √λ·eigenvector, largest first
    let mut idx: Vec<usize> = (0..side).collect();
    idx.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let mut w = DMatrix::zeros(rho, side); // Vᵀ, reduced to row echelon form below
    for (c, &k) in idx.iter().take(rho).enumerate() {
        let s = eig.eigenvalues[k].sqrt();
        for i in 0..side {
            w[(c, i)] = s * eig.eigenvectors[(i, k)];
        }
    }
    // reduced row echelon form of Vᵀ with partial pivoting: pivot columns = basis monomials
    let scale = w.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
    let mut pivots = Vec::with_capacity(rho);
    let mut row = 0;
    for col in 0..side {
        if row == rho {
            break;
        }
        let (best, val) =
            (row..rho).map(|r| (r, w[(r, col)].abs())).fold((row, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        if val <= RANK_REL.sqrt() * scale {
            continue;
        }
        w.swap_rows(row, best);
        let p = w[(row, col)];
        for j in 0..side {
            w[(row, j)] /= p;
        }
        for r in 0..rho {
            if r != row {
                let f = w[(r, col)];
                if f != 0.0 {
                    for j in 0..side {
                        w[(r, j)] -= f * w[(row, j)];
                    }
                }
            }
        }
        pivots.push(col);
        row += 1;
    }
    if pivots.len() < rho {
        return Err(ExtractionError::Echelon { found: pivots.len(), rank: rho });
    }
    // N_ℓ[j, :] = U[index(z_ℓ · w_j), :] = W[:, index(z_ℓ · w_j)]ᵀ
    let mut ns = Vec::with_capacity(nz);
    for l in 0..nz {
        let zl = mono.power(l, 1).ok_or(ExtractionError::Monomials("no first-degree monomial"))?;
        let mut nl = DMatrix::zeros(rho, rho);
        for (j, &pj) in pivots.iter().enumerate() {
            let k = mono
                .product(zl, pj)
                .filter(|&k| k < side)
                .ok_or(ExtractionError::Monomials("a shifted basis monomial is beyond the order"))?;
            for c in 0..rho {
                nl[(j, c)] = w[(c, k)];
            }
        }
        ns.push(nl);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let weights: Vec<f64> = (0..nz).map(|_| rng.random_range(0.1..1.0)).collect();
    let total: f64 = weights.iter().sum();
    let mut comb = DMatrix::zeros(rho, rho);
    for (nl, wl) in ns.iter().zip(&weights) {
        comb += nl * (*wl / total);
    }
    let schur = nalgebra::linalg::Schur::try_new(comb, 1e-12, 10_000).ok_or(ExtractionError::NoSchurForm)?;
    let (q, t) = schur.unpack();
    let tnorm = t.iter().fold(0.0, |m: f64, v| m.max(v.abs())).max(1.0);
    for j in 1..rho {
        if t[(j, j - 1)].abs() > 1e-8 * tnorm {
            return Err(ExtractionError::Complex);
        }
    }
    Ok((0..rho)
        .map(|j| {
            let qj = q.column(j);
            ns.iter().map(|nl| (qj.transpose() * nl * qj)[(0, 0)]).collect()
        })
        .collect())
}
