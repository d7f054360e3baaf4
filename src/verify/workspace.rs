//! The workspace box along a piece, checked exactly and non-strictly (start and goal
//! may lie on the box, docs/design.md §5.1): each coordinate `x_d(τ)` must satisfy
//! `lo_d ≤ x_d(τ) ≤ hi_d` on [0, 1]. Bernstein coefficients all within the bounds
//! prove it (convex hull property); for straight pieces they are the end values, so
//! the check is exact. Otherwise a violation is searched on a grid.

use super::{Status, WitnessReport};
use crate::certify::{bernstein, coordinates_exact, PieceRef};
use crate::poly::{rational_to_f64, UPoly};
use num_rational::BigRational;
use serde::{Deserialize, Serialize};

/// Grid points searched for a violation when the Bernstein hull is not conclusive.
pub const WORKSPACE_WITNESS_GRID: usize = 64;

/// The workspace verdict of one piece.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorkspaceStatus {
    /// Safe (inside), unsafe (leaves the box, with witness) or undecided.
    pub status: Status,
    /// Where it leaves the box.
    pub witness: Option<WitnessReport>,
}

/// Checks the box along a piece.
pub fn check_workspace(lower: &[f64], upper: &[f64], piece: PieceRef<'_>) -> WorkspaceStatus {
    let coords = coordinates_exact(piece);
    let mut status = Status::Safe;
    for (d, x) in coords.iter().enumerate() {
        let (Some(lo), Some(hi)) = (BigRational::from_float(lower[d]), BigRational::from_float(upper[d])) else {
            return WorkspaceStatus { status: Status::Undecided, witness: None };
        };
        for g in [x.sub(&UPoly::constant(lo)), UPoly::constant(hi).sub(x)] {
            let b = bernstein::bernstein_coefficients(&g);
            if b.iter().all(|c| !num_traits::Signed::is_negative(c)) {
                continue;
            }
            let grid = WORKSPACE_WITNESS_GRID;
            let found = (0..=grid).find_map(|k| {
                let tau = BigRational::new(k.into(), grid.into());
                let v = g.eval(&tau);
                num_traits::Signed::is_negative(&v).then(|| (rational_to_f64(&tau), rational_to_f64(&v)))
            });
            match found {
                Some((tau, value)) => {
                    let t = piece.t0 + (piece.t1 - piece.t0) * tau;
                    return WorkspaceStatus { status: Status::Unsafe, witness: Some(WitnessReport { t, value }) };
                }
                None => status = Status::Undecided,
            }
        }
    }
    WorkspaceStatus { status, witness: None }
}
