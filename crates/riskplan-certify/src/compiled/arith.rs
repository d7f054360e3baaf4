//! Fixed-capacity univariate polynomials on the stack: interval coefficients (`FPoly`), f64 with a running error bound (`EPoly`), and midpoint–radius (`RPoly`), each operation outward rounded (docs/design.md §5.10).

use super::*;

/// Capacity of an [`FPoly`]: the Bernstein checker's stack-buffer degree plus one.
/// A restriction of higher degree is not compiled ([`CompiledContour::restrict`] returns
/// `None`) and the caller falls back to the general path.
pub const CAPACITY: usize = MAX_DEGREE + 1;

/// A univariate polynomial in τ with interval coefficients, of degree < [`CAPACITY`],
/// stored inline (no heap).
#[derive(Clone, Copy, Debug)]
pub struct FPoly<const N: usize = CAPACITY> {
    pub(super) c: [Interval; N],
    pub(super) len: usize,
}

pub(super) const ZERO: Interval = Interval { lo: 0.0, hi: 0.0 };

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
pub(super) const UNIT_ROUNDOFF: f64 = 1.1102230246251565e-16;

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
pub(super) const FMA_FLOOR: f64 = pow2(-968);

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
    pub(super) v: [f64; N],
    pub(super) a: [f64; N],
    pub(super) len: usize,
    pub(super) k: u32,
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
    pub(super) fn add_assign_signed(&mut self, o: &EPoly<N>, sign: f64) {
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
    pub(super) fn mul_assign(&mut self, o: &EPoly<N>) -> Option<()> {
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
pub(super) const RADIUS_FLOOR: f64 = pow2(-900);

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
    pub(super) fn zero() -> Self {
        RPoly { v: [0.0; N], a: [0.0; N], r: [0.0; N], len: 0, k: 0 }
    }

    /// The constant `[lo, hi]`: its midpoint exactly and a radius rounded up (0 for a
    /// point). A nonzero radius below [`RADIUS_FLOOR`] is raised to it, and a midpoint
    /// below it becomes 0 with the radius grown by [`RADIUS_FLOOR`] (larger radii are sound; they
    /// keep the products of running values in the relative model). `None` when not finite.
    pub(super) fn interval(c: Interval) -> Option<Self> {
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
    pub(super) fn from_sub(s: &EPoly<N>) -> Self {
        RPoly { v: s.v, a: s.a, r: [0.0; N], len: s.len, k: s.k }
    }

    pub(super) fn add(&self, o: &RPoly<N>) -> RPoly<N> {
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
    pub(super) fn mul_sub(&self, s: &RPoly<N>) -> Option<RPoly<N>> {
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
    pub(super) fn enclosure(&self, out: &mut [Interval; N]) -> Option<usize> {
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
