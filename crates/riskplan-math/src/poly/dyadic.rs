//! Exact dyadic rationals m·2^e, the numbers every finite float is (docs/design.md §5.10).
//!
//! Sums and products of floats stay dyadic, so a polynomial in floats can be composed
//! exactly without the greatest common divisors a general rational pays on every
//! operation: a mantissa product or an aligned sum, nothing else. What
//! `riskplan_certify::compiled::Substitution` needs for curved pieces (the composition
//! x(t0 + h·s) − c, then each coefficient rounded once), where exact `BigRational`
//! arithmetic cost most of a blend's check on crowded scenes.

use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};

/// The exact number `m·2^e`. Equality is equality of the numbers (the same value
/// has many representations, e.g. 2·2^0 = 1·2^1), so it agrees with [`Ord`].
#[derive(Clone, Debug)]
pub struct Dyadic {
    m: BigInt,
    e: i64,
}

impl Dyadic {
    /// Zero.
    pub fn zero() -> Dyadic {
        Dyadic { m: BigInt::zero(), e: 0 }
    }

    /// The float `v` exactly; `None` when it is not finite.
    pub fn from_f64(v: f64) -> Option<Dyadic> {
        if !v.is_finite() {
            return None;
        }
        let bits = v.to_bits();
        let negative = bits >> 63 == 1;
        let biased = ((bits >> 52) & 0x7ff) as i64;
        let fraction = bits & ((1u64 << 52) - 1);
        // a subnormal (biased exponent 0) is fraction·2^−1074; a normal number has the
        // hidden bit
        let (m, e) = if biased == 0 { (fraction, -1074) } else { (fraction | (1u64 << 52), biased - 1075) };
        let m = BigInt::from(m);
        Some(Dyadic { m: if negative { -m } else { m }, e })
    }

    /// `self + o`, exactly.
    pub fn add(&self, o: &Dyadic) -> Dyadic {
        if self.m.is_zero() {
            return o.clone();
        }
        if o.m.is_zero() {
            return self.clone();
        }
        // both mantissas at the smaller exponent (a left shift is exact)
        let (lo, hi) = if self.e <= o.e { (self, o) } else { (o, self) };
        let shift = (hi.e - lo.e) as u64;
        Dyadic { m: &lo.m + (&hi.m << shift), e: lo.e }
    }

    /// `self − o`, exactly.
    pub fn sub(&self, o: &Dyadic) -> Dyadic {
        self.add(&o.neg())
    }

    /// `−self`.
    pub fn neg(&self) -> Dyadic {
        Dyadic { m: -&self.m, e: self.e }
    }

    /// `self·o`, exactly.
    pub fn mul(&self, o: &Dyadic) -> Dyadic {
        if self.m.is_zero() || o.m.is_zero() {
            return Dyadic::zero();
        }
        Dyadic { m: &self.m * &o.m, e: self.e + o.e }
    }

    /// The same number as a rational in lowest terms: the mantissa's factors of two moved
    /// into the exponent leave an odd numerator over a power of two (no division needed).
    pub fn to_rational(&self) -> BigRational {
        if self.m.is_zero() {
            return BigRational::zero();
        }
        let tz = self.m.trailing_zeros().unwrap_or(0);
        let m = &self.m >> tz; // exact: those bits are zero (an arithmetic shift keeps the sign)
        let e = self.e + tz as i64;
        if e >= 0 {
            BigRational::from_integer(m << e as u64)
        } else {
            // m odd, the denominator a power of two: already reduced
            BigRational::new_raw(m, BigInt::one() << (-e) as u64)
        }
    }

    /// Whether the number is negative.
    pub fn is_negative(&self) -> bool {
        self.m.is_negative()
    }
}

impl PartialEq for Dyadic {
    fn eq(&self, o: &Dyadic) -> bool {
        self.cmp(o) == std::cmp::Ordering::Equal
    }
}

impl Eq for Dyadic {}

impl PartialOrd for Dyadic {
    fn partial_cmp(&self, o: &Dyadic) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Dyadic {
    /// By the sign of the exact difference.
    fn cmp(&self, o: &Dyadic) -> std::cmp::Ordering {
        self.sub(o).m.sign().cmp(&num_bigint::Sign::NoSign)
    }
}

/// The coefficients in s of `Σ_k coeffs[k]·(t0 + (t1 − t0)·s)^k`, exactly (Horner in
/// polynomial arithmetic; `t1 − t0` is formed exactly too); `None` when an input is not
/// finite.
pub fn compose_affine(coeffs: &[f64], t0: f64, t1: f64) -> Option<Vec<Dyadic>> {
    let a = Dyadic::from_f64(t0)?;
    let b = Dyadic::from_f64(t1)?.sub(&a);
    let cs: Vec<Dyadic> = coeffs.iter().map(|&c| Dyadic::from_f64(c)).collect::<Option<_>>()?;
    let mut acc: Vec<Dyadic> = Vec::with_capacity(cs.len());
    for c in cs.iter().rev() {
        // acc ← acc·(a + b·s) + c
        let mut next = vec![Dyadic::zero(); acc.len() + 1];
        for (k, x) in acc.iter().enumerate() {
            next[k] = next[k].add(&x.mul(&a));
            next[k + 1] = next[k + 1].add(&x.mul(&b));
        }
        next[0] = next[0].add(c);
        acc = next;
    }
    Some(acc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::poly::UPoly;
    use proptest::prelude::*;

    fn q(v: f64) -> BigRational {
        BigRational::from_float(v).unwrap()
    }

    /// Floats of every kind: zero, subnormals, the extremes of the normal range and the
    /// middle, both signs.
    fn any_float() -> impl Strategy<Value = f64> {
        prop_oneof![
            Just(0.0),
            Just(-0.0),
            Just(f64::MIN_POSITIVE),
            Just(f64::MAX),
            Just(-f64::MAX),
            Just(5e-324),
            (1u64..(1u64 << 52)).prop_map(f64::from_bits),
            (-1.0e3f64..1.0e3),
            (-1.0f64..1.0, -1074i32..1023).prop_map(|(m, e)| m * 2f64.powi(e.clamp(-1022, 1023))),
        ]
    }

    #[test]
    fn floats_round_trip_exactly() {
        for v in [0.0, -0.0, 1.0, -2.5, 0.1, 5e-324, -5e-324, f64::MIN_POSITIVE, f64::MAX, -f64::MAX, 1e-310] {
            let d = Dyadic::from_f64(v).unwrap();
            assert_eq!(d.to_rational(), q(v), "{v:e}");
        }
        assert!(Dyadic::from_f64(f64::NAN).is_none());
        assert!(Dyadic::from_f64(f64::INFINITY).is_none());
    }

    /// Equal numbers in different representations are equal, and `==` agrees with
    /// `cmp` (a derived, field-wise `==` would call 2·2^0 and 1·2^1 different).
    #[test]
    fn equality_is_equality_of_numbers() {
        let a = Dyadic { m: BigInt::from(2), e: 0 };
        let b = Dyadic { m: BigInt::from(1), e: 1 };
        assert_eq!(a, b);
        assert_eq!(a.cmp(&b), std::cmp::Ordering::Equal);
        let c = Dyadic { m: BigInt::from(3), e: 0 };
        assert_ne!(a, c);
        assert_eq!(Dyadic::zero(), Dyadic { m: BigInt::zero(), e: -40 });
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Sums and products agree with `BigRational`'s, which shares no code with them.
        #[test]
        fn arithmetic_matches_big_rationals(x in any_float(), y in any_float()) {
            let (dx, dy) = (Dyadic::from_f64(x).unwrap(), Dyadic::from_f64(y).unwrap());
            prop_assert_eq!(dx.add(&dy).to_rational(), q(x) + q(y));
            prop_assert_eq!(dx.sub(&dy).to_rational(), q(x) - q(y));
            prop_assert_eq!(dx.mul(&dy).to_rational(), q(x) * q(y));
            prop_assert_eq!(dx.is_negative(), q(x) < BigRational::zero());
            prop_assert_eq!(dx.cmp(&dy), q(x).cmp(&q(y)));
        }

        /// The composition agrees with `UPoly<BigRational>::compose_affine` on pieces of
        /// degree 0 to 8 with coefficients and times of any scale.
        #[test]
        fn composition_matches_big_rationals(
            coeffs in proptest::collection::vec(any_float(), 0..=9),
            t0 in any_float(),
            t1 in any_float(),
        ) {
            let got = compose_affine(&coeffs, t0, t1).unwrap();
            let want = UPoly::new(coeffs.iter().map(|&c| q(c)).collect()).compose_affine(&q(t0), &(q(t1) - q(t0)));
            for k in 0..coeffs.len().max(1) {
                let g = got.get(k).map_or_else(BigRational::zero, Dyadic::to_rational);
                prop_assert_eq!(g, want.coeff(k), "coefficient {}", k);
            }
            for g in got.iter().skip(coeffs.len()) {
                prop_assert!(g.to_rational().is_zero());
            }
        }
    }
}
