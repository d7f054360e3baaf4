//! The certifier's centred frame and a piece's coordinates substituted into it (`Frame`, `Substitution`), with the exact sign tests of straight coordinates.

use super::*;

/// The exact sign of `c0 + c1·t − l` (a straight coordinate's value at `t` against a
/// bound), by error-free transformations: `c1·t = p + e` exactly by a fused multiply-add
/// (when `p` is zero from a zero factor or at least `FMA_FLOOR`), `c0 − l` by
/// `two_sum`, and the four terms summed into a non-overlapping expansion (Shewchuk's
/// grow-expansion), whose sign is its largest component's. `None` when a value is not
/// finite or too large for the sums to be exact (the caller decides in rationals then).
pub fn straight_value_sign(c0: f64, c1: f64, t: f64, l: f64) -> Option<std::cmp::Ordering> {
    const LIMIT: f64 = pow2(1000);
    if ![c0, c1, t, l].iter().all(|v| v.is_finite() && v.abs() < LIMIT) {
        return None;
    }
    let p = c1 * t;
    let exact_product = (c1 == 0.0 || t == 0.0) || p.abs() >= FMA_FLOOR;
    if !exact_product || !p.is_finite() || p.abs() >= LIMIT {
        return None;
    }
    let e = c1.mul_add(t, -p);
    let (s, f) = two_sum(c0, -l);
    // grow the expansion term by term (components in increasing magnitude)
    let mut expansion: [f64; 4] = [0.0; 4];
    let mut len = 0;
    for x in [f, s, e, p] {
        let mut q = x;
        for h in expansion.iter_mut().take(len) {
            let (sum, err) = two_sum(q, *h);
            *h = err;
            q = sum;
        }
        expansion[len] = q;
        len += 1;
    }
    let top = expansion[..len].iter().rev().find(|v| **v != 0.0).copied().unwrap_or(0.0);
    top.partial_cmp(&0.0)
}

/// Error-free sum: `a + b = s + e` exactly (Knuth's TwoSum; exact also under gradual
/// underflow, where sums are exact).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// Rounds an exact rational for the running error model: `(v, 0)` when the float `v`
/// is the rational, `(v, 1)` when `v` is normal (at least [`MODEL_FLOOR`]) and within
/// one relative rounding of it (`|v − q| ≤ u·|q|`, checked exactly, not assumed of the
/// conversion), `None` otherwise: a value lost to underflow, subnormal, or overflowed.
pub fn round_for_model(q: &BigRational) -> Option<(f64, u32)> {
    let v = riskplan_math::poly::rational_to_f64(q);
    if riskplan_math::poly::cmp_float_rational(v, q)? == std::cmp::Ordering::Equal {
        return Some((v, 0));
    }
    (v.abs() >= MODEL_FLOOR && riskplan_math::poly::float_within_rounding(v, q)).then_some((v, 1))
}

/// The frame of the compiled variables (docs/design.md §5.10): centred and scaled by
/// powers of two, `z_v = (x_v − c_v)·2^(−e_v)` for space and time alike. The centre
/// keeps the coefficients free of cancellation far from the origin; the scale
/// (`2^e_v` about the workspace's half-width, or half the horizon) keeps them in the
/// middle of the `f64` range at any scale, so a workspace of 10²¹ or 10⁻³⁰ compiles to
/// the same numbers as a unit one. Powers of two make the scaling exact.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// The centre `(c_1..c_n, t_c)`: floats, used exactly.
    pub center: Vec<f64>,
    /// The scale exponents `e_v`, in `[−1000, 1000]`.
    pub exponents: Vec<i32>,
}

impl Frame {
    /// Largest scale exponent magnitude: `2^±1000` and its inverse are normal floats.
    pub const MAX_EXPONENT: i32 = 1000;

    /// The frame centred at `center` whose scale `2^e_v` is the power of two nearest
    /// below `half_widths[v]` (1 where that is zero or not finite).
    pub fn new(center: &[f64], half_widths: &[f64]) -> Frame {
        let exponents = center
            .iter()
            .enumerate()
            .map(|(v, _)| {
                let w = half_widths.get(v).copied().unwrap_or(1.0);
                if w > 0.0 && w.is_finite() {
                    (w.log2().floor() as i32).clamp(-Self::MAX_EXPONENT, Self::MAX_EXPONENT)
                } else {
                    0
                }
            })
            .collect();
        Frame { center: center.to_vec(), exponents }
    }

    /// The frame centred at `center` with unit scales (tests, and callers without a
    /// workspace).
    pub fn centred(center: &[f64]) -> Frame {
        Frame { center: center.to_vec(), exponents: vec![0; center.len()] }
    }

    /// Number of variables (space, then time).
    pub fn len(&self) -> usize {
        self.center.len()
    }

    /// Whether there are no variables.
    pub fn is_empty(&self) -> bool {
        self.center.is_empty()
    }

    /// The compiled coordinates `(x − c)·2^(−e)` of a point (space, then time), enclosed.
    pub fn point_coords(&self, xt: &[f64]) -> Vec<Interval> {
        xt.iter()
            .enumerate()
            .take(self.len())
            .map(|(v, &x)| (Interval::point(x) - Interval::point(self.center[v])) * Interval::point(self.inv_scale(v)))
            .collect()
    }

    /// [`Frame::point_coords`] in plain floating point (an estimate, for choices).
    pub fn point_coords_f64(&self, xt: &[f64]) -> Vec<f64> {
        xt.iter().enumerate().take(self.len()).map(|(v, &x)| (x - self.center[v]) * self.inv_scale(v)).collect()
    }

    /// `2^(−e_v)`, the factor from centred to compiled coordinates.
    pub fn inv_scale(&self, v: usize) -> f64 {
        pow2(-self.exponents[v])
    }
}

/// `v·2^(−e)` when that is exact (`None` when it is subnormal and inexact, or not
/// finite): scaling by a power of two is exact unless it leaves the normal range.
fn scale_exact(v: f64, inv: f64) -> Option<f64> {
    let w = v * inv;
    (w.is_finite() && w / inv == v).then_some(w)
}

/// The centred, scaled coordinates of a piece, `z_d(τ) = (x_d(t0 + hτ) − c_d)·2^(−e_d)`
/// and `z_t(τ) = (t0 + hτ − t_c)·2^(−e_t)`, as coefficients with their rounding data
/// `(value, |terms|, roundings)` for [`EPoly`] (docs/design.md §5.10). Computed once
/// per piece and shared by every obstacle compiled in the same [`Frame`].
///
/// The constant term of a coordinate cancels: a workspace at x ≈ 1000 gives
/// `c0 + c1·t0 − c ≈ 0.5` from terms of size 1000, and a running bound built on the
/// terms' sizes would carry 1000 into every power of y. So it is computed without
/// that loss: for straight pieces by error-free transformations (`c1·t0 = p + e1`
/// exactly by a fused multiply-add, `c0 + p = s + e2` and `s − c = s2 + e3` by TwoSum,
/// then `y0 = s2 + (e1 + e2 + e3)`: three roundings of terms whose sizes add up to
/// about `|y0|`); for curved pieces, and for straight ones whose product `c1·t0` is too
/// small for the FMA to be error-free (`FMA_FLOOR`), exactly in rationals, then
/// rounded once ([`round_for_model`]). Every rounded value is normal or exact; the
/// scaling by `2^(−e)` is checked exact. `None` when that cannot be had.
#[derive(Clone, Debug)]
pub struct Substitution {
    pub(super) coeffs: [[(f64, f64, u32); MAX_SUB_LEN]; 9],
    pub(super) len: [usize; 9],
    pub(super) nv: usize,
    pub(super) piece_degree: usize,
}

/// Coefficients of one substituted coordinate: a piece of degree ≤ 8 (the trajectory
/// format's limit) gives at most 9.
const MAX_SUB_LEN: usize = 9;

/// Whether a rounded product `p = x·y` obeys the relative model: exact zero from a zero
/// factor, or at least [`MODEL_FLOOR`] (no underflow).
fn product_in_model(p: f64, x: f64, y: f64) -> bool {
    if x == 0.0 || y == 0.0 {
        true
    } else {
        p.abs() >= MODEL_FLOOR
    }
}

impl Substitution {
    /// The substituted coordinates as [`EPoly`]s of capacity `N` (the first `nv` of the
    /// array); `None` when one does not fit.
    pub fn epolys<const N: usize>(&self) -> Option<[EPoly<N>; 9]> {
        let mut subs = [EPoly::<N>::zero(); 9];
        for (d, e) in subs.iter_mut().enumerate().take(self.nv) {
            let len = self.len[d];
            if len > N {
                return None;
            }
            for (k, &(v, a, r)) in self.coeffs[d][..len].iter().enumerate() {
                e.v[k] = v;
                e.a[k] = a;
                e.k = e.k.max(r);
            }
            e.len = len;
        }
        Some(subs)
    }

    /// The number of substituted coordinates.
    pub fn len(&self) -> usize {
        self.nv
    }

    /// Whether there are none (never, for a substitution that was built).
    pub fn is_empty(&self) -> bool {
        self.nv == 0
    }

    /// The highest degree among the substituted coordinates.
    pub fn degree(&self) -> usize {
        self.len[..self.nv].iter().map(|l| l.saturating_sub(1)).max().unwrap_or(0)
    }

    /// The substitution of `piece` in `frame` (space, then time); `None` for more
    /// than 8 coordinates, a piece of degree above 8, non-finite numbers, or a value
    /// outside the error model's range.
    pub fn new(piece: PieceRef<'_>, frame: &Frame) -> Option<Substitution> {
        let center = &frame.center;
        let nv = center.len();
        if nv > 9 || nv == 0 || frame.exponents.len() != nv {
            return None;
        }
        let mut out = Substitution { coeffs: [[(0.0, 0.0, 0); MAX_SUB_LEN]; 9], len: [0; 9], nv, piece_degree: 0 };
        let (t0, t1) = (piece.t0, piece.t1);
        let h = t1 - t0; // one rounding (a sum: exact if subnormal)
        #[allow(clippy::needless_range_loop)] // d indexes the piece's rows, the centre and the output
        for d in 0..nv - 1 {
            let row: &[f64] = piece.coeffs.get(d).map(|r| r.as_slice()).unwrap_or(&[]);
            if row.len() > MAX_SUB_LEN {
                return None;
            }
            out.piece_degree = out.piece_degree.max(row.len().saturating_sub(1));
            let c = center[d];
            let straight = match row.len() {
                0 | 1 => {
                    let c0 = row.first().copied().unwrap_or(0.0);
                    let (s, e) = two_sum(c0, -c);
                    out.coeffs[d][0] = (s + e, s.abs() + e.abs(), 1);
                    out.len[d] = 1;
                    true
                }
                2 => {
                    let (c0, c1) = (row[0], row[1]);
                    let p = c1 * t0;
                    let y1 = c1 * h;
                    let fma_exact = t0 == 0.0 || c1 == 0.0 || p.abs() >= FMA_FLOOR;
                    if fma_exact && product_in_model(y1, c1, h) {
                        let e1 = c1.mul_add(t0, -p);
                        let (s, e2) = two_sum(c0, p);
                        let (s2, e3) = two_sum(s, -c);
                        let y0 = s2 + (e1 + e2 + e3);
                        out.coeffs[d][0] = (y0, s2.abs() + e1.abs() + e2.abs() + e3.abs(), 3);
                        out.coeffs[d][1] = (y1, y1.abs(), 2);
                        out.len[d] = 2;
                        true
                    } else {
                        false
                    }
                }
                _ => false,
            };
            if !straight {
                // exactly (dyadic rationals: floats' sums and products, no divisions), then
                // each coefficient rounded once
                use riskplan_math::poly::dyadic::{compose_affine, Dyadic};
                let mut poly = compose_affine(row, t0, t1)?;
                poly[0] = poly[0].sub(&Dyadic::from_f64(c)?);
                for (slot, q) in out.coeffs[d].iter_mut().zip(&poly).take(row.len()) {
                    let (v, r) = round_for_model(&q.to_rational())?;
                    *slot = (v, v.abs(), r);
                }
                out.len[d] = row.len();
            }
        }
        let (s, e) = two_sum(t0, -center[nv - 1]);
        out.coeffs[nv - 1][0] = (s + e, s.abs() + e.abs(), 1);
        out.coeffs[nv - 1][1] = (h, h.abs(), 1);
        out.len[nv - 1] = 2;
        for d in 0..nv {
            let inv = frame.inv_scale(d);
            for slot in &mut out.coeffs[d][..out.len[d]] {
                *slot = (scale_exact(slot.0, inv)?, scale_exact(slot.1, inv)?, slot.2);
            }
        }
        Some(out)
    }
}
