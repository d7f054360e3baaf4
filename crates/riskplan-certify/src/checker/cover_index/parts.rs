//! A piece cut into dyadic parts in time, and the boxes that hold them.

use super::*;

/// One part of a piece: its proven spatial bounding box and its time interval.
pub type PartBox = (Vec<(f64, f64)>, (f64, f64));

/// Most parts a piece is split into for the cover tests ([`SceneIndex::sub_pieces_for`]).
pub const MAX_SUB_PIECES: usize = 32;

/// The piece split in time into `k` parts (the same polynomials on sub-intervals):
/// consecutive parts share their floating-point end times, the first starts at `t0` and
/// the last ends at `t1`, so the parts cover the piece whatever the rounding of the times
/// between. `None` unless `t0 ≤ t1`.
pub fn piece_parts<'a>(piece: PieceRef<'a>, k: usize) -> Option<Vec<PieceRef<'a>>> {
    let k = k.max(1);
    let (t0, t1) = (piece.t0, piece.t1);
    if t0.is_nan() || t1.is_nan() || t0 > t1 {
        return None;
    }
    let mut out = Vec::with_capacity(k);
    let mut a = t0;
    for j in 1..=k {
        let b = if j == k { t1 } else { (t0 + (t1 - t0) * (j as f64 / k as f64)).clamp(a, t1) };
        out.push(PieceRef { t0: a, t1: b, coeffs: piece.coeffs });
        a = b;
    }
    Some(out)
}

/// The piece's [`piece_parts`] with each part's proven bounding box ([`piece_bbox`]) and
/// time interval. `None` when a part's box is not available.
pub fn piece_sub_boxes(piece: PieceRef<'_>, k: usize) -> Option<Vec<PartBox>> {
    piece_parts(piece, k)?.into_iter().map(|p| Some((piece_bbox(p)?, (p.t0, p.t1)))).collect()
}

/// A proven bounding box of a piece's positions over its time interval, from the
/// Bernstein coefficients of each coordinate (convex hull property), or `None` when
/// the degree exceeds the compiled capacity or a bound is not finite.
pub fn piece_bbox(piece: PieceRef<'_>) -> Option<Vec<(f64, f64)>> {
    let t0 = Interval::point(piece.t0);
    let h = Interval::point(piece.t1) - t0;
    let lin = FPoly::<{ riskplan_scene::MAX_PIECE_DEGREE + 1 }>::linear(t0, h);
    let mut out = Vec::with_capacity(piece.coeffs.len());
    for row in piece.coeffs {
        let mut acc = FPoly::zero();
        for &c in row.iter().rev() {
            acc = acc.mul(&lin)?;
            acc.add_assign(&FPoly::constant(Interval::point(c)));
        }
        let b = crate::positivity::bernstein::bernstein_enclosure(acc.coeffs())?;
        if !(b.lo.is_finite() && b.hi.is_finite()) {
            return None;
        }
        out.push((b.lo, b.hi));
    }
    Some(out)
}
