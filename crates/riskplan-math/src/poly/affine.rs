//! Exact affine changes of variables, `p(c + s·z)`, in integer arithmetic
//! (docs/design.md §5.10: the compiled frames and the covers' centred bounds).
//!
//! [`Poly::subst`] composes in [`BigRational`] arithmetic, which reduces every product and
//! sum by a gcd: on a scene's moment polynomials (coefficients of a few hundred bits, from
//! decimal inputs) the binary gcds were nearly all of a cold plan's set-up time. Here every
//! coefficient is brought over one common denominator first, each variable's `c` and `s`
//! over one denominator `L`, so that
//!
//! `p(c + s·z) = (1 / (D · Π L_v^{d_v})) · Σ_m N_m · Π_v L_v^{d_v − m_v} · (A_v + S_v·z_v)^{m_v}`
//!
//! with integers only (`N_m = D·a_m`, `A_v = L_v·c_v`, `S_v = L_v·s_v`, `d_v` the degree of
//! `p` in `v`); the binomial expansion is exact and each result coefficient is reduced once.
//! The result is the same polynomial as the rational composition, coefficient for
//! coefficient (test `affine_subst_equals_the_rational_composition`).

use super::{Monomial, Poly, QPoly, Var};
use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::BigRational;
use num_traits::{One, Zero};
use std::collections::HashMap;

/// One variable's affine map `v ↦ c + s·v` over one denominator: `(A + S·v) / L`.
struct Map {
    a: Vec<BigInt>,
    s: Vec<BigInt>,
    /// `L^k` for `k = 0..=d`.
    l: Vec<BigInt>,
    degree: u32,
}

/// `p(c_v + s_v·z_v)` for every variable `v` with `maps[v] = Some((c_v, s_v))` (each
/// substituted variable keeps its index; the others are left alone), exactly.
pub fn affine_subst(p: &QPoly, maps: &[Option<(BigRational, BigRational)>]) -> QPoly {
    let active = |v: Var| maps.get(v as usize).is_some_and(|m| m.is_some());
    if p.is_zero() || !p.terms().any(|(m, _)| m.pairs().iter().any(|&(v, _)| active(v))) {
        return p.clone();
    }
    // per variable: (A + S·v) / L with integers, and powers up to the degree in p
    let tables: Vec<Option<Map>> = maps
        .iter()
        .enumerate()
        .map(|(v, m)| {
            let (c, s) = m.as_ref()?;
            let degree = p.degree_in(v as Var);
            if degree == 0 {
                return None;
            }
            let l = c.denom().lcm(s.denom());
            let a = c.numer() * (&l / c.denom());
            let sc = s.numer() * (&l / s.denom());
            let powers = |x: &BigInt| {
                let mut out = Vec::with_capacity(degree as usize + 1);
                out.push(BigInt::one());
                for k in 1..=degree as usize {
                    let next = &out[k - 1] * x;
                    out.push(next);
                }
                out
            };
            Some(Map { a: powers(&a), s: powers(&sc), l: powers(&l), degree })
        })
        .collect();
    let table = |v: Var| tables.get(v as usize).and_then(|t| t.as_ref());
    // the coefficients over one denominator D
    let den = p.terms().fold(BigInt::one(), |acc, (_, c)| acc.lcm(c.denom()));
    let mut acc: HashMap<Vec<(Var, u32)>, BigInt> = HashMap::new();
    let mut partial: Vec<(Vec<(Var, u32)>, BigInt)> = Vec::new();
    let mut next: Vec<(Vec<(Var, u32)>, BigInt)> = Vec::new();
    for (m, c) in p.terms() {
        let mut factor = c.numer() * (&den / c.denom());
        for t in tables.iter().enumerate().filter_map(|(v, t)| t.as_ref().map(|t| (v as Var, t))) {
            factor *= &t.1.l[(t.1.degree - m.exp(t.0)) as usize];
        }
        partial.clear();
        partial.push((Vec::with_capacity(m.pairs().len()), factor));
        for &(v, e) in m.pairs() {
            let Some(t) = table(v) else {
                for (pairs, _) in partial.iter_mut() {
                    pairs.push((v, e));
                }
                continue;
            };
            next.clear();
            let e = e as usize;
            let mut binom = BigInt::one();
            for k in 0..=e {
                // C(e, k)·A^(e−k)·S^k, the coefficient of v^k in (A + S·v)^e
                let w = &binom * &t.a[e - k] * &t.s[k];
                if !w.is_zero() {
                    for (pairs, f) in &partial {
                        let mut q = pairs.clone();
                        if k > 0 {
                            q.push((v, k as u32));
                        }
                        next.push((q, f * &w));
                    }
                }
                binom = binom * BigInt::from(e - k) / BigInt::from(k + 1);
            }
            std::mem::swap(&mut partial, &mut next);
        }
        for (pairs, f) in partial.drain(..) {
            *acc.entry(pairs).or_insert_with(BigInt::zero) += f;
        }
    }
    let total = tables.iter().flatten().fold(den, |d, t| d * &t.l[t.degree as usize]);
    let mut out = Poly::zero();
    for (pairs, n) in acc {
        if !n.is_zero() {
            out.add_term(Monomial(pairs), BigRational::new(n, total.clone()));
        }
    }
    out
}

/// A polynomial over one common denominator: integer numerators and `den > 0`.
pub(super) struct OverDen {
    pub(super) terms: Vec<(Monomial, BigInt)>,
    pub(super) den: BigInt,
}

impl OverDen {
    pub(super) fn new(p: &QPoly) -> Self {
        let den = p.terms().fold(BigInt::one(), |acc, (_, c)| acc.lcm(c.denom()));
        let terms = p.terms().map(|(m, c)| (m.clone(), c.numer() * (&den / c.denom()))).collect();
        OverDen { terms, den }
    }
}

/// `a² − c·b`, exactly — Cantelli's constraint `E[P]² − (1−Δ)·E[P²]` of eq. (15) — with
/// integer numerators over one denominator (`(A²·B_d·c_d − B·c_n·a_d²) / (a_d²·b_d·c_d)`)
/// and one reduction per coefficient, instead of reduced rational products (see the
/// module's introduction). Equal to the rational expression coefficient for coefficient
/// (test `square_minus_scaled_equals_the_rational_expression`).
pub fn square_minus_scaled(a: &QPoly, b: &QPoly, c: &BigRational) -> QPoly {
    let (a, b) = (OverDen::new(a), OverDen::new(b));
    let mut acc: HashMap<Monomial, BigInt> = HashMap::new();
    let left = &b.den * c.denom();
    for (i, (m1, n1)) in a.terms.iter().enumerate() {
        // the square's cross terms once, doubled
        for (m2, n2) in &a.terms[i..] {
            let mut v = n1 * n2 * &left;
            if m1 != m2 {
                v <<= 1usize;
            }
            *acc.entry(m1.mul(m2)).or_insert_with(BigInt::zero) += v;
        }
    }
    let right = c.numer() * &a.den * &a.den;
    for (m, n) in &b.terms {
        *acc.entry(m.clone()).or_insert_with(BigInt::zero) -= n * &right;
    }
    let total = &a.den * &a.den * &left;
    let mut out = Poly::zero();
    for (m, n) in acc {
        if !n.is_zero() {
            out.add_term(m, BigRational::new(n, total.clone()));
        }
    }
    out
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use proptest::prelude::*;

    pub(in crate::poly) fn q(n: i64, d: i64) -> BigRational {
        BigRational::new(n.into(), d.into())
    }

    /// Random polynomials in 3 variables, degree ≤ 4 per variable, rational coefficients.
    pub(in crate::poly) fn poly() -> impl Strategy<Value = QPoly> {
        prop::collection::vec(((0u32..5, 0u32..4, 0u32..3), (-1000i64..1000, 1i64..1000)), 0..12).prop_map(|terms| {
            let mut p = QPoly::zero();
            for ((a, b, c), (n, d)) in terms {
                p.add_term(Monomial::from_pairs([(0, a), (1, b), (2, c)]), q(n, d));
            }
            p
        })
    }

    fn map() -> impl Strategy<Value = Option<(BigRational, BigRational)>> {
        prop::option::of(((-1e6f64..1e6), -20i32..20, any::<bool>())).prop_map(|m| {
            m.map(|(c, e, decimal)| {
                // floats (dyadic) as the frames use, or decimals
                let c = if decimal { q((c * 1000.0) as i64, 997) } else { BigRational::from_float(c).unwrap() };
                let s = num_traits::Pow::pow(&q(2, 1), e);
                (c, s)
            })
        })
    }

    proptest! {
        /// The oracle: the same substitution by rational composition ([`Poly::subst`]).
        #[test]
        fn affine_subst_equals_the_rational_composition(p in poly(), m in prop::collection::vec(map(), 0..4)) {
            let fast = affine_subst(&p, &m);
            let slow = p.subst(&|v| {
                m.get(v as usize).cloned().flatten().map(|(c, s)| Poly::var(v).scale(&s).add(&Poly::constant(c)))
            });
            prop_assert_eq!(fast, slow);
        }
    }

    proptest! {
        /// The oracle: the same expression in reduced rational arithmetic.
        #[test]
        fn square_minus_scaled_equals_the_rational_expression(a in poly(), b in poly(), n in -1000i64..1000, d in 1i64..1000) {
            let c = q(n, d);
            prop_assert_eq!(square_minus_scaled(&a, &b, &c), a.mul(&a).sub(&b.scale(&c)));
        }
    }

    #[test]
    fn a_shifted_square() {
        // (x − 3)² at x = 3 + z/2 is z²/4
        let p = Poly::var(0).sub(&Poly::constant(q(3, 1))).pow(2);
        let r = affine_subst(&p, &[Some((q(3, 1), q(1, 2)))]);
        assert_eq!(r, Poly::monomial(Monomial::var_pow(0, 2), q(1, 4)));
    }
}
