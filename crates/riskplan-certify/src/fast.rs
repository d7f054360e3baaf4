//! The compiled restriction: contour polynomials prepared once per obstacle so that
//! restricting them to a trajectory piece allocates nothing (docs/design.md §5.1, §5.10).
//!
//! [`super::restrict_interval`] composes the contour polynomials with a piece through
//! general polynomial objects, a heap allocation per product; for a planner's edge
//! that bookkeeping costs far more than the positivity proof itself. Here E\[P\] and
//! E\[P²\] are compiled once into a Horner tree ([`Compiled`]) over **centred**
//! variables `y = x − c`, `s = t − t_c`, and a piece's coordinates are substituted as
//! fixed-capacity univariate interval polynomials ([`FPoly`]), on the stack.
//!
//! Soundness is the same as the interval restriction's: the compiled coefficients are
//! outward-rounded enclosures of the *exact* centred polynomial (the shift is done in
//! rationals), every operation is outward rounded, so the resulting coefficients
//! enclose those of the exact restriction `e1(τ)`, `e2(τ)` of eq. (15). Centring
//! matters off the paper's unit scenes: a workspace at x ≈ 1000 makes the monomials of
//! the uncentred polynomial cancel by many orders of magnitude, and the enclosures
//! lose as many digits; in centred variables the coefficients stay at the scale of the
//! obstacle.

mod bounds;
pub use bounds::{restricted, CompiledBounds};

use super::bernstein::MAX_DEGREE;
use super::compose::PieceRef;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use riskplan_math::contour::RiskContour;
use riskplan_math::poly::{Interval, Poly, QPoly, UPoly};

/// Capacity of an [`FPoly`]: the Bernstein checker's stack-buffer degree plus one.
/// A restriction of higher degree is not compiled ([`CompiledContour::restrict`] returns
/// `None`) and the caller falls back to the general path.
pub const CAPACITY: usize = MAX_DEGREE + 1;

/// A univariate polynomial in τ with interval coefficients, of degree < [`CAPACITY`],
/// stored inline (no heap).
#[derive(Clone, Copy, Debug)]
pub struct FPoly<const N: usize = CAPACITY> {
    c: [Interval; N],
    len: usize,
}

const ZERO: Interval = Interval { lo: 0.0, hi: 0.0 };

impl<const N: usize> FPoly<N> {
    /// The zero polynomial.
    pub fn zero() -> Self {
        FPoly { c: [ZERO; N], len: 0 }
    }
    /// A constant.
    pub fn constant(v: Interval) -> Self {
        let mut p = Self::zero();
        p.c[0] = v;
        p.len = 1;
        p
    }
    /// `a + b·τ`.
    pub fn linear(a: Interval, b: Interval) -> Self {
        let mut p = Self::constant(a);
        p.c[1] = b;
        p.len = 2;
        p
    }
    /// Coefficients of `τ^0, τ^1, …` (no trailing zeros are removed).
    pub fn coeffs(&self) -> &[Interval] {
        &self.c[..self.len]
    }
    /// `self += o`.
    pub fn add_assign(&mut self, o: &FPoly<N>) {
        for k in 0..o.len {
            self.c[k] = if k < self.len { self.c[k] + o.c[k] } else { o.c[k] };
        }
        self.len = self.len.max(o.len);
    }
    /// `self − o`.
    pub fn sub(&self, o: &FPoly<N>) -> FPoly<N> {
        let mut r = *self;
        r.add_assign(&o.neg());
        r
    }
    /// `−self`.
    pub fn neg(&self) -> FPoly<N> {
        let mut r = *self;
        for v in &mut r.c[..r.len] {
            *v = -*v;
        }
        r
    }
    /// `s·self`.
    pub fn scale(&self, s: Interval) -> FPoly<N> {
        let mut r = *self;
        for v in &mut r.c[..r.len] {
            *v = *v * s;
        }
        r
    }
    /// `self·o`, or `None` when the degree would reach the capacity `N`.
    pub fn mul(&self, o: &FPoly<N>) -> Option<FPoly<N>> {
        if self.len == 0 || o.len == 0 {
            return Some(FPoly::zero());
        }
        let len = self.len + o.len - 1;
        if len > N {
            return None;
        }
        let mut r = FPoly { c: [ZERO; N], len };
        for i in 0..self.len {
            let a = self.c[i];
            for j in 0..o.len {
                r.c[i + j] = r.c[i + j] + a * o.c[j];
            }
        }
        Some(r)
    }
    /// Degree (`len − 1`; 0 for the zero polynomial).
    pub fn degree(&self) -> usize {
        self.len.saturating_sub(1)
    }
    /// The same polynomial in a buffer of capacity `M`; `None` when it does not fit.
    pub fn resized<const M: usize>(&self) -> Option<FPoly<M>> {
        if self.len > M {
            return None;
        }
        let mut r = FPoly::<M>::zero();
        r.c[..self.len].copy_from_slice(&self.c[..self.len]);
        r.len = self.len;
        Some(r)
    }
}

/// Unit roundoff of `f64` (round to nearest): `2^-53`.
const UNIT_ROUNDOFF: f64 = 1.1102230246251565e-16;

/// Absolute slack added to each error bound in [`EPoly::enclosure`]: it covers the
/// rounding of that very computation (`a·factor` may be subnormal, where rounding errs
/// by up to `2^-1075` absolutely). It is **not** a cover for underflow inside the
/// restriction: an absolute error there is multiplied by later factors (y⁸…y¹⁶), which
/// no constant covers; [`MODEL_FLOOR`] keeps every such error relative instead
/// (docs/design.md §5.10).
const ENCLOSURE_SLACK: f64 = 1e-300;

/// `2^-1020`, four times the smallest normal `f64`: the smallest magnitude at which the
/// running error model of [`EPoly`] accepts a rounded quantity (docs/design.md §5.10,
/// "the whole f64 range"). A rounded input (compiled coefficient, substituted
/// coordinate, `1−Δ`) must be exact or at least this large, and every product of two
/// nonzero running absolute values must be at least this large; otherwise the compiled
/// path refuses (returns `None`) and the caller's interval/exact path decides. At or
/// above it a product is normal, so its rounding is relative (`|δ| ≤ u`), and the
/// absolute error `≤ 2^-1075` of a product that underflows by cancellation of signed
/// terms is at most `u` times the absolute terms behind it — one more rounding per
/// product. The factor 4 over the smallest normal absorbs `(1 ± γ_k)` between the
/// computed and the exact absolute values (`k·u < 10^-3` is enforced).
pub const MODEL_FLOOR: f64 = pow2(-1020);

/// `2^-968`: the smallest nonzero product `c1·t0` whose rounding error a fused
/// multiply-add returns exactly (the error of a product is a float when the product's
/// exponent is at least `emin + p − 1 = −970`; docs/design.md §5.10). Smaller products
/// are substituted through exact rationals instead.
const FMA_FLOOR: f64 = pow2(-968);

/// `2^e` for `−1022 ≤ e ≤ 1023`, exactly (built from its bits).
pub const fn pow2(e: i32) -> f64 {
    assert!(-1022 <= e && e <= 1023);
    f64::from_bits(((e + 1023) as u64) << 52)
}

/// A univariate polynomial in τ computed in plain `f64` with a running bound on its
/// rounding error (docs/design.md §5.10): beside each coefficient `v` it carries `a`,
/// the same computation on the absolute values of every input, and `k`, a bound on the
/// number of roundings on any path from an input to a coefficient. Each computed
/// coefficient is `Σ ±(Π inputs)·Π_{j≤k}(1+δ_j)` with `|δ_j| ≤ u`, so it errs from the
/// exact value by at most `γ_k·|E|_abs`, `γ_k = k·u/(1 − k·u)`, and the computed `a`
/// is at least `(1 − γ_k)·|E|_abs` (Higham, *Accuracy and Stability*, §3.1–3.4).
/// [`EPoly::enclosure`] turns this into outward intervals. Two `f64` operations per
/// operation instead of an interval's eight and two roundings outward.
#[derive(Clone, Copy, Debug)]
pub struct EPoly<const N: usize> {
    v: [f64; N],
    a: [f64; N],
    len: usize,
    k: u32,
}

impl<const N: usize> EPoly<N> {
    /// The zero polynomial.
    pub fn zero() -> Self {
        EPoly { v: [0.0; N], a: [0.0; N], len: 0, k: 0 }
    }
    /// A constant known exactly (a float input).
    pub fn exact(c: f64) -> Self {
        let mut p = Self::zero();
        p.v[0] = c;
        p.a[0] = c.abs();
        p.len = 1;
        p
    }
    /// `a + b·τ` from exact floats.
    pub fn linear(a: f64, b: f64) -> Self {
        let mut p = Self::exact(a);
        p.v[1] = b;
        p.a[1] = b.abs();
        p.len = 2;
        p
    }
    /// `self + o` (`sign` −1 subtracts).
    pub fn add_signed(&self, o: &EPoly<N>, sign: f64) -> EPoly<N> {
        let mut r = *self;
        for i in 0..o.len {
            if i < r.len {
                r.v[i] += sign * o.v[i];
                r.a[i] += o.a[i];
            } else {
                r.v[i] = sign * o.v[i];
                r.a[i] = o.a[i];
            }
        }
        r.len = r.len.max(o.len);
        r.k = r.k.max(o.k) + 1;
        r
    }
    /// The smallest nonzero running absolute value (`+∞` when all are zero).
    fn min_abs(&self) -> f64 {
        self.a[..self.len].iter().fold(f64::INFINITY, |m, &a| if a != 0.0 { m.min(a) } else { m })
    }

    /// `self·o`, or `None` beyond the capacity or outside the model's range.
    ///
    /// Roundings: each exact coefficient is a sum of terms carrying `(1+θ_kx)` and
    /// `(1+θ_ky)` factors, so their product carries `(1+θ_(kx+ky))`; the float product
    /// adds one rounding, its possible underflow one more (see [`MODEL_FLOOR`]), and the
    /// at most `min(len)` products summed into one coefficient add `min(len) − 1`:
    /// `k = kx + ky + min(len) + 1`. (An earlier `max(kx, ky) + min(len) + 1`
    /// undercounted when both operands were computed — see the test
    /// `product_of_two_computed_operands_is_enclosed`.)
    ///
    /// Range: every product of two nonzero running absolute values is at least
    /// `min_abs(self)·min_abs(o)` (rounding is monotone); when that is below
    /// [`MODEL_FLOOR`] a product may underflow and its error would be absolute, so the
    /// product is refused (`None`).
    pub fn mul(&self, o: &EPoly<N>) -> Option<EPoly<N>> {
        if self.len == 0 || o.len == 0 {
            return Some(EPoly::zero());
        }
        let len = self.len + o.len - 1;
        if len > N {
            return None;
        }
        let (m1, m2) = (self.min_abs(), o.min_abs());
        if m1.is_finite() && m2.is_finite() && m1 * m2 < MODEL_FLOOR {
            return None;
        }
        let mut r = EPoly { v: [0.0; N], a: [0.0; N], len, k: self.k + o.k + self.len.min(o.len) as u32 + 1 };
        for i in 0..self.len {
            let (x, xa) = (self.v[i], self.a[i]);
            for j in 0..o.len {
                r.v[i + j] += x * o.v[j];
                r.a[i + j] += xa * o.a[j];
            }
        }
        Some(r)
    }
    /// [`EPoly::add_signed`] in place.
    fn add_assign_signed(&mut self, o: &EPoly<N>, sign: f64) {
        for i in 0..o.len {
            if i < self.len {
                self.v[i] += sign * o.v[i];
                self.a[i] += o.a[i];
            } else {
                self.v[i] = sign * o.v[i];
                self.a[i] = o.a[i];
            }
        }
        self.len = self.len.max(o.len);
        self.k = self.k.max(o.k) + 1;
    }

    /// [`EPoly::mul`] in place (no copy of the arrays; `None` leaves `self` unspecified).
    /// Coefficient `p` of the product is the same sum of products `x_i·o_j`, `i + j = p`,
    /// accumulated in another order (`i` descending: position `i` is written first by
    /// `x_i·o_0` once no higher `i` can reach it); the rounding bound counts additions,
    /// not their order, so the model of [`EPoly::mul`] holds unchanged.
    fn mul_assign(&mut self, o: &EPoly<N>) -> Option<()> {
        if self.len == 0 || o.len == 0 {
            self.len = 0;
            self.k = 0;
            return Some(());
        }
        let len = self.len + o.len - 1;
        if len > N {
            return None;
        }
        let (m1, m2) = (self.min_abs(), o.min_abs());
        if m1.is_finite() && m2.is_finite() && m1 * m2 < MODEL_FLOOR {
            return None;
        }
        let k = self.k + o.k + self.len.min(o.len) as u32 + 1;
        for i in self.len..len {
            self.v[i] = 0.0;
            self.a[i] = 0.0;
        }
        for i in (0..self.len).rev() {
            let (x, xa) = (self.v[i], self.a[i]);
            self.v[i] = x * o.v[0];
            self.a[i] = xa * o.a[0];
            for j in 1..o.len {
                self.v[i + j] += x * o.v[j];
                self.a[i + j] += xa * o.a[j];
            }
        }
        self.len = len;
        self.k = k;
        Some(())
    }

    /// `s·self` for an enclosed scalar given by its nearest float and its own bound of
    /// roundings `ks` (1 for a rounded rational, which must then be normal); `None`
    /// outside the model's range (as [`EPoly::mul`]).
    pub fn scale(&self, s: f64, ks: u32) -> Option<EPoly<N>> {
        let m = self.min_abs();
        if s != 0.0 && m.is_finite() && m * s.abs() < MODEL_FLOOR {
            return None;
        }
        let mut r = *self;
        for i in 0..r.len {
            r.v[i] *= s;
            r.a[i] *= s.abs();
        }
        r.k = self.k + ks + 2;
        Some(r)
    }
    /// Outward intervals enclosing the exact coefficients, or `None` when a value is
    /// not finite or the rounding count is too large for the bound to mean anything.
    pub fn enclosure(&self, out: &mut [Interval; N]) -> Option<usize> {
        let ku = self.k as f64 * UNIT_ROUNDOFF;
        if ku >= 1e-3 {
            return None;
        }
        // γ_k/(1 − γ_k) ≤ k·u/(1 − 2k·u), enlarged by 2^-40 for the rounding of this
        // very computation
        let factor = ku / (1.0 - 2.0 * ku) * (1.0 + 1.0 / (1u64 << 40) as f64);
        for ((o, &v), &a) in out.iter_mut().zip(&self.v).zip(&self.a).take(self.len) {
            let e = a * factor + ENCLOSURE_SLACK;
            if !(v.is_finite() && e.is_finite()) {
                return None;
            }
            *o = Interval { lo: (v - e).next_down(), hi: (v + e).next_up() };
        }
        Some(self.len)
    }
}

/// `2^-900`: the smallest nonzero midpoint or radius [`RPoly`] takes (smaller ones are
/// widened to about it), so that the products of running values stay above
/// [`MODEL_FLOOR`] — the guard of [`RPoly`]'s product still refuses any that would not.
/// Used only for polynomials whose largest coefficient is at least [`RPOLY_MIN_SCALE`],
/// where the widening is below 2⁻³⁰⁰ relative.
const RADIUS_FLOOR: f64 = pow2(-900);

/// `2^-600`: the smallest largest-coefficient magnitude of a polynomial restricted
/// through [`RPoly`] (smaller ones take the interval walk).
pub const RPOLY_MIN_SCALE: f64 = pow2(-600);

/// An [`EPoly`] whose inputs are intervals (the central moments' enclosures, §3.8):
/// each input coefficient is its midpoint `m`, taken as an exact float, plus an unknown
/// `δ` with `|δ| ≤ r`. A composition is linear in its coefficients, so the exact
/// restriction differs from the one computed from the midpoints by `Σ δ_β·s(τ)^β`, which
/// is bounded coefficientwise by the same computation on `r_β` and the substitutions'
/// absolute values — carried here in `r`, beside the value `v`, its running absolute
/// value `a` and the rounding count `k` of [`EPoly`] (docs/design.md §5.13). Three `f64`
/// operations per operation instead of an interval's eight and two outward roundings.
#[derive(Clone, Copy, Debug)]
pub struct RPoly<const N: usize> {
    v: [f64; N],
    a: [f64; N],
    r: [f64; N],
    len: usize,
    k: u32,
}

impl<const N: usize> RPoly<N> {
    fn zero() -> Self {
        RPoly { v: [0.0; N], a: [0.0; N], r: [0.0; N], len: 0, k: 0 }
    }

    /// The constant `[lo, hi]`: its midpoint exactly and a radius rounded up (0 for a
    /// point). A nonzero radius below [`RADIUS_FLOOR`] is raised to it, and a midpoint
    /// below it becomes 0 with the radius grown by [`RADIUS_FLOOR`] (larger radii are sound; they
    /// keep the products of running values in the relative model). `None` when not finite.
    fn interval(c: Interval) -> Option<Self> {
        let mut m = c.mid();
        if !(m.is_finite() && c.lo.is_finite() && c.hi.is_finite()) {
            return None;
        }
        let (below, above) = (m - c.lo, c.hi - m);
        let mut rad = if below > 0.0 || above > 0.0 { below.max(above).next_up() } else { 0.0 };
        if rad != 0.0 && rad < RADIUS_FLOOR {
            rad = RADIUS_FLOOR;
        }
        if m != 0.0 && m.abs() < RADIUS_FLOOR {
            // [m − rad, m + rad] ⊆ [−(|m| + rad), |m| + rad] and |m| < RADIUS_FLOOR (the
            // radius may be far larger than the midpoint: an interval straddling 0)
            m = 0.0;
            rad = (rad + RADIUS_FLOOR).next_up().max(4.0 * RADIUS_FLOOR);
        }
        let mut p = Self::zero();
        p.v[0] = m;
        p.a[0] = m.abs();
        p.r[0] = rad;
        p.len = 1;
        Some(p)
    }

    /// The substituted coordinate `s` (exact radius 0).
    fn from_sub(s: &EPoly<N>) -> Self {
        RPoly { v: s.v, a: s.a, r: [0.0; N], len: s.len, k: s.k }
    }

    fn add(&self, o: &RPoly<N>) -> RPoly<N> {
        let mut r = *self;
        for i in 0..o.len {
            if i < r.len {
                r.v[i] += o.v[i];
                r.a[i] += o.a[i];
                r.r[i] += o.r[i];
            } else {
                r.v[i] = o.v[i];
                r.a[i] = o.a[i];
                r.r[i] = o.r[i];
            }
        }
        r.len = r.len.max(o.len);
        r.k = r.k.max(o.k) + 1;
        r
    }

    /// The smallest nonzero running absolute value or radius.
    fn min_abs(&self) -> f64 {
        self.a[..self.len]
            .iter()
            .chain(&self.r[..self.len])
            .fold(f64::INFINITY, |m, &a| if a != 0.0 { m.min(a) } else { m })
    }

    /// `self·s` for a substituted coordinate `s` (radius 0), as [`EPoly::mul`]: `None`
    /// beyond the capacity or when a product could underflow.
    fn mul_sub(&self, s: &RPoly<N>) -> Option<RPoly<N>> {
        if self.len == 0 || s.len == 0 {
            return Some(RPoly::zero());
        }
        let len = self.len + s.len - 1;
        if len > N {
            return None;
        }
        let (m1, m2) = (self.min_abs(), s.min_abs());
        if m1.is_finite() && m2.is_finite() && m1 * m2 < MODEL_FLOOR {
            return None;
        }
        let mut out =
            RPoly { v: [0.0; N], a: [0.0; N], r: [0.0; N], len, k: self.k + s.k + self.len.min(s.len) as u32 + 1 };
        for i in 0..self.len {
            let (x, xa, xr) = (self.v[i], self.a[i], self.r[i]);
            for j in 0..s.len {
                out.v[i + j] += x * s.v[j];
                out.a[i + j] += xa * s.a[j];
                out.r[i + j] += xr * s.a[j];
            }
        }
        Some(out)
    }

    /// Outward intervals enclosing every restriction of a polynomial within the input
    /// enclosures: `v ± (γ_k·a + (1 + 4k·u)·r)` (the radius run is a sum of products of
    /// nonnegative numbers, computed with at most `k` roundings from values that the
    /// substitutions' `a` majorise up to `(1 + γ)` factors); `None` when a value is not
    /// finite or `k` too large.
    fn enclosure(&self, out: &mut [Interval; N]) -> Option<usize> {
        let ku = self.k as f64 * UNIT_ROUNDOFF;
        if ku >= 1e-3 {
            return None;
        }
        let enlarge = 1.0 + 1.0 / (1u64 << 40) as f64;
        let factor = ku / (1.0 - 2.0 * ku) * enlarge;
        let rfactor = (1.0 + 4.0 * ku) * enlarge;
        for (i, o) in out.iter_mut().enumerate().take(self.len) {
            let e = self.a[i] * factor + self.r[i] * rfactor + ENCLOSURE_SLACK;
            let v = self.v[i];
            if !(v.is_finite() && e.is_finite()) {
                return None;
            }
            *o = Interval { lo: (v - e).next_down(), hi: (v + e).next_up() };
        }
        Some(self.len)
    }
}

/// Runs `$run::<N>(args…)` with the smallest stack capacity N (9, 17 or [`CAPACITY`])
/// that holds `$len` coefficients: every product of a Horner walk zeroes and copies its
/// whole buffer, so a straight piece's low orders should not pay for 33.
macro_rules! by_capacity {
    ($len:expr, $run:ident, $($arg:expr),*) => {
        if $len <= 9 {
            $run::<9>($($arg),*)
        } else if $len <= 17 {
            $run::<17>($($arg),*)
        } else {
            $run::<CAPACITY>($($arg),*)
        }
    };
}
pub(crate) use by_capacity;

/// Coefficients of `c` restricted to a piece whose coordinates have degree ≤ `sub_degree`.
pub(crate) fn restricted_len(c: &Compiled, sub_degree: usize) -> usize {
    c.degree().saturating_mul(sub_degree.max(1)).saturating_add(1)
}

/// `c` composed with a [`Substitution`] in `f64` with a running error bound, as an
/// enclosure in the smallest stack buffer that holds it.
fn enclosed_e(c: &Compiled, sub: &Substitution) -> Option<UPoly<Interval>> {
    fn run<const N: usize>(c: &Compiled, sub: &Substitution) -> Option<UPoly<Interval>> {
        let subs = sub.epolys::<N>()?;
        let e = c.compose_e(&subs[..sub.len()])?;
        let mut out = [ZERO; N];
        let n = e.enclosure(&mut out)?;
        Some(UPoly::new(out[..n].to_vec()))
    }
    by_capacity!(restricted_len(c, sub.degree()), run, c, sub)
}

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
    coeffs: [[(f64, f64, u32); MAX_SUB_LEN]; 9],
    len: [usize; 9],
    nv: usize,
    piece_degree: usize,
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

/// A node of a Horner tree: `Σ_k coeffs[k]·v^k` with each coefficient a tree over the
/// later variables.
#[derive(Clone, Debug)]
enum Node {
    Zero,
    /// The enclosure, and the nearest float with its rounding count (0 if exact).
    Const(Interval, f64, u32),
    Horner {
        var: usize,
        coeffs: Vec<Node>,
    },
}

/// A polynomial in `n` variables compiled for repeated evaluation: a Horner tree with
/// outward-rounded interval coefficients.
#[derive(Clone, Debug)]
pub struct Compiled {
    root: Node,
    nvars: usize,
    degree: usize,
    /// Every coefficient's nearest float is exact or normal ([`round_for_model`]): the
    /// `f64` path ([`Compiled::compose_e`]) is used only then.
    in_model: bool,
    /// The largest coefficient magnitude (of the enclosures' midpoints, or nearest floats).
    max_coeff: f64,
}

/// A term as its exponent vector and coefficient.
type ExpTerm<C> = (Vec<u32>, C);

/// Builds the Horner tree of `terms` from variable `var` on; `leaf` turns the terms that
/// differ only beyond the last variable into one constant node (summing their
/// coefficients).
fn build<C>(terms: &mut [ExpTerm<C>], var: usize, nvars: usize, leaf: &mut dyn FnMut(&[ExpTerm<C>]) -> Node) -> Node {
    if terms.is_empty() {
        return Node::Zero;
    }
    if var == nvars {
        return leaf(terms);
    }
    let top = terms.iter().map(|(e, _)| e[var]).max().unwrap_or(0) as usize;
    if top == 0 {
        return build(terms, var + 1, nvars, leaf);
    }
    terms.sort_by_key(|(e, _)| e[var]);
    let mut coeffs = Vec::with_capacity(top + 1);
    let mut i = 0;
    for k in 0..=top as u32 {
        let j = i + terms[i..].iter().take_while(|(e, _)| e[var] == k).count();
        coeffs.push(build(&mut terms[i..j], var + 1, nvars, leaf));
        i = j;
    }
    Node::Horner { var, coeffs }
}

/// The exponent vectors (variables `0..nvars`) and coefficients of `p`'s terms.
fn exponent_terms<C: riskplan_math::poly::Ring>(p: &Poly<C>, nvars: usize) -> Vec<(Vec<u32>, C)> {
    p.terms()
        .map(|(m, c)| {
            let mut e = vec![0u32; nvars];
            for &(v, k) in m.pairs() {
                if (v as usize) < nvars {
                    e[v as usize] = k;
                }
            }
            (e, c.clone())
        })
        .collect()
}

impl Compiled {
    /// Compiles `p` (variables `0..nvars`; any other variable must not occur) with
    /// every coefficient enclosed.
    pub fn new(p: &QPoly, nvars: usize) -> Self {
        let mut terms = exponent_terms(p, nvars);
        let degree = terms.iter().map(|(e, _)| e.iter().sum::<u32>() as usize).max().unwrap_or(0);
        let mut in_model = true;
        let root = build(&mut terms, 0, nvars, &mut |ts: &[(Vec<u32>, BigRational)]| {
            let mut acc = BigRational::zero();
            for (_, c) in ts {
                acc += c;
            }
            let (near, k) = round_for_model(&acc).unwrap_or_else(|| {
                in_model = false;
                (riskplan_math::poly::rational_to_f64(&acc), 1)
            });
            Node::Const(Interval::enclose_rational(&acc), near, k)
        });
        let max_coeff = max_const(&root);
        Compiled { root, nvars, degree, in_model, max_coeff }
    }

    /// Compiles a polynomial whose coefficients are enclosures already (the central
    /// moments of §3.8): usable with [`Compiled::compose`] only (interval arithmetic;
    /// the `f64` model path [`Compiled::compose_e`] refuses it).
    pub fn from_intervals(p: &Poly<Interval>, nvars: usize) -> Self {
        let mut terms = exponent_terms(p, nvars);
        let degree = terms.iter().map(|(e, _)| e.iter().sum::<u32>() as usize).max().unwrap_or(0);
        let root = build(&mut terms, 0, nvars, &mut |ts: &[(Vec<u32>, Interval)]| {
            let acc = ts.iter().fold(ZERO, |acc, (_, c)| acc + *c);
            Node::Const(acc, acc.mid(), 1)
        });
        let max_coeff = max_const(&root);
        Compiled { root, nvars, degree, in_model: false, max_coeff }
    }

    /// Total degree.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Number of variables.
    pub fn nvars(&self) -> usize {
        self.nvars
    }

    /// The polynomial with every variable replaced by a univariate polynomial in τ
    /// (`subs[v]`), enclosed; `None` when a degree would reach the capacity `N`.
    pub fn compose<const N: usize>(&self, subs: &[FPoly<N>]) -> Option<FPoly<N>> {
        fn go<const N: usize>(n: &Node, subs: &[FPoly<N>]) -> Option<FPoly<N>> {
            match n {
                Node::Zero => Some(FPoly::zero()),
                Node::Const(c, _, _) => Some(FPoly::constant(*c)),
                Node::Horner { var, coeffs } => {
                    let mut acc = go(&coeffs[coeffs.len() - 1], subs)?;
                    for c in coeffs[..coeffs.len() - 1].iter().rev() {
                        acc = acc.mul(&subs[*var])?;
                        if !matches!(c, Node::Zero) {
                            acc.add_assign(&go(c, subs)?);
                        }
                    }
                    Some(acc)
                }
            }
        }
        go(&self.root, subs)
    }

    /// [`Compiled::compose`] for a polynomial with interval coefficients
    /// ([`Compiled::from_intervals`]) in `f64` with midpoints, radii and a running error
    /// bound ([`RPoly`]): the enclosure of every restriction of a polynomial within the
    /// coefficients' intervals; `None` beyond the capacity or outside the model's range
    /// (the caller composes in interval arithmetic then).
    pub fn compose_r<const N: usize>(&self, subs: &[EPoly<N>]) -> Option<FPoly<N>> {
        if self.max_coeff.is_nan() || self.max_coeff < RPOLY_MIN_SCALE {
            return None;
        }
        fn go<const N: usize>(n: &Node, subs: &[RPoly<N>]) -> Option<RPoly<N>> {
            match n {
                Node::Zero => Some(RPoly::zero()),
                Node::Const(c, _, _) => RPoly::interval(*c),
                Node::Horner { var, coeffs } => {
                    let mut acc = go(&coeffs[coeffs.len() - 1], subs)?;
                    for c in coeffs[..coeffs.len() - 1].iter().rev() {
                        acc = acc.mul_sub(&subs[*var])?;
                        if !matches!(c, Node::Zero) {
                            acc = acc.add(&go(c, subs)?);
                        }
                    }
                    Some(acc)
                }
            }
        }
        let rs: Vec<RPoly<N>> = subs.iter().map(RPoly::from_sub).collect();
        let p = go(&self.root, &rs)?;
        let mut out = FPoly::<N>::zero();
        out.len = p.enclosure(&mut out.c)?;
        Some(out)
    }

    /// [`Compiled::compose`] in `f64` with a running error bound ([`EPoly`]); `None`
    /// beyond the capacity or outside the model's range (a coefficient, or a product
    /// on the way, that would underflow).
    pub fn compose_e<const N: usize>(&self, subs: &[EPoly<N>]) -> Option<EPoly<N>> {
        if !self.in_model {
            return None;
        }
        // in place: the polynomials are small and their arrays large, so copies, not
        // arithmetic, would dominate (a node's value goes to `out`)
        fn go<const N: usize>(n: &Node, subs: &[EPoly<N>], out: &mut EPoly<N>) -> Option<()> {
            match n {
                Node::Zero => {
                    out.len = 0;
                    out.k = 0;
                }
                Node::Const(_, f, k) => {
                    out.v[0] = *f;
                    out.a[0] = f.abs();
                    out.len = 1;
                    out.k = *k;
                }
                Node::Horner { var, coeffs } => {
                    go(&coeffs[coeffs.len() - 1], subs, out)?;
                    let mut term = EPoly::zero();
                    for c in coeffs[..coeffs.len() - 1].iter().rev() {
                        out.mul_assign(&subs[*var])?;
                        if !matches!(c, Node::Zero) {
                            go(c, subs, &mut term)?;
                            out.add_assign_signed(&term, 1.0);
                        }
                    }
                }
            }
            Some(())
        }
        let mut out = EPoly::zero();
        go(&self.root, subs, &mut out)?;
        Some(out)
    }

    /// The value at `vals` in plain floating point from the coefficients' nearest floats
    /// (an estimate, for choices; never for proofs).
    pub fn eval_f64(&self, vals: &[f64]) -> f64 {
        horner(&self.root, vals, 0.0, &|c| match c {
            Node::Const(_, f, _) => *f,
            _ => 0.0,
        })
    }

    /// An enclosure of the polynomial's range over the box `vals` (naive interval
    /// Horner evaluation).
    pub fn eval_box(&self, vals: &[Interval]) -> Interval {
        horner(&self.root, vals, ZERO, &|c| match c {
            Node::Const(i, _, _) => *i,
            _ => ZERO,
        })
    }
}

/// Horner evaluation of a tree at `vals`: `leaf` gives a constant node's value (`zero` for
/// an empty subtree).
fn horner<T>(n: &Node, vals: &[T], zero: T, leaf: &dyn Fn(&Node) -> T) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    match n {
        Node::Zero => zero,
        Node::Const(..) => leaf(n),
        Node::Horner { var, coeffs } => {
            let x = vals[*var];
            let mut acc = horner(&coeffs[coeffs.len() - 1], vals, zero, leaf);
            for c in coeffs[..coeffs.len() - 1].iter().rev() {
                acc = acc * x + horner(c, vals, zero, leaf);
            }
            acc
        }
    }
}

/// The largest magnitude among a tree's constants (nearest floats).
fn max_const(n: &Node) -> f64 {
    match n {
        Node::Zero => 0.0,
        Node::Const(_, f, _) => f.abs(),
        Node::Horner { coeffs, .. } => coeffs.iter().map(max_const).fold(0.0, f64::max),
    }
}

/// `p(c + 2^e·z)`: the polynomial in the compiled variables of `frame`, exactly.
pub fn to_frame(p: &QPoly, frame: &Frame) -> QPoly {
    let two = BigRational::from_integer(2.into());
    let maps: Vec<Option<(BigRational, BigRational)>> = frame
        .center
        .iter()
        .zip(&frame.exponents)
        .map(|(&c, &e)| {
            let c = BigRational::from_float(c).unwrap_or_default();
            let l: BigRational = num_traits::Pow::pow(&two, e);
            (!(c.is_zero() && l.is_one())).then_some((c, l))
        })
        .collect();
    riskplan_math::poly::affine_subst(p, &maps)
}

/// `∂p/∂x_v`, exactly.
pub fn derivative(p: &QPoly, v: usize) -> QPoly {
    let mut out = QPoly::zero();
    for (m, c) in p.terms() {
        let e = m.exp(v as riskplan_math::poly::Var);
        if e == 0 {
            continue;
        }
        let pairs = m.pairs().iter().map(|&(w, k)| if w as usize == v { (w, k - 1) } else { (w, k) });
        out.add_term(riskplan_math::poly::Monomial::from_pairs(pairs), c * BigRational::from_integer(e.into()));
    }
    out
}

/// One obstacle's E\[P\] and E\[P²\], compiled in centred variables
/// `(y_1..y_n, s) = (x − c, t − t_c)`.
#[derive(Clone, Debug)]
pub struct CompiledContour {
    frame: Frame,
    mean: Compiled,
    second: Compiled,
    /// The bounds beyond Cantelli in the same frame, compiled on first use (§5.13).
    bounds: std::sync::OnceLock<std::sync::Arc<CompiledBounds>>,
}

/// The two restricted moment polynomials of one obstacle on one piece.
#[derive(Clone, Copy, Debug)]
pub struct FastRestriction<const N: usize = CAPACITY> {
    /// `e1(τ) = E[P](x(t(τ)), t(τ))`.
    pub mean: FPoly<N>,
    /// `e2(τ) = E[P²](…)`.
    pub second: FPoly<N>,
}

impl<const N: usize> FastRestriction<N> {
    /// `g1 = e1² − (1−Δ)·e2` (Cantelli) and `g2 = −e1` (mean), for `1−Δ` enclosed in
    /// `one_minus_delta`; `None` when `e1²` exceeds the capacity.
    pub fn constraints(&self, one_minus_delta: Interval) -> Option<(FPoly<N>, FPoly<N>)> {
        let sq = self.mean.mul(&self.mean)?;
        Some((sq.sub(&self.second.scale(one_minus_delta)), self.mean.neg()))
    }
}

impl CompiledContour {
    /// Compiles a contour in `frame` (`dim + 1` variables: space, then time).
    pub fn new(contour: &RiskContour, frame: &Frame) -> Self {
        let nv = contour.layout().xt_len();
        debug_assert_eq!(frame.len(), nv);
        CompiledContour {
            frame: frame.clone(),
            mean: Compiled::new(&to_frame(&contour.mean, frame), nv),
            second: Compiled::new(&to_frame(&contour.second, frame), nv),
            bounds: std::sync::OnceLock::new(),
        }
    }

    /// Whether Cantelli's two constraints of eq. (15) are proven at the point `xt`
    /// (space, then time; floats used exactly) by interval evaluation of the compiled
    /// E\[P\] and E\[P²\]: `E[P] < 0` and `E[P]² − (1−Δ)·E[P²] > 0` with `1−Δ` enclosed in
    /// `one_minus_delta`. `false` means not proven here (the caller decides exactly).
    pub fn proves_point(&self, xt: &[f64], one_minus_delta: Interval) -> bool {
        if xt.len() != self.frame.len() || xt.iter().any(|v| !v.is_finite()) {
            return false;
        }
        let z = self.frame.point_coords(xt);
        let m = self.mean.eval_box(&z);
        // (a NaN bound fails both comparisons: not proven)
        if m.hi.is_nan() || m.hi >= 0.0 {
            return false;
        }
        let g1 = m * m - one_minus_delta * self.second.eval_box(&z);
        g1.lo > 0.0
    }

    /// The compiled bounds beyond Cantelli of `contour` (the contour this was compiled
    /// from), built on first use.
    pub fn bounds(&self, contour: &RiskContour) -> &CompiledBounds {
        self.bounds.get_or_init(|| std::sync::Arc::new(CompiledBounds::new(contour, &self.frame)))
    }

    /// Whether [`Self::bounds`] are built (for tests).
    pub fn bounds_built(&self) -> bool {
        self.bounds.get().is_some()
    }

    /// E\[P\] restricted to a piece (`subs`: its coordinates from
    /// [`CompiledContour::substitutions`]), enclosed.
    pub fn mean_on(&self, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
        restricted(&self.mean, subs)
    }

    /// E\[P²\] restricted to a piece, enclosed.
    pub fn second_on(&self, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
        restricted(&self.second, subs)
    }

    /// E\[P\] restricted to a piece given by its [`Substitution`], in `f64` with a running
    /// error bound ([`Compiled::compose_e`]), enclosed; `None` outside the model (the
    /// caller uses [`CompiledContour::mean_on`] then).
    pub fn mean_on_f64(&self, sub: &Substitution) -> Option<UPoly<Interval>> {
        enclosed_e(&self.mean, sub)
    }

    /// E\[P²\] likewise.
    pub fn second_on_f64(&self, sub: &Substitution) -> Option<UPoly<Interval>> {
        enclosed_e(&self.second, sub)
    }

    /// The frame of the compiled variables.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The compiled coordinates of a piece as polynomials in τ ∈ [0, 1]:
    /// `z_d(τ) = (x_d(t0 + hτ) − c_d)·2^(−e_d)`, `z_t(τ) = (t0 + hτ − t_c)·2^(−e_t)`, in
    /// interval arithmetic. `None` when a piece's degree exceeds the capacity or it has
    /// more than 8 coordinates.
    pub fn substitutions<const N: usize>(&self, piece: PieceRef<'_>) -> Option<[FPoly<N>; 9]> {
        let nv = self.frame.len();
        if nv > 9 || nv == 0 {
            return None;
        }
        let center = &self.frame.center;
        let t0 = Interval::point(piece.t0);
        let h = Interval::point(piece.t1) - t0;
        let lin = FPoly::linear(t0, h);
        let mut subs = [FPoly::zero(); 9];
        for (d, sub) in subs.iter_mut().enumerate().take(nv - 1) {
            let row: &[f64] = piece.coeffs.get(d).map(|r| r.as_slice()).unwrap_or(&[]);
            let mut acc = FPoly::zero();
            for &c in row.iter().rev() {
                acc = acc.mul(&lin)?;
                acc.add_assign(&FPoly::constant(Interval::point(c)));
            }
            acc.add_assign(&FPoly::constant(Interval::point(-center[d])));
            *sub = acc.scale(Interval::point(self.frame.inv_scale(d)));
        }
        subs[nv - 1] =
            FPoly::linear(t0 - Interval::point(center[nv - 1]), h).scale(Interval::point(self.frame.inv_scale(nv - 1)));
        Some(subs)
    }

    /// E\[P\] and E\[P²\] restricted to a piece, enclosed, with capacity `N`; `None`
    /// beyond it.
    pub fn restrict_with<const N: usize>(&self, piece: PieceRef<'_>) -> Option<FastRestriction<N>> {
        let subs = self.substitutions::<N>(piece)?;
        let subs = &subs[..self.frame.len()];
        Some(FastRestriction { mean: self.mean.compose(subs)?, second: self.second.compose(subs)? })
    }

    /// E\[P\] and E\[P²\] restricted to a piece, enclosed; `None` beyond [`CAPACITY`].
    pub fn restrict(&self, piece: PieceRef<'_>) -> Option<FastRestriction> {
        self.restrict_with::<CAPACITY>(piece)
    }

    /// Runs `f(g2, g1)` on outward intervals enclosing the coefficients of the mean
    /// and Cantelli constraints restricted to a piece (`1−Δ` given as its nearest float
    /// and whether that float is exact), computed in `f64` with a running error bound
    /// ([`EPoly`]) in the smallest stack buffer that holds them; `None` beyond
    /// [`CAPACITY`], on overflow, or outside the model's range ([`MODEL_FLOOR`]; a
    /// rounded `1−Δ` must be normal too). `subs` are the piece's compiled coordinates
    /// ([`Substitution::new`] in this contour's frame).
    pub fn with_constraints<R>(
        &self,
        subs: &Substitution,
        one_minus_delta: (f64, bool),
        f: impl FnOnce(&[Interval], &[Interval]) -> R,
    ) -> Option<R> {
        fn run<const N: usize, R>(
            c: &CompiledContour,
            sub: &Substitution,
            omd: (f64, bool),
            f: impl FnOnce(&[Interval], &[Interval]) -> R,
        ) -> Option<R> {
            let nv = c.frame.len();
            if nv != sub.nv || !(omd.1 || omd.0.abs() >= MODEL_FLOOR) {
                return None;
            }
            let subs = sub.epolys::<N>()?;
            let subs = &subs[..nv];
            let e1 = c.mean.compose_e(subs)?;
            let e2 = c.second.compose_e(subs)?;
            let g1 = e1.mul(&e1)?.add_signed(&e2.scale(omd.0, u32::from(!omd.1))?, -1.0);
            let (mut b1, mut b2) = ([ZERO; N], [ZERO; N]);
            let n1 = g1.enclosure(&mut b1)?;
            let n2 = e1.enclosure(&mut b2)?;
            for v in &mut b2[..n2] {
                *v = -*v;
            }
            Some(f(&b2[..n2], &b1[..n1]))
        }
        let need = self.restricted_degree(subs.piece_degree) + 1;
        if need <= 8 {
            run::<8, R>(self, subs, one_minus_delta, f)
        } else if need <= 16 {
            run::<16, R>(self, subs, one_minus_delta, f)
        } else {
            run::<CAPACITY, R>(self, subs, one_minus_delta, f)
        }
    }

    /// The degree in τ of `E[P²]` restricted to a piece of degree `k` in t (an upper
    /// bound: total degree times k).
    pub fn restricted_degree(&self, piece_degree: usize) -> usize {
        self.second.degree().max(2 * self.mean.degree()) * piece_degree.max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compose::restrict_exact;
    use num_traits::Signed;
    use proptest::prelude::*;
    use riskplan_math::contour::Layout;
    use riskplan_math::poly::VarTable;

    fn contour(text: &str, dim: usize) -> RiskContour {
        let mut names: Vec<String> = (1..=dim).map(|i| format!("x{i}")).collect();
        names.push("t".into());
        names.push("w".into());
        let vars = VarTable::new(names);
        // a large work budget: the extreme-scale texts carry numbers of thousands of digits
        let mut budget = usize::MAX;
        let p = riskplan_math::poly::parse_with_budget(
            text,
            &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string()),
            &mut budget,
        )
        .unwrap();
        // w uniform on [0.3, 0.4]: raw moments (b^{k+1} − a^{k+1}) / ((k+1)(b − a))
        let m = |k: u32| {
            let (a, b) = (BigRational::new(3.into(), 10.into()), BigRational::new(4.into(), 10.into()));
            let p1 = |x: &BigRational| num_traits::pow(x.clone(), k as usize + 1);
            (p1(&b) - p1(&a)) / (BigRational::from_integer((k + 1).into()) * (b - a))
        };
        RiskContour::new(Layout { dim }, &p, &|_, k| Some(m(k)), &|v| vars.name(v)).unwrap()
    }

    fn encloses(i: &[Interval], e: &riskplan_math::poly::UPoly<BigRational>) -> Result<(), String> {
        for k in 0..=e.degree().max(i.len().saturating_sub(1)) {
            let v = e.coeff(k);
            let b = i.get(k).copied().unwrap_or(ZERO);
            // an infinite end bounds nothing on its side
            let above = b.lo == f64::NEG_INFINITY || BigRational::from_float(b.lo).is_some_and(|lo| lo <= v);
            let below = b.hi == f64::INFINITY || BigRational::from_float(b.hi).is_some_and(|hi| v <= hi);
            if !(above && below) {
                return Err(format!("coefficient {k}: {v} not in {b:?}"));
            }
        }
        Ok(())
    }

    /// Squaring a value that has already been rounded ten times: each sum `1 + b`
    /// rounds back to 1, so the float result is 1 while the exact value is
    /// `(1 + 10b)² ≈ 1 + 2.2e-15`. The enclosure must hold it; a rounding count of
    /// `max(kx, ky) + min(len) + 1` would give an interval that misses it.
    #[test]
    fn product_of_two_computed_operands_is_enclosed() {
        let b = (1.0 - 2f64.powi(-10)) * 2f64.powi(-53);
        let mut x = EPoly::<4>::exact(1.0);
        for _ in 0..10 {
            x = x.add_signed(&EPoly::exact(b), 1.0);
        }
        assert_eq!(x.v[0], 1.0, "every sum rounds back to 1");
        let sq = x.mul(&x).unwrap();
        let mut out = [ZERO; 4];
        assert_eq!(sq.enclosure(&mut out), Some(1));
        let exact_x = BigRational::from_integer(1.into())
            + BigRational::from_float(b).unwrap() * BigRational::from_integer(10.into());
        let exact = exact_x.clone() * exact_x;
        let (lo, hi) = (BigRational::from_float(out[0].lo).unwrap(), BigRational::from_float(out[0].hi).unwrap());
        assert!(lo <= exact && exact <= hi, "{:?} misses {}", out[0], exact);
    }

    proptest! {
        /// The compiled restriction encloses the exact one (computed in rationals by a
        /// different code path: no centring, general polynomial composition), for moving
        /// and static obstacles, curved pieces, far-off centres and shifted times.
        #[test]
        fn compiled_restriction_encloses_the_exact_one(
            cx in -1e3f64..1e3, cy in -1e3f64..1e3, tc in -50f64..50.0,
            a in prop::collection::vec(-2f64..2.0, 3), b in prop::collection::vec(-2f64..2.0, 3),
            t0 in -20f64..20.0, h in 1e-3f64..10.0, moving in any::<bool>(),
        ) {
            let text = if moving {
                format!("w^2 - (x1 - {cx} - 0.1*t)^2 - (x2 - {cy} + 0.05*t^2)^2")
            } else {
                format!("w^2*(1 - x1 + x2) - (x1 - {cx})^4 - (x2 - {cy})^2")
            };
            let c = contour(&text, 2);
            let center = [cx + 0.3, cy - 0.2, tc];
            let cc = CompiledContour::new(&c, &Frame::new(&center, &[4.0, 0.3, 1e-3 + tc.abs()]));
            let coeffs = vec![vec![cx + a[0], a[1], a[2] * 0.1], vec![cy + b[0], b[1]]];
            let piece = PieceRef { t0, t1: t0 + h, coeffs: &coeffs };
            let delta = BigRational::new(1.into(), 20.into());
            let exact = restrict_exact(&c, piece, &delta);
            let fast = cc.restrict(piece).unwrap();
            let (g1, g2) = fast.constraints(Interval::enclose_rational(&(BigRational::from_integer(1.into()) - &delta))).unwrap();
            prop_assert!(encloses(g1.coeffs(), &exact.cantelli).is_ok(), "{:?}", encloses(g1.coeffs(), &exact.cantelli));
            prop_assert!(encloses(g2.coeffs(), &exact.mean).is_ok(), "{:?}", encloses(g2.coeffs(), &exact.mean));
            // the f64 path with a running error bound encloses it too
            let omd = BigRational::from_integer(1.into()) - &delta;
            let f = riskplan_math::poly::rational_to_f64(&omd);
            let fe = BigRational::from_float(f).is_some_and(|e| e == omd);
            let subs = Substitution::new(piece, cc.frame()).unwrap();
            let checked = cc.with_constraints(&subs, (f, fe), |g2, g1| {
                encloses(g1, &exact.cantelli).and_then(|_| encloses(g2, &exact.mean))
            }).unwrap();
            prop_assert!(checked.is_ok(), "{:?}", checked);
        }
    }

    proptest! {
        /// Each substituted coefficient is within `k·u·a` of the exact one (the model
        /// [`EPoly`] builds on), for straight pieces (error-free transformations) and
        /// curved ones (exact rationals), far from the origin and at shifted times.
        #[test]
        fn substitution_coefficients_meet_their_error_model(
            c in prop::collection::vec(-1e3f64..1e3, 3), slope in -5f64..5.0, curve in -1f64..1.0,
            t0 in -50f64..50.0, h in 1e-3f64..10.0, center in prop::collection::vec(-1e3f64..1e3, 3),
        ) {
            let coeffs = vec![vec![c[0], slope], vec![c[1], slope * 0.3, curve]];
            let piece = PieceRef { t0, t1: t0 + h, coeffs: &coeffs };
            let sub = Substitution::new(piece, &Frame::centred(&center)).unwrap();
            let q = |v: f64| BigRational::from_float(v).unwrap();
            for d in 0..2 {
                let exact = riskplan_math::poly::UPoly::new(coeffs[d].iter().map(|&v| q(v)).collect())
                    .compose_affine(&q(t0), &(q(t0 + h) - q(t0)))
                    .sub(&riskplan_math::poly::UPoly::constant(q(center[d])));
                for k in 0..sub.len[d] {
                    let (v, a, r) = sub.coeffs[d][k];
                    let err = (q(v) - exact.coeff(k)).abs();
                    let bound = q(a * r as f64 * UNIT_ROUNDOFF * (1.0 + 1e-12) + 1e-300);
                    prop_assert!(err <= bound, "coordinate {d}, τ^{k}: error {} > bound {}", riskplan_math::poly::rational_to_f64(&err), riskplan_math::poly::rational_to_f64(&bound));
                }
            }
        }
    }

    /// An obstacle at scale `10^k` (lengths `x/S`, `S = 10^k`) and horizon `T`, and a piece
    /// through it: the three shapes of the extreme-scale tests — a superellipse (degree 8,
    /// E\[P²\] of degree 16), a disk, and a mixed degree-6 polynomial; static or moving, in
    /// 2-D or 3-D.
    fn extreme_case(k: i32, t: f64, dim: usize, shape: usize, moving: bool) -> RiskContour {
        let s = format!("1e{k}");
        let x = |i: usize| {
            if moving && i == 1 {
                format!("(x1/{s} - 0.2*t/{t:e})")
            } else {
                format!("(x{i}/{s})")
            }
        };
        let text = match shape {
            0 => format!("w + 0.5 - {}", (1..=dim).map(|i| format!("{}^8", x(i))).collect::<Vec<_>>().join(" - ")),
            1 => format!("w^2 - {}", (1..=dim).map(|i| format!("({} - 0.1)^2", x(i))).collect::<Vec<_>>().join(" - ")),
            _ => {
                format!("w*{x1}^3*{x2} - {x1}^6 - 0.5*{x2}^4 + 0.1*w - 0.25*{xl}^2", x1 = x(1), x2 = x(2), xl = x(dim))
            }
        };
        contour(&text, dim)
    }

    /// The fast path's enclosures (the `f64` running error bound, and the interval
    /// composition) hold the exact rational restriction (a different code path: no
    /// frame, general composition in rationals), or the fast path refuses. Scales
    /// 10⁻³⁰…10³⁰⁰, horizons 10⁻³…10⁶, degrees up to 8 (16 in E\[P²\]), 2-D and 3-D,
    /// moving obstacles, straight and curved pieces cut down to 2⁻⁴⁰ of the horizon
    /// (grazing), in three frames: the scene's (scaled to the workspace), a unit frame
    /// (the compiled numbers then reach 10^±4800: underflow and overflow everywhere),
    /// and one scaled wrongly by 2^±300.
    /// The exact composition, in rationals, of `p` (frame variables) with a straight
    /// piece `c0 + c1·t` per coordinate over [t0, t1] moved into `frame` — by general
    /// polynomial composition, not by the Horner trees under test.
    fn exact_in_frame(
        p: &QPoly,
        rows: &[[f64; 2]],
        t0: f64,
        t1: f64,
        frame: &Frame,
    ) -> riskplan_math::poly::UPoly<BigRational> {
        let q = |v: f64| BigRational::from_float(v).unwrap();
        let two = BigRational::from_integer(2.into());
        let scale = |e: i32| -> BigRational { num_traits::Pow::pow(&two, -e) };
        let (qt0, h) = (q(t0), q(t1) - q(t0));
        let lin = riskplan_math::poly::UPoly::new(vec![qt0.clone(), h.clone()]);
        let mut subs: Vec<riskplan_math::poly::UPoly<BigRational>> = rows
            .iter()
            .enumerate()
            .map(|(d, r)| {
                let x = riskplan_math::poly::UPoly::new(vec![q(r[0]), q(r[1])]);
                let x = riskplan_math::poly::UPoly::new(vec![x.coeff(0) + x.coeff(1) * &qt0, x.coeff(1) * &h]);
                x.sub(&riskplan_math::poly::UPoly::constant(q(frame.center[d]))).map(|c| c * scale(frame.exponents[d]))
            })
            .collect();
        let d = rows.len();
        subs.push(
            lin.sub(&riskplan_math::poly::UPoly::constant(q(frame.center[d]))).map(|c| c * scale(frame.exponents[d])),
        );
        p.compose_univariate(&subs)
    }

    proptest! {
        /// The `f64` mid-radius restriction of a polynomial with interval coefficients
        /// ([`Compiled::compose_r`]) encloses the exact restriction of every polynomial
        /// within those intervals: checked for the lower ends, the upper ends and a mix,
        /// against rational composition by a different code path.
        #[test]
        fn mid_radius_restriction_encloses_every_member(
            coeffs in prop::collection::vec((-3f64..3.0, 0f64..1e-3, 0u32..4, 0u32..4, 0u32..3), 1..12),
            rows in prop::collection::vec((-50f64..50.0, -20f64..20.0), 2),
            t0 in -5f64..5.0, h in 1e-3f64..4.0, cx in -40f64..40.0, scale in -3i32..3, pick in 0u32..3,
        ) {
            let frame = Frame::new(&[cx, -cx * 0.5, 0.25], &[2f64.powi(scale) * 20.0, 30.0, 3.0]);
            let mut p = Poly::<Interval>::zero();
            let mut members = vec![QPoly::zero(), QPoly::zero(), QPoly::zero()];
            for (k, &(m, r, e1, e2, e3)) in coeffs.iter().enumerate() {
                let mono = riskplan_math::poly::Monomial::from_pairs([(0, e1), (1, e2), (2, e3)].into_iter().filter(|x| x.1 > 0));
                let iv = Interval::new(m - r * m.abs(), m + r * m.abs());
                p.add_term(mono.clone(), iv);
                let q = |v: f64| BigRational::from_float(v).unwrap();
                let mix = if (k as u32 + pick) % 2 == 0 { iv.lo } else { iv.hi };
                for (member, v) in members.iter_mut().zip([iv.lo, iv.hi, mix]) {
                    member.add_term(mono.clone(), q(v));
                }
            }
            let compiled = Compiled::from_intervals(&p, 3);
            let rows: Vec<[f64; 2]> = rows.iter().map(|&(a, b)| [a, b]).collect();
            let coeff_rows: Vec<Vec<f64>> = rows.iter().map(|r| r.to_vec()).collect();
            let piece = PieceRef { t0, t1: t0 + h, coeffs: &coeff_rows };
            let Some(sub) = Substitution::new(piece, &frame) else { return Ok(()) };
            let subs = sub.epolys::<CAPACITY>().unwrap();
            let Some(enc) = compiled.compose_r(&subs[..sub.len()]) else { return Ok(()) };
            for member in &members {
                let exact = exact_in_frame(member, &rows, t0, t0 + h, &frame);
                prop_assert!(encloses(enc.coeffs(), &exact).is_ok(), "{:?}", encloses(enc.coeffs(), &exact));
            }
        }
    }

    proptest! {
        /// The error-free sign of c0 + c1·t − l equals the sign computed in rationals,
        /// also for bounds at, one ulp around, and a rounding away from the float value.
        #[test]
        fn straight_value_sign_is_exact(
            c0 in -1e6f64..1e6, c1 in -1e6f64..1e6, t in -1e3f64..1e3, k in 0u32..5, scale in -300i32..300,
        ) {
            let sc = 2f64.powi(scale);
            let (c0, c1) = (c0 * sc, c1 * sc);
            let v = c0 + c1 * t;
            let l = match k { 0 => v, 1 => v.next_up(), 2 => v.next_down(), 3 => c0, _ => v * 1.5 };
            let q = |x: f64| BigRational::from_float(x).unwrap();
            if let Some(sign) = straight_value_sign(c0, c1, t, l) {
                let exact = (q(c0) + q(c1) * q(t) - q(l)).cmp(&BigRational::from_integer(0.into()));
                prop_assert_eq!(sign, exact);
            }
        }
    }

    /// An interval straddling 0 with a midpoint below `RADIUS_FLOOR` and a far larger
    /// radius keeps its radius (it is not replaced by 0 ± 4·`RADIUS_FLOOR`).
    #[test]
    fn tiny_midpoint_with_a_wide_radius_is_enclosed() {
        let (lo, hi) = (-pow2(-860), pow2(-860) + pow2(-910));
        let iv = Interval::new(lo, hi);
        assert!(iv.mid() != 0.0 && iv.mid().abs() < RADIUS_FLOOR);
        let mut p = Poly::<Interval>::zero();
        p.add_term(riskplan_math::poly::Monomial::one(), iv);
        p.add_term(riskplan_math::poly::Monomial::var_pow(0, 1), Interval::point(1.0));
        let compiled = Compiled::from_intervals(&p, 3);
        let rows = vec![vec![0.0], vec![0.0]];
        let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &rows };
        let sub = Substitution::new(piece, &Frame::centred(&[0.0, 0.0, 0.0])).unwrap();
        let subs = sub.epolys::<CAPACITY>().unwrap();
        let c0 = compiled.compose_r(&subs[..sub.len()]).expect("the f64 path").coeffs()[0];
        let q = |v: f64| BigRational::from_float(v).unwrap();
        assert!(q(c0.lo) <= q(lo) && q(hi) <= q(c0.hi), "[{lo:e}, {hi:e}] not in {c0:?}");
    }

    proptest! {
        /// [`Compiled::compose_r`] at extreme scales and shapes of coefficient intervals
        /// (points, one ulp, straddling 0, midpoints from 2⁻¹⁰⁰⁰ to 2⁶⁰), straight and
        /// curved pieces, frame exponents ±200: every member's exact restriction is enclosed.
        #[test]
        fn mid_radius_restriction_encloses_members_at_extreme_scales(
            coeffs in prop::collection::vec((-3f64..3.0, -1000i32..60, 0usize..6, -60i32..1, 0u32..7, 0u32..7, 0u32..4, 0usize..3), 1..20),
            rows in prop::collection::vec((-3f64..3.0, -3f64..3.0, -1f64..1.0, 0usize..3, -200i32..200), 2),
            t0 in -5f64..5.0, lh in -30i32..3, cx in prop::collection::vec(-3f64..3.0, 3), big in 0i32..40,
            fe in prop::collection::vec(-200i32..200, 3),
        ) {
            let q = |v: f64| BigRational::from_float(v).unwrap();
            let mut p = Poly::<Interval>::zero();
            let mut members = vec![QPoly::zero(), QPoly::zero(), QPoly::zero()];
            for &(m, e, kind, re, e1, e2, e3, pick) in &coeffs {
                let mid = m * 2f64.powi(e);
                let r = 2f64.powi(re) * mid.abs();
                let iv = match kind {
                    0 => Interval::point(mid),
                    1 => Interval::new(mid - r, mid + r),
                    2 => Interval::new(-mid.abs() * 2.0, mid.abs() * 2.0 + r * 1e-3),
                    3 => Interval::new(mid, (mid + r).max(mid)),
                    4 => Interval::new(mid.min(mid.next_up()), mid.next_up()),
                    _ => Interval::new(-mid.abs(), mid.abs().next_up()),
                };
                if !(iv.lo.is_finite() && iv.hi.is_finite()) {
                    return Ok(());
                }
                let mono = riskplan_math::poly::Monomial::from_pairs([(0, e1), (1, e2), (2, e3)].into_iter().filter(|x| x.1 > 0));
                p.add_term(mono.clone(), iv);
                for (i, member) in members.iter_mut().enumerate() {
                    let v = match (i, pick) { (0, _) | (2, 0) => iv.lo, (1, _) | (2, 1) => iv.hi, _ => iv.mid().clamp(iv.lo, iv.hi) };
                    member.add_term(mono.clone(), q(v));
                }
            }
            let cx: Vec<f64> = cx
                .iter()
                .enumerate()
                .map(|(d, &c)| if d < 2 { rows[d].0 * 2f64.powi(rows[d].4) + c * 2f64.powi(rows[d].4 - big) } else { c })
                .collect();
            let frame = Frame { center: cx.clone(), exponents: fe.clone() };
            let compiled = Compiled::from_intervals(&p, 3);
            let t1 = t0 + 2f64.powi(lh);
            let rws: Vec<Vec<f64>> = rows
                .iter()
                .map(|&(a, b, c, deg, s)| {
                    let sc = 2f64.powi(s);
                    [a * sc, b * sc, c * sc][..=deg].to_vec()
                })
                .collect();
            let piece = PieceRef { t0, t1, coeffs: &rws };
            let Some(sub) = Substitution::new(piece, &frame) else { return Ok(()) };
            let Some(subs) = sub.epolys::<CAPACITY>() else { return Ok(()) };
            let Some(enc) = compiled.compose_r(&subs[..sub.len()]) else { return Ok(()) };
            let two = BigRational::from_integer(2.into());
            let exact_sub = |row: &[f64], c: f64, e: i32| {
                let sc: BigRational = num_traits::Pow::pow(&two, -e);
                riskplan_math::poly::UPoly::new(row.iter().map(|&v| q(v)).collect())
                    .compose_affine(&q(t0), &(q(t1) - q(t0)))
                    .sub(&riskplan_math::poly::UPoly::constant(q(c)))
                    .map(|x| x * &sc)
            };
            let mut esubs: Vec<riskplan_math::poly::UPoly<BigRational>> = (0..2).map(|d| exact_sub(&rws[d], cx[d], fe[d])).collect();
            esubs.push(exact_sub(&[0.0, 1.0], cx[2], fe[2]));
            for member in &members {
                let exact = member.compose_univariate(&esubs);
                prop_assert!(encloses(enc.coeffs(), &exact).is_ok(), "{:?}", encloses(enc.coeffs(), &exact));
            }
        }
    }

    mod extreme_scales {
        use super::*;

        proptest! {
            #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
            #[test]
            fn fast_path_encloses_the_exact_restriction_at_any_scale(
                k in -30i32..=300, tk in -3i32..=6, dim3 in any::<bool>(), moving in any::<bool>(),
                shape in 0usize..3, frame_kind in 0usize..4,
                p0 in prop::collection::vec(-0.95f64..0.95, 3), p1 in prop::collection::vec(-1.9f64..1.9, 3),
                curve in -0.5f64..0.5, cut in 0u32..=40, at in 0f64..1.0, delta_i in 0usize..3,
            ) {
                let dim = if dim3 { 3 } else { 2 };
                let (sc, t) = (10f64.powi(k), 10f64.powi(tk));
                let c = extreme_case(k, t, dim, shape, moving);
                let half: Vec<f64> = (0..dim).map(|_| 3.0 * sc).chain([t / 2.0]).collect();
                let mut center: Vec<f64> = vec![0.0; dim];
                center.push(t / 2.0);
                let frame = match frame_kind {
                    0 | 1 => Frame::new(&center, &half),
                    2 => Frame::centred(&center),
                    _ => Frame { center: center.clone(), exponents: vec![if k % 2 == 0 { 300 } else { -300 }; dim + 1] },
                };
                let cc = CompiledContour::new(&c, &frame);
                // x_d(t) = S·(p0 + p1·t/T [+ curve·(t/T)²]), cut to [t0, t0 + T·2^-cut]
                let coeffs: Vec<Vec<f64>> = (0..dim)
                    .map(|d| {
                        let mut row = vec![sc * p0[d], sc * p1[d] / t];
                        if d == 0 && frame_kind != 1 {
                            row.push(sc * curve / (t * t));
                        }
                        row
                    })
                    .collect();
                let len = t * 2f64.powi(-(cut as i32));
                let t0 = at * (t - len);
                let piece = PieceRef { t0, t1: t0 + len, coeffs: &coeffs };
                let delta = BigRational::new(1.into(), [10, 2, 1000][delta_i].into());
                let exact = restrict_exact(&c, piece, &delta);
                let omd = BigRational::from_integer(1.into()) - &delta;
                let f = riskplan_math::poly::rational_to_f64(&omd);
                let fe = BigRational::from_float(f).is_some_and(|e| e == omd);
                if let Some(subs) = Substitution::new(piece, cc.frame()) {
                    if let Some(checked) = cc.with_constraints(&subs, (f, fe), |g2, g1| {
                        encloses(g1, &exact.cantelli).and_then(|_| encloses(g2, &exact.mean))
                    }) {
                        prop_assert!(checked.is_ok(), "f64 path, scale 1e{k}, frame {frame_kind}: {:?}", checked);
                    }
                }
                if let Some(r) = cc.restrict(piece) {
                    if let Some((g1, g2)) = r.constraints(Interval::enclose_rational(&omd)) {
                        let checked = encloses(g1.coeffs(), &exact.cantelli).and_then(|_| encloses(g2.coeffs(), &exact.mean));
                        prop_assert!(checked.is_ok(), "interval path, scale 1e{k}, frame {frame_kind}: {:?}", checked);
                    }
                }
            }
        }

        /// The scene's frame keeps the `f64` path in use at every scale (the property
        /// above is not vacuous): the extreme-scale superellipse from 10⁻³⁰ to 10³⁰⁰, a
        /// straight piece through it, is computed (not refused) and enclosed.
        #[test]
        fn scene_frame_keeps_the_fast_path_at_every_scale() {
            for k in [-30, -5, 0, 18, 20, 21, 41, 100, 200, 300] {
                let sc = 10f64.powi(k);
                let c = extreme_case(k, 1.0, 2, 0, false);
                let cc = CompiledContour::new(&c, &Frame::new(&[0.0, 0.0, 0.5], &[3.0 * sc, 3.0 * sc, 0.5]));
                let coeffs = vec![vec![-2.9 * sc, 5.8 * sc], vec![1.05 * sc]];
                let piece = PieceRef { t0: 0.0, t1: 1.0, coeffs: &coeffs };
                let delta = BigRational::new(1.into(), 10.into());
                let exact = restrict_exact(&c, piece, &delta);
                let subs = Substitution::new(piece, cc.frame()).expect("substitution");
                let checked = cc
                    .with_constraints(&subs, (0.9, false), |g2, g1| {
                        encloses(g1, &exact.cantelli).and_then(|_| encloses(g2, &exact.mean))
                    })
                    .unwrap_or_else(|| panic!("scale 1e{k}: the fast path refused"));
                assert!(checked.is_ok(), "scale 1e{k}: {checked:?}");
            }
        }
    }

    /// Centring keeps the enclosures tight far from the origin: at x ≈ 1000 the
    /// uncentred restriction's coefficients are orders of magnitude wider.
    #[test]
    fn centring_keeps_enclosures_tight_far_from_the_origin() {
        let c = contour("w^2 - (x1 - 1000)^2 - (x2 + 500)^2", 2);
        let coeffs = vec![vec![999.0, 0.5], vec![-501.0, 0.25]];
        let piece = PieceRef { t0: 10.0, t1: 11.0, coeffs: &coeffs };
        let delta = BigRational::new(1.into(), 20.into());
        let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - &delta));
        let width = |p: &FPoly| p.coeffs().iter().map(|i| i.width()).fold(0.0, f64::max);
        let centred = CompiledContour::new(&c, &Frame::centred(&[1000.0, -500.0, 10.0])).restrict(piece).unwrap();
        let origin = CompiledContour::new(&c, &Frame::centred(&[0.0, 0.0, 0.0])).restrict(piece).unwrap();
        let (g_c, _) = centred.constraints(omd).unwrap();
        let (g_o, _) = origin.constraints(omd).unwrap();
        assert!(width(&g_c) < 1e-8, "{}", width(&g_c));
        assert!(width(&g_o) > 1e3 * width(&g_c), "{} vs {}", width(&g_o), width(&g_c));
    }

    #[test]
    fn box_evaluation_encloses_point_values_and_derivatives_are_exact() {
        let c = contour("w^2 - (x1 - t)^2 - x2^2", 2);
        let cc = Compiled::new(&c.mean, 3);
        let v = cc.eval_box(&[Interval::new(0.1, 0.2), Interval::new(-0.1, 0.3), Interval::new(0.0, 0.5)]);
        for &(x, y, t) in &[(0.1, -0.1, 0.0), (0.2, 0.3, 0.5), (0.15, 0.0, 0.25)] {
            let (m, _) = c.moments_f64(&[x, y, t]);
            assert!(v.lo <= m && m <= v.hi);
        }
        let d = derivative(&c.mean, 0); // ∂/∂x1 of E[w²] − (x1 − t)² − x2² = −2(x1 − t)
        let q = |v: i64| BigRational::from_integer(v.into());
        assert_eq!(d.eval(&[q(3), q(0), q(1), q(0)]), q(-4));
    }
}
