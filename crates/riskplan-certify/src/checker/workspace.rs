//! The workspace box along a piece, checked exactly and non-strictly (start and goal
//! may lie on the box, docs/design.md §5.1): each coordinate `x_d(τ)` must satisfy
//! `lo_d ≤ x_d(τ) ≤ hi_d` on [0, 1]. Bernstein coefficients all within the bounds
//! prove it (convex hull property); for straight pieces they are the end values, so
//! the check is exact. Otherwise a violation is searched on a grid.

use super::decide::{Status, WitnessReport};
use crate::compiled::straight_value_sign;
use crate::{coordinates_exact, positivity::bernstein, PieceRef};
use num_rational::BigRational;
use riskplan_math::poly::{rational_to_f64, Interval, Ring, UPoly};
use serde::{Deserialize, Serialize};

/// Grid points searched for a violation when the Bernstein hull is not conclusive.
pub const WORKSPACE_WITNESS_GRID: usize = 64;

/// The workspace verdict of one piece.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct WorkspaceStatus {
    /// Safe (inside), unsafe (leaves the box, with witness) or undecided.
    pub status: Status,
    /// Where it leaves the box.
    pub witness: Option<WitnessReport>,
}

/// Whether every coordinate's Bernstein hull, computed in outward-rounded interval
/// arithmetic, lies within the box: a sufficient condition for "inside" (the exact
/// check decides everything else). Pieces that end on the boundary overshoot by
/// rounding and go on to the exact check.
fn inside_by_intervals(lower: &[f64], upper: &[f64], piece: PieceRef<'_>) -> bool {
    interval_hull(piece)
        .is_some_and(|hull| hull.iter().zip(lower.iter().zip(upper)).all(|(b, (&lo, &hi))| lo <= b.lo && b.hi <= hi))
}

/// A time on the witness grid at which some coordinate's outward-rounded enclosure lies
/// entirely outside its bounds: a proof that the piece leaves the box, found in
/// floating point (the planners' edges leave through the walls by whole steps; the
/// exact search below costs a hundred times more). `None` proves nothing.
fn outside_by_intervals(lower: &[f64], upper: &[f64], piece: PieceRef<'_>) -> Option<WitnessReport> {
    let grid = WORKSPACE_WITNESS_GRID;
    (0..=grid).find_map(|k| {
        let t = piece.t0 + (piece.t1 - piece.t0) * (k as f64 / grid as f64);
        if !(piece.t0..=piece.t1).contains(&t) {
            return None;
        }
        let ti = Interval::point(t);
        piece.coeffs.iter().zip(lower.iter().zip(upper)).find_map(|(row, (&lo, &hi))| {
            let x = row.iter().rev().fold(Interval::point(0.0), |acc, &c| acc * ti + Interval::point(c));
            if x.hi < lo {
                Some(WitnessReport { t, value: x.hi - lo })
            } else if x.lo > hi {
                Some(WitnessReport { t, value: hi - x.lo })
            } else {
                None
            }
        })
    })
}

/// Whether a coordinate of degree ≤ 1, `c0 + c1·t` on `[t0, t1]`, stays in `[l, u]`,
/// exactly (its extremes are its end values, evaluated in rationals): the float
/// enclosure of an edge that ends on the workspace boundary crosses it by rounding.
pub(crate) fn straight_coordinate_inside(c: &[f64], t0: f64, t1: f64, l: f64, u: f64) -> bool {
    if c.len() > 2 {
        return false;
    }
    // exactly in floating point by error-free transformations (rationals otherwise)
    let (c0, c1) = (c.first().copied().unwrap_or(0.0), c.get(1).copied().unwrap_or(0.0));
    let signs: Option<Vec<(std::cmp::Ordering, std::cmp::Ordering)>> = [t0, t1]
        .iter()
        .map(|&t| Some((straight_value_sign(c0, c1, t, l)?, straight_value_sign(c0, c1, t, u)?)))
        .collect();
    if let Some(signs) = signs {
        use std::cmp::Ordering::{Greater, Less};
        return signs.iter().all(|&(lo, hi)| lo != Less && hi != Greater);
    }
    let q = |v: f64| BigRational::from_float(v);
    let (Some(c0), Some(c1), Some(a), Some(b), Some(l), Some(u)) =
        (q(c.first().copied().unwrap_or(0.0)), q(c.get(1).copied().unwrap_or(0.0)), q(t0), q(t1), q(l), q(u))
    else {
        return false;
    };
    [a, b].iter().all(|t| {
        let x = &c0 + &c1 * t;
        l <= x && x <= u
    })
}

/// A sufficient test that a piece stays in the box `[lower, upper]`, in floating point:
/// its proven bounding box `bbox` ([`super::piece_bbox`]) lies inside, coordinate by
/// coordinate, or the coordinate is straight and its end values are inside exactly
/// (`straight_coordinate_inside`: an edge that ends on a wall is inside). `false`
/// proves nothing: [`check_workspace`] decides then.
pub fn inside_by_box(lower: &[f64], upper: &[f64], piece: PieceRef<'_>, bbox: Option<&[(f64, f64)]>) -> bool {
    bbox.is_some_and(|b| {
        b.len() == lower.len()
            && b.iter().zip(lower.iter().zip(upper)).enumerate().all(|(d, (&(lo, hi), (&l, &u)))| {
                (l <= lo && hi <= u)
                    || piece.coeffs.get(d).is_some_and(|c| straight_coordinate_inside(c, piece.t0, piece.t1, l, u))
            })
    })
}

/// An enclosure of each coordinate of a piece over its time interval: the
/// outward-rounded Bernstein hull of the coordinate composed with `t0 + hτ` in interval
/// arithmetic (general polynomial code, not the planners' compiled path); `None` when
/// a hull is not finite.
///
/// The composition is [`UPoly::compose_affine`]'s Horner scheme — the same interval
/// operations in the same order, so the same enclosure bit for bit — carried out in
/// fixed buffers (`coordinate_hull`): the final check forms a hull for every piece,
/// for each of its parts and for its grid lookup, and the general code allocates at every
/// step.
pub fn interval_hull(piece: PieceRef<'_>) -> Option<Vec<Interval>> {
    let t0 = Interval::point(piece.t0);
    let h = Interval::point(piece.t1) - t0;
    piece.coeffs.iter().map(|row| coordinate_hull(row, t0, h)).collect()
}

/// One coordinate's hull for [`interval_hull`]: `Σ c_k (t0 + hτ)^k` by Horner over
/// intervals — `acc ← acc·(t0 + hτ) + c_k`, each step as [`UPoly::mul`] then
/// [`UPoly::add`] form it (zero coefficients skipped in the product, trailing zeros
/// trimmed after each step) — then its Bernstein enclosure on [0, 1]. Rows longer than
/// the buffers ([`bernstein::MAX_DEGREE`] + 1 coefficients after trimming) go through the
/// general polynomial code itself (its result is `None` unless the composition is
/// shorter, e.g. a constant when `h` is 0).
fn coordinate_hull(row: &[f64], t0: Interval, h: Interval) -> Option<Interval> {
    const N: usize = bernstein::MAX_DEGREE + 1;
    let zero = Interval::point(0.0);
    // the coefficients as `UPoly::new` keeps them (trailing zeros trimmed)
    let mut n = row.len();
    while n > 0 && Interval::point(row[n - 1]).is_zero() {
        n -= 1;
    }
    if n > N {
        let x = UPoly::new(row.iter().map(|&c| Interval::point(c)).collect()).compose_affine(&t0, &h);
        return bernstein::bernstein_enclosure(x.coeffs());
    }
    // t0 + hτ as `UPoly::linear` keeps it
    let lin = [t0, h];
    let lin_len = if !h.is_zero() {
        2
    } else if !t0.is_zero() {
        1
    } else {
        0
    };
    let trimmed = |b: &[Interval], mut len: usize| {
        while len > 0 && b[len - 1].is_zero() {
            len -= 1;
        }
        len
    };
    let (mut acc, mut len) = ([zero; N], 0usize);
    let mut product = [zero; N];
    for &c in row[..n].iter().rev() {
        // acc · (t0 + hτ): the product has at most as many coefficients as the row part
        // taken so far (lin has at most 2), so it fits
        if len == 0 || lin_len == 0 {
            len = 0;
        } else {
            let out = len + lin_len - 1;
            product[..out].fill(zero);
            for (i, a) in acc[..len].iter().enumerate() {
                if a.is_zero() {
                    continue;
                }
                for (j, b) in lin[..lin_len].iter().enumerate() {
                    product[i + j] = product[i + j] + *a * *b;
                }
            }
            len = trimmed(&product, out);
            acc[..len].copy_from_slice(&product[..len]);
        }
        // + c (a zero constant is the zero polynomial: nothing is added, as in `add`)
        let c = Interval::point(c);
        let c_len = usize::from(!c.is_zero());
        let m = len.max(c_len);
        for (i, a) in acc[..m].iter_mut().enumerate() {
            let x = if i < len { *a } else { zero };
            let y = if i == 0 && c_len == 1 { c } else { zero };
            *a = x + y;
        }
        len = trimmed(&acc, m);
    }
    bernstein::bernstein_enclosure(&acc[..len])
}

/// Checks the box along a piece.
pub fn check_workspace(lower: &[f64], upper: &[f64], piece: PieceRef<'_>) -> WorkspaceStatus {
    // the exact conversion reads a non-finite float as 0: never judge such a piece
    if !piece.is_finite() {
        return WorkspaceStatus { status: Status::Undecided, witness: None };
    }
    if piece.coeffs.len() == lower.len() && inside_by_intervals(lower, upper, piece) {
        return WorkspaceStatus { status: Status::Safe, witness: None };
    }
    if piece.coeffs.len() == lower.len() {
        if let Some(w) = outside_by_intervals(lower, upper, piece) {
            return WorkspaceStatus { status: Status::Unsafe, witness: Some(w) };
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixed-buffer [`interval_hull`] against the general composition it stands for.
    mod hull_by_upoly {
        use super::super::*;
        use proptest::prelude::*;

        /// The general composition by `UPoly::compose_affine` that `interval_hull` stands
        /// for (the reference of the fixed-buffer one).
        fn interval_hull_by_upoly(piece: PieceRef<'_>) -> Option<Vec<Interval>> {
            let t0 = Interval::point(piece.t0);
            let h = Interval::point(piece.t1) - t0;
            piece
                .coeffs
                .iter()
                .map(|row| {
                    let x = UPoly::new(row.iter().map(|&c| Interval::point(c)).collect()).compose_affine(&t0, &h);
                    bernstein::bernstein_enclosure(x.coeffs())
                })
                .collect()
        }

        /// A float of any scale: zeros of both signs, subnormals, huge and tiny normals,
        /// ordinary values, and now and then a non-finite one.
        fn any_scale() -> impl Strategy<Value = f64> {
            prop_oneof![
                3 => -10.0f64..10.0,
                1 => Just(0.0),
                1 => Just(-0.0),
                1 => (-1.0f64..1.0, -330i32..300).prop_map(|(m, e)| m * 10f64.powi(e)),
                1 => (-1.0f64..1.0).prop_map(|m| m * f64::MIN_POSITIVE),
                1 => prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::MAX)],
            ]
        }

        /// A coordinate: mostly of degree below 6, sometimes near or beyond the
        /// buffers' length (33 coefficients) with moderate finite coefficients (so that
        /// the enclosure exists) or with any, sometimes zeros only.
        fn row() -> impl Strategy<Value = Vec<f64>> {
            prop_oneof![
                8 => proptest::collection::vec(any_scale(), 0..6),
                2 => proptest::collection::vec(-2.0f64..2.0, 28..40),
                1 => proptest::collection::vec(any_scale(), 30..42),
                1 => proptest::collection::vec(Just(0.0), 1..4),
            ]
        }

        proptest! {
            /// The same enclosure bit for bit (or `None` where it is `None`), at any
            /// scale, on time intervals of any length including none, with trailing
            /// zeros of both signs (which the general code trims).
            #[test]
            fn the_fixed_buffer_hull_is_the_general_compositions(
                rows in proptest::collection::vec(row(), 1..4),
                t0 in prop_oneof![3 => -4.0f64..4.0, 1 => any_scale()],
                dt in prop_oneof![3 => 0.0f64..1.5, 1 => Just(0.0), 1 => any_scale()],
                trailing in 0usize..3,
            ) {
                let mut rows = rows;
                for r in rows.iter_mut() {
                    r.extend(std::iter::repeat_n(if trailing == 2 { -0.0 } else { 0.0 }, trailing));
                }
                // row by row (a piece's hull is `None` as soon as one row's is)
                for r in &rows {
                    let piece = PieceRef { t0, t1: t0 + dt, coeffs: std::slice::from_ref(r) };
                    let bits = |h: Option<Vec<Interval>>| h.map(|v| v.iter().map(|i| (i.lo.to_bits(), i.hi.to_bits())).collect::<Vec<_>>());
                    prop_assert_eq!(bits(interval_hull(piece)), bits(interval_hull_by_upoly(piece)));
                }
                let piece = PieceRef { t0, t1: t0 + dt, coeffs: &rows };
                prop_assert_eq!(interval_hull(piece).is_some(), interval_hull_by_upoly(piece).is_some());
            }
        }
    }

    const LO: [f64; 2] = [0.0, 0.0];
    const HI: [f64; 2] = [1.0, 1.0];

    fn check(t0: f64, t1: f64, coeffs: Vec<Vec<f64>>) -> (WorkspaceStatus, Vec<Vec<f64>>) {
        let s = check_workspace(&LO, &HI, PieceRef { t0, t1, coeffs: &coeffs });
        (s, coeffs)
    }

    fn at(coeffs: &[Vec<f64>], t: f64) -> Vec<f64> {
        coeffs.iter().map(|c| c.iter().rev().fold(0.0, |acc, &k| acc * t + k)).collect()
    }

    fn outside(x: &[f64]) -> bool {
        x.iter().zip(LO.iter().zip(&HI)).any(|(v, (lo, hi))| v < lo || v > hi)
    }

    #[test]
    fn straight_pieces_inside_on_the_boundary_and_leaving() {
        // corner to corner, on [2, 4]: start and goal on the box are allowed
        let seg = |a: [f64; 2], b: [f64; 2]| {
            let p = riskplan_scene::Piece::segment(&a, &b, 2.0, 4.0);
            check(2.0, 4.0, p.coeffs)
        };
        assert_eq!(seg([0.0, 0.0], [1.0, 1.0]).0.status, Status::Safe);
        assert_eq!(seg([0.2, 0.9], [0.8, 0.1]).0.status, Status::Safe);
        // leaves through x1 = 1 at t = 3
        let (s, c) = seg([0.5, 0.5], [1.5, 0.5]);
        assert_eq!(s.status, Status::Unsafe);
        let w = s.witness.expect("a witness");
        assert!((3.0..=4.0).contains(&w.t) && w.value < 0.0, "{w:?}");
        assert!(outside(&at(&c, w.t)), "the witness {w:?} is inside");
        // leaves through x2 = 0 right after the start
        let (s, c) = seg([0.5, 0.0], [0.6, -0.5]);
        assert_eq!(s.status, Status::Unsafe);
        assert!(outside(&at(&c, s.witness.unwrap().t)));
    }

    #[test]
    fn curved_pieces_leaving_between_inside_endpoints() {
        // x1(t) = 0.5 + 3t(1 − t): both ends at 0.5, 1.25 at t = 1/2
        let (s, c) = check(0.0, 1.0, vec![vec![0.5, 3.0, -3.0], vec![0.5]]);
        assert_eq!(s.status, Status::Unsafe);
        let w = s.witness.expect("a witness");
        assert!(outside(&at(&c, w.t)), "the witness {w:?} is inside");
        // x1(t) = 0.5 + t(1 − t) stays in [0.5, 0.75]; its Bernstein hull proves it
        assert_eq!(check(0.0, 1.0, vec![vec![0.5, 1.0, -1.0], vec![0.5]]).0.status, Status::Safe);
        // x1(t) = 2.4t(1 − t) stays in [0, 0.6], but its Bernstein hull reaches 1.2:
        // not proven inside, so never safe
        assert_eq!(check(0.0, 1.0, vec![vec![0.0, 2.4, -2.4], vec![0.5]]).0.status, Status::Undecided);
    }

    /// The exact value of coordinate row `row` at the float time `t`.
    fn exact_at(row: &[f64], t: f64) -> BigRational {
        let t = BigRational::from_float(t).unwrap();
        row.iter()
            .rev()
            .fold(BigRational::from_integer(0.into()), |acc, &c| acc * &t + BigRational::from_float(c).unwrap())
    }

    proptest::proptest! {
        /// The interval proof that a piece leaves the box (`outside_by_intervals`) gives
        /// only genuine witnesses: the coordinate, evaluated exactly at the witness's
        /// time, lies outside its bounds — at every scale, grazing pieces included.
        #[test]
        fn interval_witnesses_are_outside_exactly(
            e in -300i32..300,
            c in proptest::collection::vec(-2.0f64..2.0, 6),
            t0 in -3.0f64..3.0,
            len in 1e-3f64..4.0,
        ) {
            let s = 2f64.powi(e);
            let lower = [0.0, -s];
            let upper = [s, s];
            // coordinates of order s: some leave the box, some graze it
            let coeffs = vec![
                vec![c[0] * s, c[1] * s, c[2] * s],
                vec![c[3] * s, c[4] * s, c[5] * s],
            ];
            let piece = PieceRef { t0, t1: t0 + len, coeffs: &coeffs };
            if let Some(w) = outside_by_intervals(&lower, &upper, piece) {
                proptest::prop_assert!(w.value < 0.0 && (t0..=t0 + len).contains(&w.t));
                let out = coeffs.iter().zip(lower.iter().zip(&upper)).any(|(row, (&lo, &hi))| {
                    let x = exact_at(row, w.t);
                    x < BigRational::from_float(lo).unwrap() || x > BigRational::from_float(hi).unwrap()
                });
                proptest::prop_assert!(out, "witness {:?} is inside", w);
                proptest::prop_assert_eq!(check_workspace(&lower, &upper, piece).status, Status::Unsafe);
            }
        }

        /// Pieces inside the box that touch its wall (x = lo + k·t², x = hi − k·t² on a
        /// window around t = 0, exact in floating point) are never called outside.
        #[test]
        fn pieces_grazing_the_wall_are_not_outside(
            e in -300i32..300,
            k in 0.0f64..4.0,
            a in 0.0f64..1.0,
            len in 1e-3f64..4.0,
            upper_wall in proptest::bool::ANY,
        ) {
            let s = 2f64.powi(e);
            let (lower, upper) = ([0.0, -s], [s, s]);
            let row = if upper_wall { vec![s, 0.0, -k * s] } else { vec![0.0, 0.0, k * s] };
            // stays within [0, s]: k t² ≤ s needs |t| ≤ 1/√k
            let lim = if k > 0.0 { 0.99 / k.sqrt() } else { f64::INFINITY };
            let t0 = (-a * len).max(-lim);
            let t1 = (t0 + len).min(lim);
            let coeffs = vec![row, vec![0.0]];
            let piece = PieceRef { t0, t1, coeffs: &coeffs };
            proptest::prop_assert!(outside_by_intervals(&lower, &upper, piece).is_none());
        }
    }
}
