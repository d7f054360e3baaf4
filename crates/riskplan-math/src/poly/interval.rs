//! Outward-rounded interval arithmetic on `f64`.
//!
//! Every operation computes the round-to-nearest result and then widens it by one
//! ulp in each direction (`next_down`/`next_up`). Round-to-nearest errs by at most
//! half an ulp, so the widened interval always contains the exact result of the
//! operation on any reals in the operands (docs/design.md §1.3, §5.3). This makes "all
//! lower bounds > 0" a proof of positivity, at a cost of a few ulps of width.
//!
//! Ends known to be exact are kept: a sum or difference below the least normal float in
//! magnitude, 0 included (with gradual underflow such a sum is representable), a product
//! end 0 whose zero products all have a zero factor, a halving that doubles back to its
//! input. Exact zeros then stay 0 instead of becoming the subnormal pair ±2⁻¹⁰⁷⁴, whose
//! later products each cost a microcode assist (the whole-path partition ran 1.7× slower).

use super::ring::{rational_to_f64, Ring};
use num_rational::BigRational;
use std::ops::{Add, Mul, Neg, Sub};

/// A closed interval `[lo, hi]` of reals. `lo <= hi`, or both NaN-free infinities.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

impl Interval {
    /// The whole real line: the result of any operation that produced NaN.
    pub const ENTIRE: Interval = Interval { lo: f64::NEG_INFINITY, hi: f64::INFINITY };

    /// The degenerate interval `[x, x]` (exact: `x` is a float).
    pub fn point(x: f64) -> Self {
        if x.is_nan() {
            Self::ENTIRE
        } else {
            Interval { lo: x, hi: x }
        }
    }

    /// `[lo, hi]`; NaN or inverted input gives [`Interval::ENTIRE`].
    pub fn new(lo: f64, hi: f64) -> Self {
        if lo.is_nan() || hi.is_nan() || lo > hi {
            Self::ENTIRE
        } else {
            Interval { lo, hi }
        }
    }

    /// The tightest float interval containing the rational `r`: a point when `r` is a
    /// float, otherwise the two floats around it.
    pub fn enclose_rational(r: &BigRational) -> Self {
        let f = rational_to_f64(r);
        if !f.is_finite() {
            return if f > 0.0 {
                Interval { lo: f64::MAX, hi: f64::INFINITY }
            } else {
                Interval { lo: f64::NEG_INFINITY, hi: f64::MIN }
            };
        }
        match super::ring::cmp_float_rational(f, r) {
            Some(std::cmp::Ordering::Equal) => Interval::point(f),
            Some(std::cmp::Ordering::Less) => Interval { lo: f, hi: f.next_up() },
            _ => Interval { lo: f.next_down(), hi: f },
        }
    }

    fn widen(lo: f64, hi: f64) -> Self {
        if lo.is_nan() || hi.is_nan() {
            return Self::ENTIRE;
        }
        Interval { lo: lo.next_down(), hi: hi.next_up() }
    }

    /// Midpoint (for reporting only).
    pub fn mid(&self) -> f64 {
        0.5 * self.lo + 0.5 * self.hi
    }

    /// Width `hi - lo` (rounded up).
    pub fn width(&self) -> f64 {
        (self.hi - self.lo).next_up()
    }

    /// Every point of the interval is `> 0`.
    pub fn is_positive(&self) -> bool {
        self.lo > 0.0
    }

    /// Every point of the interval is `< 0`.
    pub fn is_negative(&self) -> bool {
        self.hi < 0.0
    }

    /// Whether `x` lies in the interval.
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// The smallest interval containing both (exact: ends are compared, not computed).
    pub fn hull(self, o: Interval) -> Self {
        Interval { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }

    /// `x * 0.5`: kept when the halving is exact (it doubles back to its input: always
    /// for normal results, and for subnormals with a zero last bit), widened otherwise.
    /// (Checking the result's magnitude instead is not enough: the largest normal below
    /// 2⁻¹⁰²¹ halves to a tie that rounds up to exactly the least normal float.)
    pub fn half(self) -> Self {
        let lo = self.lo * 0.5;
        let hi = self.hi * 0.5;
        if lo * 2.0 == self.lo && hi * 2.0 == self.hi {
            Interval { lo, hi }
        } else {
            Self::widen(lo, hi)
        }
    }
}

impl Interval {
    /// Outward rounding of a float sum or difference: a result below the least normal
    /// float in magnitude (0 included) is exact — with gradual underflow the exact sum of
    /// two floats is then a multiple of 2⁻¹⁰⁷⁴ that is representable (Hauser 1996) — and is
    /// kept; any other is widened by an ulp. Keeps exact zeros (x − x, 0 + 0) free of the
    /// subnormal pair ±2⁻¹⁰⁷⁴, which would slow every later product by a microcode assist.
    fn widen_sum(lo: f64, hi: f64) -> Self {
        if lo.is_nan() || hi.is_nan() {
            return Self::ENTIRE;
        }
        let lo = if lo.abs() < f64::MIN_POSITIVE { lo } else { lo.next_down() };
        let hi = if hi.abs() < f64::MIN_POSITIVE { hi } else { hi.next_up() };
        Interval { lo, hi }
    }
}

impl Add for Interval {
    type Output = Interval;
    fn add(self, o: Interval) -> Interval {
        Interval::widen_sum(self.lo + o.lo, self.hi + o.hi)
    }
}

impl Sub for Interval {
    type Output = Interval;
    fn sub(self, o: Interval) -> Interval {
        Interval::widen_sum(self.lo - o.hi, self.hi - o.lo)
    }
}

impl Neg for Interval {
    type Output = Interval;
    fn neg(self) -> Interval {
        Interval { lo: -self.hi, hi: -self.lo }
    }
}

impl Mul for Interval {
    type Output = Interval;
    fn mul(self, o: Interval) -> Interval {
        // Points: one product, exact sign handling; common in compositions.
        if self.lo == self.hi && o.lo == o.hi {
            let p = self.lo * o.lo;
            if p == 0.0 && (self.lo == 0.0 || o.lo == 0.0) {
                return Interval::point(0.0);
            }
            return if p.is_nan() { Interval::ENTIRE } else { Interval::widen(p, p) };
        }
        let a = self.lo * o.lo;
        let b = self.lo * o.hi;
        let c = self.hi * o.lo;
        let d = self.hi * o.hi;
        if a.is_nan() || b.is_nan() || c.is_nan() || d.is_nan() {
            return Interval::ENTIRE;
        }
        let (lo, hi) = (a.min(b).min(c.min(d)), a.max(b).max(c.max(d)));
        // An end that is 0 stays 0 when every product equal to 0 has a zero factor (all
        // four are then exact or of the end's strict sign); a product that underflowed to
        // 0 from nonzero factors widens it as any other.
        let exact_zeros = || {
            let ok = |p: f64, x: f64, y: f64| p != 0.0 || x == 0.0 || y == 0.0;
            ok(a, self.lo, o.lo) && ok(b, self.lo, o.hi) && ok(c, self.hi, o.lo) && ok(d, self.hi, o.hi)
        };
        let lo = if lo == 0.0 && exact_zeros() { 0.0 } else { lo.next_down() };
        let hi = if hi == 0.0 && exact_zeros() { 0.0 } else { hi.next_up() };
        Interval { lo, hi }
    }
}

/// Intervals as a coefficient ring (docs/design.md §5.3): every operation outward-rounded.
impl Ring for Interval {
    fn zero() -> Self {
        Interval::point(0.0)
    }
    fn one() -> Self {
        Interval::point(1.0)
    }
    fn is_zero(&self) -> bool {
        self.lo == 0.0 && self.hi == 0.0
    }
    fn radd(&self, o: &Self) -> Self {
        *self + *o
    }
    fn rsub(&self, o: &Self) -> Self {
        *self - *o
    }
    fn rmul(&self, o: &Self) -> Self {
        *self * *o
    }
    fn rneg(&self) -> Self {
        -*self
    }
    fn from_rational(r: &BigRational) -> Self {
        Interval::enclose_rational(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_traits::FromPrimitive;
    use proptest::prelude::*;

    fn exact(x: f64) -> BigRational {
        BigRational::from_f64(x).unwrap()
    }

    #[test]
    fn encloses_tenth() {
        let tenth = BigRational::new(1.into(), 10.into());
        let i = Interval::enclose_rational(&tenth);
        assert!(exact(i.lo) < tenth && tenth < exact(i.hi));
        assert_eq!(Interval::enclose_rational(&BigRational::new(1.into(), 4.into())), Interval::point(0.25));
    }

    proptest! {
        /// The exact result of each operation on the exact endpoints lies inside.
        #[test]
        fn operations_enclose_exact(a in -1e6f64..1e6, b in -1e6f64..1e6, c in -1e3f64..1e3, d in -1e3f64..1e3) {
            let x = Interval::new(a.min(b), a.max(b));
            let y = Interval::new(c.min(d), c.max(d));
            for (u, v) in [(x.lo, y.lo), (x.hi, y.hi), (x.lo, y.hi)] {
                let (eu, ev) = (exact(u), exact(v));
                let s = x + y; prop_assert!(exact(s.lo) <= &eu + &ev && &eu + &ev <= exact(s.hi));
                let dd = x - y; prop_assert!(exact(dd.lo) <= &eu - &ev && &eu - &ev <= exact(dd.hi));
                let m = x * y; prop_assert!(exact(m.lo) <= &eu * &ev && &eu * &ev <= exact(m.hi));
            }
        }

        /// The same at the edges of the float range, where ends are kept unwidened (exact
        /// zeros, sums below the least normal float): zeros of both signs, subnormals,
        /// tiny and huge values; every product and sum of endpoint pairs checked exactly.
        #[test]
        fn unwidened_ends_are_exact(v in proptest::collection::vec(prop_oneof![
            Just(0.0f64), Just(-0.0f64),
            (-1_000_000i64..1_000_000).prop_map(|k| k as f64 * f64::from_bits(1)),
            -1e-300f64..1e-300, -1e-154f64..1e-154, -1e3f64..1e3, -1e300f64..1e300,
        ], 4)) {
            let x = Interval::new(v[0].min(v[1]), v[0].max(v[1]));
            let y = Interval::new(v[2].min(v[3]), v[2].max(v[3]));
            let (s, dd, m, hx) = (x + y, x - y, x * y, x.half());
            // r inside i, an infinite end enclosing everything beyond the float range
            let inside = |i: Interval, r: &BigRational| {
                (i.lo == f64::NEG_INFINITY || exact(i.lo) <= *r) && (i.hi == f64::INFINITY || *r <= exact(i.hi))
            };
            for u in [x.lo, x.hi] {
                for w in [y.lo, y.hi] {
                    let (eu, ew) = (exact(u), exact(w));
                    prop_assert!(inside(s, &(&eu + &ew)), "{x:?} + {y:?} = {s:?}");
                    prop_assert!(inside(dd, &(&eu - &ew)), "{x:?} - {y:?} = {dd:?}");
                    prop_assert!(inside(m, &(&eu * &ew)), "{x:?} * {y:?} = {m:?}");
                    prop_assert!(inside(hx, &(&eu / BigRational::from_integer(2.into()))), "{x:?} / 2 = {hx:?}");
                }
            }
        }
    }

    #[test]
    fn exact_zeros_stay_zero() {
        let z = Interval::point(0.0);
        let x = Interval::new(-2.0, 3.0);
        assert_eq!(z + z, z);
        assert_eq!(x - x, Interval::new((-5.0f64).next_down(), 5.0f64.next_up()));
        assert_eq!(Interval::point(1.5) - Interval::point(1.5), z);
        assert_eq!(Interval::new(0.0, 2.0) * Interval::new(0.0, 3.0), Interval::new(0.0, 6.0f64.next_up()));
        assert_eq!(z * z, z);
        // a product that underflows to 0 from nonzero factors is widened
        let tiny = Interval::point(1e-200);
        let p = tiny * tiny;
        assert!(p.lo < 0.0 && p.hi > 0.0);
        let q = Interval::new(0.0, 1e-200) * Interval::new(-1e-200, 0.0);
        assert!(q.lo < 0.0 && q.hi >= 0.0, "{q:?}");
        // halving: the largest normal below 2^-1021 halves to a tie rounded up to the least
        // normal (helper-19's case); the result must still contain the exact half
        let x = f64::from_bits(0x001f_ffff_ffff_ffff);
        let h = Interval::point(x).half();
        assert!(h.lo < f64::MIN_POSITIVE && h.hi >= f64::MIN_POSITIVE, "{h:?}");
        let h = Interval::point(-x).half();
        assert!(h.hi > -f64::MIN_POSITIVE, "{h:?}");
        assert_eq!(Interval::new(-3.0, 1.0).half(), Interval::new(-1.5, 0.5));
    }
}
