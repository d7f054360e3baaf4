//! Seeded random univariate polynomials for testing and benchmarking riskplan's
//! positivity checkers (docs/design.md §5.8, generator 1). Not part of the stable API.
//!
//! Each [`Case`] is built in a time variable `t` on a random interval `[t1, t2]` as
//!
//! ```text
//! p0(t) = s · c · Π (t − r_i)^(m_i) · Π ((t − u_j)² + v_j²),    p(t) = p0(t) + ε
//! ```
//!
//! with rational roots `r_i` inside and outside `[t1, t2]` (double roots included,
//! sometimes exactly at an end), a positive constant `c`, positive quadratic factors,
//! a sign `s` and a perturbation `ε ∈ {0, ±10^-k·S}` (`k = 1..12`, `S` the size of the
//! coefficients), and then composed with `t = t1 + (t2 − t1)·τ` by
//! [`UPoly::compose_affine`], so the question is again `p > 0` for τ in [0, 1] (§5.1).
//! "Tangent" cases put only even-multiplicity roots inside with `p0 ≥ 0`, so that
//! `±ε` makes them barely positive or barely negative.
//!
//! Where the construction alone proves the answer, [`Case::truth`] records it, which
//! checks the exact oracle itself.

use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use riskplan_math::poly::{Interval, UPoly};

/// Smallest and largest generated degree.
pub const DEGREES: std::ops::RangeInclusive<usize> = 1..=10;

/// Perturbation exponents: `ε = ±10^-k · S` for `k` in this range.
pub const PERTURBATION_EXPONENTS: std::ops::RangeInclusive<u32> = 1..=12;

/// What the construction proves about `p > 0` on [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Truth {
    /// `p > 0` on [0, 1].
    Positive,
    /// `p ≤ 0` somewhere in [0, 1].
    NotPositive,
    /// Not known from the construction (an exact oracle must decide).
    Unknown,
}

/// One generated polynomial, restricted to [0, 1].
#[derive(Clone, Debug)]
pub struct Case {
    /// `p(t1 + (t2 − t1)τ)`, exact: `original.compose_affine(t1, t2 − t1)`.
    pub exact: UPoly<BigRational>,
    /// The coefficient-wise tightest float enclosure of `exact`.
    pub interval: UPoly<Interval>,
    /// What the construction proves.
    pub truth: Truth,
    /// `p(t)` before the domain `[t1, t2]` is mapped to [0, 1].
    pub original: UPoly<BigRational>,
    /// The time interval `[t1, t2]` mapped to [0, 1].
    pub domain: (BigRational, BigRational),
    /// How it was built (for failure messages).
    pub recipe: String,
}

/// A seeded stream of [`Case`]s (ChaCha8, reproducible across platforms).
pub struct Generator {
    rng: ChaCha8Rng,
}

/// Denominators of generated rationals: dyadic and not, small enough that exact
/// arithmetic stays fast.
const DENOMINATORS: [i64; 12] = [1, 2, 3, 4, 5, 7, 8, 10, 16, 20, 25, 100];

/// A polynomial `Σ c_i t^i / den` with integer coefficients (`den > 0`). The generator
/// works in this form because `BigRational` reduces (a gcd) after every operation,
/// which made generation slower than the checkers under test; tests use it for the
/// same reason to evaluate exactly.
#[derive(Clone, Debug)]
pub struct IntPoly {
    c: Vec<BigInt>,
    den: BigInt,
}

impl IntPoly {
    /// The same polynomial over the common denominator of its coefficients.
    pub fn from_upoly(p: &UPoly<BigRational>) -> Self {
        let den = p.coeffs().iter().fold(BigInt::one(), |l, x| l.lcm(x.denom()));
        let c = p.coeffs().iter().map(|x| x.numer() * (&den / x.denom())).collect();
        IntPoly { c, den }
    }

    /// The value at `x`, exactly (one reduction).
    pub fn at(&self, x: &BigRational) -> BigRational {
        let deg = self.c.len().saturating_sub(1);
        let d_deg = num_traits::pow(x.denom().clone(), deg);
        BigRational::new(self.homogenised(x), &self.den * d_deg)
    }

    /// The sign of the value at `x` (no reduction at all).
    pub fn sign_at(&self, x: &BigRational) -> std::cmp::Ordering {
        self.homogenised(x).sign().cmp(&num_bigint::Sign::NoSign)
    }

    /// `Σ c_i n^i d^(deg−i)` for `x = n/d`, `d > 0`: `d^deg · den` times the value.
    fn homogenised(&self, x: &BigRational) -> BigInt {
        let (n, d) = (x.numer(), x.denom());
        let mut acc = BigInt::zero();
        let mut dpow = BigInt::one();
        for c in self.c.iter().rev() {
            acc = acc * n + c * &dpow;
            dpow *= d;
        }
        acc
    }

    fn constant(r: &BigRational) -> Self {
        IntPoly { c: vec![r.numer().clone()], den: r.denom().clone() }
    }

    /// `self · (Σ f_i t^i) / f_den`.
    fn mul(&self, f: &[BigInt], f_den: &BigInt) -> Self {
        let mut c = vec![BigInt::zero(); self.c.len() + f.len() - 1];
        for (i, a) in self.c.iter().enumerate() {
            for (j, b) in f.iter().enumerate() {
                c[i + j] += a * b;
            }
        }
        IntPoly { c, den: &self.den * f_den }
    }

    /// `(t − r)^m`, times `den(r)^m` to stay integral.
    fn mul_root(&self, r: &BigRational, m: u32) -> Self {
        let f = [-r.numer().clone(), r.denom().clone()];
        (0..m).fold(self.clone(), |acc, _| acc.mul(&f, r.denom()))
    }

    /// `(t − u)² + v²`, as `((bd·t − ad)² + (cb)²) / (bd)²` for `u = a/b`, `v = c/d`.
    fn mul_quadratic(&self, u: &BigRational, v: &BigRational) -> Self {
        let bd = u.denom() * v.denom();
        let ad = u.numer() * v.denom();
        let cb = v.numer() * u.denom();
        let f = [&ad * &ad + &cb * &cb, BigInt::from(-2) * &ad * &bd, &bd * &bd];
        self.mul(&f, &(&bd * &bd))
    }

    fn neg(&self) -> Self {
        IntPoly { c: self.c.iter().map(|x| -x).collect(), den: self.den.clone() }
    }

    /// `self + e` for a rational constant `e`.
    fn add_constant(&self, e: &BigRational) -> Self {
        let (en, ed) = (e.numer(), e.denom());
        let mut c: Vec<BigInt> = self.c.iter().map(|x| x * ed).collect();
        c[0] += en * &self.den;
        IntPoly { c, den: &self.den * ed }
    }

    /// `self(t1 + w·τ)`: with `t1 = A/L`, `w = C/L`, `L^deg · self((A + Cτ)/L)` is the
    /// integer polynomial `Σ c_i (A + Cτ)^i L^(deg−i)`, built by Horner.
    fn compose_affine(&self, t1: &BigRational, w: &BigRational) -> Self {
        let l = t1.denom().lcm(w.denom());
        let a = t1.numer() * (&l / t1.denom());
        let cw = w.numer() * (&l / w.denom());
        let deg = self.c.len() - 1;
        let mut acc: Vec<BigInt> = vec![self.c[deg].clone()];
        let mut lpow = BigInt::one();
        for ci in self.c.iter().rev().skip(1) {
            lpow *= &l;
            let mut next = vec![BigInt::zero(); acc.len() + 1];
            for (k, x) in acc.iter().enumerate() {
                next[k] += x * &a;
                next[k + 1] += x * &cw;
            }
            next[0] += ci * &lpow;
            acc = next;
        }
        IntPoly { c: acc, den: &self.den * lpow }
    }

    fn to_upoly(&self) -> UPoly<BigRational> {
        UPoly::new(self.c.iter().map(|x| BigRational::new(x.clone(), self.den.clone())).collect())
    }

    /// `max |c_i| / den` as an f64.
    fn size(&self) -> f64 {
        let big = self.c.iter().map(|x| x.abs()).max().unwrap_or_default();
        riskplan_math::poly::rational_to_f64(&BigRational::new(big, self.den.clone()))
    }
}

impl Generator {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Self {
        Generator { rng: ChaCha8Rng::seed_from_u64(seed) }
    }

    /// A case of random degree in [`DEGREES`].
    pub fn case(&mut self) -> Case {
        let deg = self.rng.random_range(DEGREES);
        self.case_of_degree(deg)
    }

    /// A case of degree exactly `deg` (≥ 1).
    pub fn case_of_degree(&mut self, deg: usize) -> Case {
        let deg = deg.max(1);
        let (t1, t2) = self.domain();
        let tangent = self.rng.random_bool(0.35);
        let mut recipe = format!("deg {deg} on [{t1}, {t2}]{}", if tangent { " tangent" } else { "" });
        let c = self.rational(1, 50).abs() + BigRational::new(1.into(), 10.into());
        recipe += &format!(": {c}");
        let mut p0 = IntPoly::constant(&c);
        let mut inside: Vec<(BigRational, u32)> = Vec::new();
        let mut left = deg;
        while left > 0 {
            if left >= 2 && self.rng.random_bool(0.2) {
                let u = self.rational(-3, 3);
                let v = self.nonzero_rational();
                recipe += &format!(" · ((t − {u})² + ({v})²)");
                p0 = p0.mul_quadratic(&u, &v);
                left -= 2;
                continue;
            }
            let in_domain = self.rng.random_bool(0.6);
            let mut mult = [1u32, 1, 2, 2, 2, 3, 4][self.rng.random_range(0..7)];
            if tangent && in_domain && mult % 2 == 1 {
                mult += 1;
            }
            let mult = mult.min(left as u32);
            let r = if tangent && in_domain && mult % 2 == 1 {
                // no room for an even root: put it outside
                &t2 + BigRational::one() + self.rational(0, 2).abs()
            } else if in_domain {
                self.point_in(&t1, &t2)
            } else {
                self.point_outside(&t1, &t2)
            };
            recipe += &format!(" · (t − {r})^{mult}");
            p0 = p0.mul_root(&r, mult);
            if r >= t1 && r <= t2 {
                inside.push((r, mult));
            }
            left -= mult as usize;
        }
        let nonneg = inside.iter().all(|(_, m)| m % 2 == 0);
        let probe = probe_point(&p0, &t1, &t2);
        // sign: tangent cases are made p0 ≥ 0 on the domain, others are random
        let negative_at_probe = p0.sign_at(&probe).is_lt();
        let flip = if tangent && nonneg { negative_at_probe } else { self.rng.random_bool(0.4) };
        if flip {
            p0 = p0.neg();
            recipe = format!("−[{recipe}]");
        }
        let p0_pos_at_probe = p0.sign_at(&probe).is_gt();
        let eps = self.perturbation(p0.size(), tangent);
        if !eps.is_zero() {
            recipe += &format!(" + {eps}");
        }
        let truth = truth_of(!inside.is_empty(), nonneg, p0_pos_at_probe, &eps);
        let p = p0.add_constant(&eps);
        let exact = p.compose_affine(&t1, &(&t2 - &t1)).to_upoly();
        let interval = exact.map(Interval::enclose_rational);
        Case { exact, interval, truth, original: p.to_upoly(), domain: (t1, t2), recipe }
    }

    /// `[0, 1]` half the time, else a random `[t1, t2]` in [−2, 2].
    fn domain(&mut self) -> (BigRational, BigRational) {
        if self.rng.random_bool(0.5) {
            return (BigRational::zero(), BigRational::one());
        }
        loop {
            let (a, b) = (self.rational(-2, 2), self.rational(-2, 2));
            if a != b {
                return if a < b { (a, b) } else { (b, a) };
            }
        }
    }

    /// A rational in `[lo, hi]` with a random denominator from [`DENOMINATORS`].
    fn rational(&mut self, lo: i64, hi: i64) -> BigRational {
        let d = DENOMINATORS[self.rng.random_range(0..DENOMINATORS.len())];
        let n = self.rng.random_range(lo * d..=hi * d);
        BigRational::new(n.into(), d.into())
    }

    fn nonzero_rational(&mut self) -> BigRational {
        loop {
            let r = self.rational(-1, 1);
            if !r.is_zero() {
                return r;
            }
        }
    }

    /// A point of `[t1, t2]`; an end with probability 1/8.
    fn point_in(&mut self, t1: &BigRational, t2: &BigRational) -> BigRational {
        match self.rng.random_range(0..16) {
            0 => t1.clone(),
            1 => t2.clone(),
            _ => {
                let d = DENOMINATORS[self.rng.random_range(0..DENOMINATORS.len())];
                let k = self.rng.random_range(0..=d);
                t1 + (t2 - t1) * BigRational::new(k.into(), d.into())
            }
        }
    }

    /// A point outside `[t1, t2]`, within 2 of it.
    fn point_outside(&mut self, t1: &BigRational, t2: &BigRational) -> BigRational {
        let gap = self.rational(0, 2).abs() + BigRational::new(1.into(), 100.into());
        if self.rng.random_bool(0.5) {
            t1 - gap
        } else {
            t2 + gap
        }
    }

    /// `0` or `±10^-k · S` with `S` the power of ten nearest the largest coefficient
    /// `size`. Tangent cases are perturbed more often, since that is where they are hard.
    fn perturbation(&mut self, size: f64, tangent: bool) -> BigRational {
        if !self.rng.random_bool(if tangent { 0.8 } else { 0.5 }) {
            return BigRational::zero();
        }
        let k = self.rng.random_range(PERTURBATION_EXPONENTS) as i32;
        let e = size.max(1e-30).log10().round() as i32 - k;
        let ten_e = num_traits::pow(BigInt::from(10), e.unsigned_abs() as usize);
        let eps = if e >= 0 { BigRational::from_integer(ten_e) } else { BigRational::new(BigInt::one(), ten_e) };
        if self.rng.random_bool(0.5) {
            eps
        } else {
            -eps
        }
    }
}

/// A point of `[t1, t2]` where `p0 ≠ 0` (one of 18 equally spaced points; `p0` has at
/// most `deg ≤ 17` roots there unless it is zero).
fn probe_point(p0: &IntPoly, t1: &BigRational, t2: &BigRational) -> BigRational {
    (0..=17)
        .map(|k| t1 + (t2 - t1) * BigRational::new(k.into(), 17.into()))
        .find(|t| !p0.sign_at(t).is_eq())
        .unwrap_or_else(|| t1.clone())
}

/// What `p = p0 + ε` is on the domain, from the construction alone.
///
/// `has_root`: `p0` vanishes somewhere in the domain; `nonneg`: every root there has even
/// multiplicity, so `p0` keeps the sign it has at a non-root point (`pos_at_probe`).
fn truth_of(has_root: bool, nonneg: bool, pos_at_probe: bool, eps: &BigRational) -> Truth {
    let p0_positive = !has_root && pos_at_probe;
    let p0_nonneg = nonneg && pos_at_probe;
    if (p0_positive && !eps.is_negative()) || (p0_nonneg && eps.is_positive()) {
        Truth::Positive
    } else if !eps.is_positive() && (has_root || !pos_at_probe) {
        // p(r) = ε ≤ 0 at a root r, or (no root, negative probe) p0 < 0 on the domain
        Truth::NotPositive
    } else {
        Truth::Unknown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(n: i64, d: i64) -> BigRational {
        BigRational::new(n.into(), d.into())
    }

    #[test]
    fn seeded_and_reproducible() {
        let a: Vec<_> = (0..20)
            .map({
                let mut g = Generator::new(7);
                move |_| g.case().exact
            })
            .collect();
        let b: Vec<_> = (0..20)
            .map({
                let mut g = Generator::new(7);
                move |_| g.case().exact
            })
            .collect();
        assert_eq!(a, b);
    }

    #[test]
    fn degrees_and_enclosures() {
        let mut g = Generator::new(1);
        for deg in DEGREES {
            for _ in 0..20 {
                let c = g.case_of_degree(deg);
                assert_eq!(c.exact.degree(), deg, "{}", c.recipe);
                assert_eq!(c.interval.degree(), deg);
                for (e, i) in c.exact.coeffs().iter().zip(c.interval.coeffs()) {
                    assert!(q_of(i.lo) <= *e && *e <= q_of(i.hi));
                }
                // the integer construction is the composition UPoly::compose_affine computes
                let (t1, t2) = &c.domain;
                assert_eq!(c.original.compose_affine(t1, &(t2 - t1)), c.exact, "{}", c.recipe);
            }
        }
    }

    fn q_of(x: f64) -> BigRational {
        BigRational::from_float(x).unwrap()
    }

    /// Composition with the affine map is exact: p̃(τ) = p(t1 + (t2 − t1)τ); in interval
    /// arithmetic it encloses the exact composition.
    #[test]
    fn compose_affine_maps_the_domain() {
        let p = UPoly::new(vec![q(1, 3), q(-2, 1), q(0, 1), q(5, 7)]);
        let (t1, t2) = (q(-3, 10), q(6, 5));
        let pt = p.compose_affine(&t1, &(&t2 - &t1));
        for k in 0..=10 {
            let tau = q(k, 10);
            assert_eq!(pt.eval(&tau), p.eval(&(&t1 + (&t2 - &t1) * &tau)));
        }
        let pi = p.map(Interval::enclose_rational);
        let ti = Interval::enclose_rational(&t1);
        let wi = Interval::enclose_rational(&t2) - ti;
        let composed = pi.compose_affine(&ti, &wi);
        for (e, i) in pt.coeffs().iter().zip(composed.coeffs()) {
            assert!(q_of(i.lo) <= *e && *e <= q_of(i.hi));
        }
    }

    #[test]
    fn truth_table() {
        let (z, pos, neg) = (q(0, 1), q(1, 100), q(-1, 100));
        assert_eq!(truth_of(false, true, true, &z), Truth::Positive);
        assert_eq!(truth_of(true, true, true, &pos), Truth::Positive);
        assert_eq!(truth_of(true, true, true, &z), Truth::NotPositive);
        assert_eq!(truth_of(true, false, true, &pos), Truth::Unknown);
        assert_eq!(truth_of(false, true, false, &neg), Truth::NotPositive);
        assert_eq!(truth_of(false, true, false, &pos), Truth::Unknown);
        assert_eq!(truth_of(false, true, true, &neg), Truth::Unknown);
    }

    /// The recorded truth agrees with dense exact sampling wherever sampling can refute.
    #[test]
    fn truth_is_consistent_with_sampling() {
        let mut g = Generator::new(3);
        let mut known = 0;
        for _ in 0..500 {
            let c = g.case();
            let min_sample = (0..=64).map(|k| c.exact.eval(&q(k, 64))).min().unwrap_or_else(BigRational::zero);
            if c.truth == Truth::Positive {
                assert!(min_sample.is_positive(), "{}", c.recipe);
            }
            if c.truth != Truth::Unknown {
                known += 1;
            }
        }
        assert!(known > 250, "only {known} of 500 cases have a known answer");
    }
}
