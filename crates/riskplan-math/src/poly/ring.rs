//! The coefficient rings polynomials are generic over.
//!
//! Three rings matter to riskplan: exact rationals ([`BigRational`]) for the
//! contour polynomials E\[P\], E\[P²\] (docs/design.md §1.4: exact arithmetic makes
//! certification reproducible), `f64` for plotting and sampling, and
//! outward-rounded [`Interval`](super::Interval)s (their ring instance beside the type) for fast *sound* certification (§5.3).

use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{One, Signed, ToPrimitive, Zero};
use std::fmt::Debug;

/// A commutative ring with the operations polynomial arithmetic needs.
///
/// Method names carry an `r` prefix so they never collide with `std::ops`.
pub trait Ring: Clone + PartialEq + Debug + Send + Sync + 'static {
    /// Additive identity.
    fn zero() -> Self;
    /// Multiplicative identity.
    fn one() -> Self;
    /// Exactly zero (terms with a zero coefficient are dropped).
    fn is_zero(&self) -> bool;
    /// `self + o`.
    fn radd(&self, o: &Self) -> Self;
    /// `self - o`.
    fn rsub(&self, o: &Self) -> Self;
    /// `self * o`.
    fn rmul(&self, o: &Self) -> Self;
    /// `-self`.
    fn rneg(&self) -> Self;
    /// The ring element enclosing (or equal to) an exact rational.
    fn from_rational(r: &BigRational) -> Self;
    /// `self^k` by repeated squaring.
    fn rpow(&self, mut k: u32) -> Self {
        let mut base = self.clone();
        let mut acc = Self::one();
        while k > 0 {
            if k & 1 == 1 {
                acc = acc.rmul(&base);
            }
            k >>= 1;
            if k > 0 {
                base = base.rmul(&base);
            }
        }
        acc
    }
}

impl Ring for BigRational {
    fn zero() -> Self {
        Zero::zero()
    }
    fn one() -> Self {
        One::one()
    }
    fn is_zero(&self) -> bool {
        Zero::is_zero(self)
    }
    fn radd(&self, o: &Self) -> Self {
        self + o
    }
    fn rsub(&self, o: &Self) -> Self {
        self - o
    }
    fn rmul(&self, o: &Self) -> Self {
        self * o
    }
    fn rneg(&self) -> Self {
        -self
    }
    fn from_rational(r: &BigRational) -> Self {
        r.clone()
    }
}

impl Ring for f64 {
    fn zero() -> Self {
        0.0
    }
    fn one() -> Self {
        1.0
    }
    fn is_zero(&self) -> bool {
        *self == 0.0
    }
    fn radd(&self, o: &Self) -> Self {
        self + o
    }
    fn rsub(&self, o: &Self) -> Self {
        self - o
    }
    fn rmul(&self, o: &Self) -> Self {
        self * o
    }
    fn rneg(&self) -> Self {
        -self
    }
    fn from_rational(r: &BigRational) -> Self {
        rational_to_f64(r)
    }
}

/// The `f64` nearest to `r` (±∞ when out of range).
pub fn rational_to_f64(r: &BigRational) -> f64 {
    match r.to_f64() {
        Some(f) => f,
        None => {
            if r.is_negative() {
                f64::NEG_INFINITY
            } else {
                f64::INFINITY
            }
        }
    }
}

/// The order of the finite float `v` against the rational `q` (`v.cmp(q)`), exactly, in
/// integers: `v = m·2^e`, `q = n/d` with `d > 0`, so `v ⋚ q ⟺ m·2^e·d ⋚ n` (the power of
/// two moved to the side where it is an integer). No gcd: converting a rational to its
/// enclosure this way costs a few integer products instead of the reduced rational
/// arithmetic of `BigRational::from_float(v) == q`. `None` for a NaN or infinite `v`.
pub fn cmp_float_rational(v: f64, q: &BigRational) -> Option<std::cmp::Ordering> {
    let (m, e) = float_parts(v)?;
    let (n, d) = (q.numer(), q.denom());
    Some(if e >= 0 { ((m * d) << e as usize).cmp(n) } else { (m * d).cmp(&(n << (-e) as usize)) })
}

/// Whether the float `v` is within one relative rounding of the nonzero rational `q`:
/// `|v − q|·2^53 ≤ |q|`, exactly, in integers (as [`cmp_float_rational`]).
pub fn float_within_rounding(v: f64, q: &BigRational) -> bool {
    let Some((m, e)) = float_parts(v) else { return false };
    let (n, d) = (q.numer(), q.denom());
    // |m·2^e·d − n|·2^53 ≤ |n|, both sides times 2^(−e) when e < 0
    let (lhs, rhs) = if e >= 0 { ((m * d) << e as usize, n.clone()) } else { (m * d, n << (-e) as usize) };
    ((lhs - &rhs).abs() << 53usize) <= rhs.abs()
}

/// `v = m·2^e` exactly, for a finite float (`m` a signed integer of at most 53 bits).
fn float_parts(v: f64) -> Option<(BigInt, i64)> {
    if !v.is_finite() {
        return None;
    }
    if v == 0.0 {
        return Some((BigInt::zero(), 0));
    }
    let bits = v.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i64;
    let frac = bits & ((1u64 << 52) - 1);
    // subnormals: exponent field 0, no implicit bit, scale 2^(−1074)
    let (mant, e) = if exp == 0 { (frac, -1074) } else { (frac | (1u64 << 52), exp - 1075) };
    let m = BigInt::from(mant);
    Some((if v < 0.0 { -m } else { m }, e))
}

/// The exact rational value of a finite `f64` (every finite float is a dyadic rational).
/// Returns `None` for NaN and ±∞.
pub fn f64_to_rational(f: f64) -> Option<BigRational> {
    BigRational::from_float(f)
}

/// Largest decimal exponent magnitude [`parse_decimal`] accepts: every finite `f64`
/// (|exponent| ≤ 324) fits, and nothing larger is a physical quantity. A bound, because
/// `1e4000` read exactly is a 4000-digit integer that every later exact operation
/// (moments, contours) pays for.
pub const MAX_DECIMAL_EXPONENT: u64 = 400;

/// Most digits (integer and fraction part together) [`parse_decimal`] accepts: far
/// more than any measured quantity carries, few enough that exact arithmetic on them
/// stays cheap.
pub const MAX_DECIMAL_DIGITS: usize = 400;

/// Parses decimal text exactly: `"0.3"` is 3/10, `"1e-3"` is 1/1000, `"-2.5E2"` is -250.
///
/// Returns `None` when the text is not a decimal number, or when it has more than
/// [`MAX_DECIMAL_DIGITS`] digits or an exponent beyond ±[`MAX_DECIMAL_EXPONENT`]. This is the policy of
/// docs/design.md §1.4: scene numbers are exact rationals, not binary floats.
pub fn parse_decimal(s: &str) -> Option<BigRational> {
    let s = s.trim();
    let (neg, body) = match s.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, s.strip_prefix('+').unwrap_or(s)),
    };
    let (mantissa, exp) = match body.find(['e', 'E']) {
        Some(i) => {
            let e: i64 = body[i + 1..].parse().ok()?;
            (&body[..i], e)
        }
        None => (body, 0),
    };
    let (int_part, frac_part) = match mantissa.find('.') {
        Some(i) => (&mantissa[..i], &mantissa[i + 1..]),
        None => (mantissa, ""),
    };
    if int_part.is_empty() && frac_part.is_empty() {
        return None;
    }
    if !int_part.bytes().all(|b| b.is_ascii_digit()) || !frac_part.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    // Sizes that cannot come from a sensible scene: refuse rather than allocate.
    if exp.unsigned_abs() > MAX_DECIMAL_EXPONENT || int_part.len() + frac_part.len() > MAX_DECIMAL_DIGITS {
        return None;
    }
    let digits = format!("{int_part}{frac_part}");
    let numer: BigInt = if digits.is_empty() { BigInt::zero() } else { digits.parse().ok()? };
    let scale = exp - frac_part.len() as i64;
    let ten = BigInt::from(10u32);
    let value = if scale >= 0 {
        BigRational::from_integer(numer * num_traits::pow(ten, scale as usize))
    } else {
        BigRational::new(numer, num_traits::pow(ten, (-scale) as usize))
    };
    Some(if neg { -value } else { value })
}

/// Parses `"p/q"` or decimal text exactly.
pub fn parse_num_text(s: &str) -> Option<BigRational> {
    match s.split_once('/') {
        Some((a, b)) => {
            let (a, b) = (parse_decimal(a)?, parse_decimal(b)?);
            if num_traits::Zero::is_zero(&b) {
                None
            } else {
                Some(a / b)
            }
        }
        None => parse_decimal(s),
    }
}

/// Exact rational from a JSON `f64`: the shortest decimal that round-trips to `f`
/// (what `{}` prints), read exactly. For a number written in a scene as `0.3`, this is
/// 3/10, the value the author meant, rather than the binary float nearest to it.
pub fn f64_shortest_decimal(f: f64) -> Option<BigRational> {
    if !f.is_finite() {
        return None;
    }
    parse_decimal(&format!("{f:e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(n: i64, d: i64) -> BigRational {
        BigRational::new(n.into(), d.into())
    }

    use proptest::prelude::*;

    /// Rationals of any scale: n/d · 10^k, k from −330 to 330 (subnormal to overflow).
    fn rational() -> impl Strategy<Value = BigRational> {
        (-1_000_000_000i64..1_000_000_000, 1i64..1_000_000_000, -330i32..330).prop_map(|(n, d, k)| {
            let ten = BigRational::from_integer(10.into());
            q(n, d) * num_traits::Pow::pow(&ten, k)
        })
    }

    proptest! {
        /// The integer comparisons agree with reduced rational arithmetic (the oracle) at
        /// the nearest float and its neighbours, subnormals and zero included.
        #[test]
        fn float_rational_comparisons_agree_with_rationals(r in rational(), step in 0usize..3) {
            let mut v = rational_to_f64(&r);
            for _ in 0..step {
                v = v.next_up();
            }
            let exact = BigRational::from_float(v);
            prop_assert_eq!(cmp_float_rational(v, &r), exact.as_ref().map(|e| e.cmp(&r)));
            if let (Some(e), false) = (exact, Zero::is_zero(&r)) {
                let within = (&e - &r).abs() * BigRational::from_integer((1u64 << 53).into()) <= r.abs();
                prop_assert_eq!(float_within_rounding(v, &r), within);
            }
        }
    }

    #[test]
    fn float_rational_comparisons_at_the_edges() {
        assert_eq!(cmp_float_rational(0.0, &q(0, 1)), Some(std::cmp::Ordering::Equal));
        assert_eq!(cmp_float_rational(-0.0, &q(1, 3)), Some(std::cmp::Ordering::Less));
        let tiny = BigRational::from_float(f64::from_bits(1)).unwrap();
        assert_eq!(cmp_float_rational(f64::from_bits(1), &tiny), Some(std::cmp::Ordering::Equal));
        assert_eq!(
            cmp_float_rational(f64::MAX, &BigRational::from_float(f64::MAX).unwrap()),
            Some(std::cmp::Ordering::Equal)
        );
        assert_eq!(cmp_float_rational(f64::INFINITY, &q(1, 1)), None);
        assert!(float_within_rounding(0.1, &q(1, 10)));
        assert!(!float_within_rounding(0.1f64.next_up().next_up(), &q(1, 10)));
    }

    #[test]
    fn decimals_are_exact() {
        assert_eq!(parse_decimal("0.3"), Some(q(3, 10)));
        assert_eq!(parse_decimal("1e-3"), Some(q(1, 1000)));
        assert_eq!(parse_decimal("-2.5E2"), Some(q(-250, 1)));
        assert_eq!(parse_decimal(".5"), Some(q(1, 2)));
        assert_eq!(parse_decimal("5."), Some(q(5, 1)));
        assert_eq!(parse_decimal("abc"), None);
        assert_eq!(parse_decimal("."), None);
        assert_eq!(parse_decimal("1e99999"), None);
        assert_eq!(f64_shortest_decimal(0.3), Some(q(3, 10)));
        assert_eq!(f64_shortest_decimal(-0.0316), Some(q(-316, 10000)));
    }

    #[test]
    fn rpow_matches_repeated_product() {
        let x = q(3, 2);
        assert_eq!(x.rpow(0), q(1, 1));
        assert_eq!(x.rpow(5), q(243, 32));
        assert_eq!(2.0f64.rpow(10), 1024.0);
    }
}
