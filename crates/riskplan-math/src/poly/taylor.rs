//! Exact affine changes of variables `p(c + s·z)` by Taylor shifts in Horner's scheme
//! (synthetic division) over the integers: the verify path's own substitution
//! (docs/design.md §5.12: its frame and its box tests' points).
//!
//! The final check shares no code with the compiled path's frames, which use
//! [`super::affine_subst`] (a binomial expansion of every term); this is another algorithm
//! for the same polynomial, so that a fault in one is not repeated in the other. Both are
//! held to the general rational composition [`Poly::subst`] (and to each other) by property
//! tests. [`Poly::subst`] itself reduces every product and sum by a gcd: it cost about
//! 0.25 ms per obstacle, most of a cold plan's final check on 512 disks (0.3 s).
//!
//! One variable `v` at a time, with `c = a/b` (`b > 0`) and `s = σ/τ` (`τ > 0`), and `d` the
//! polynomial's degree in `v`: each *lane* (the terms sharing the other variables'
//! exponents) is an integer polynomial `q(x) = Σⱼ nⱼxʲ`. With `r(w) = Σⱼ nⱼ·b^(d−j)·wʲ`,
//! `b^d·q(x) = r(b·x)`, so `b^d·q(y + a/b) = r(b·y + a) = Σₖ mₖ·bᵏ·yᵏ` where `mₖ` are the
//! coefficients of `r(w + a)` (integer Taylor shift: `d(d+1)/2` multiply-adds), and with
//! `y = s·z`, `b^d·τ^d·q(c + s·z) = Σₖ mₖ·bᵏ·σᵏ·τ^(d−k)·zᵏ`. Every lane of `v` shares the
//! factor `(b·τ)^d`, which joins the common denominator; each result coefficient is
//! reduced once at the end.

use super::{Monomial, Poly, QPoly, Var};
use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::BigRational;
use num_traits::{One, Zero};
use std::collections::BTreeMap;

/// `p(c_v + s_v·z_v)` for every variable `v` with `maps[v] = Some((c_v, s_v))` (each
/// substituted variable keeps its index; the others are left alone), exactly: the same
/// polynomial as [`Poly::subst`] with `v ↦ c_v + s_v·v` and as [`super::affine_subst`].
pub fn taylor_shift(p: &QPoly, maps: &[Option<(BigRational, BigRational)>]) -> QPoly {
    if p.is_zero() {
        return p.clone();
    }
    // every coefficient over one denominator: N_m / den
    let mut den = p.terms().fold(BigInt::one(), |acc, (_, c)| acc.lcm(c.denom()));
    let mut terms: BTreeMap<Vec<(Var, u32)>, BigInt> =
        p.terms().map(|(m, c)| (m.pairs().to_vec(), c.numer() * (&den / c.denom()))).collect();
    for (v, map) in maps.iter().enumerate() {
        let Some((c, s)) = map else { continue };
        let v = v as Var;
        let d = terms.keys().map(|m| exponent(m, v)).max().unwrap_or(0) as usize;
        if d == 0 {
            continue;
        }
        // (BigRational keeps its denominator positive)
        let (a, b) = (c.numer(), c.denom());
        let (sigma, tau) = (s.numer(), s.denom());
        // the lanes: the other variables' exponents → the coefficients of v⁰..v^d
        let mut lanes: BTreeMap<Vec<(Var, u32)>, Vec<BigInt>> = BTreeMap::new();
        for (m, n) in std::mem::take(&mut terms) {
            let j = exponent(&m, v) as usize;
            let rest: Vec<(Var, u32)> = m.into_iter().filter(|&(w, _)| w != v).collect();
            lanes.entry(rest).or_insert_with(|| vec![BigInt::zero(); d + 1])[j] += n;
        }
        let b_pow = powers(b, d);
        // bᵏ·σᵏ·τ^(d−k), the factor of mₖ
        let sigma_pow = powers(sigma, d);
        let tau_pow = powers(tau, d);
        let factor: Vec<BigInt> = (0..=d).map(|k| &b_pow[k] * &sigma_pow[k] * &tau_pow[d - k]).collect();
        for (rest, mut r) in lanes {
            for (j, n) in r.iter_mut().enumerate() {
                *n *= &b_pow[d - j];
            }
            // r(w + a), in place: after pass i the coefficients below i are final
            if !a.is_zero() {
                for i in 0..d {
                    for j in (i..d).rev() {
                        let carry = a * &r[j + 1];
                        r[j] += carry;
                    }
                }
            }
            for (k, m) in r.into_iter().enumerate() {
                if m.is_zero() {
                    continue;
                }
                let mut mono = rest.clone();
                if k > 0 {
                    // (pairs are kept sorted by variable)
                    let at = mono.partition_point(|&(w, _)| w < v);
                    mono.insert(at, (v, k as u32));
                }
                terms.insert(mono, m * &factor[k]);
            }
        }
        den *= num_traits::pow(b * tau, d);
    }
    let mut out = Poly::zero();
    for (pairs, n) in terms {
        if !n.is_zero() {
            out.add_term(Monomial(pairs), BigRational::new(n, den.clone()));
        }
    }
    out
}

/// The exponent of `v` in a monomial's pairs.
fn exponent(pairs: &[(Var, u32)], v: Var) -> u32 {
    pairs.iter().find(|&&(w, _)| w == v).map_or(0, |&(_, e)| e)
}

/// `x⁰ … x^d`.
fn powers(x: &BigInt, d: usize) -> Vec<BigInt> {
    let mut out = Vec::with_capacity(d + 1);
    out.push(BigInt::one());
    for k in 1..=d {
        let next = &out[k - 1] * x;
        out.push(next);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::affine::tests::{poly, q};
    use super::*;
    use proptest::prelude::*;

    /// A variable's map: a float (dyadic) centre as the frames use — moderate, huge
    /// (about 10³⁰⁰) or subnormal —, or a decimal one, or 0; a scale 2^e, or a rational one.
    fn map() -> impl Strategy<Value = Option<(BigRational, BigRational)>> {
        prop::option::of(((-1e6f64..1e6), 0u8..5, -20i32..20, prop::option::of((1i64..50, 1i64..50)))).prop_map(|m| {
            m.map(|(c, kind, e, ratio)| {
                let c = match kind {
                    0 => BigRational::from_float(c).unwrap(),
                    1 => q((c * 1000.0) as i64, 997),
                    2 => BigRational::from_float(c * 1e294).unwrap(),
                    3 => BigRational::from_float(c * 1e-314).unwrap(),
                    _ => BigRational::zero(),
                };
                let s = ratio.map_or_else(|| num_traits::Pow::pow(&q(2, 1), e), |(n, d)| q(-n, d));
                (c, s)
            })
        })
    }

    proptest! {
        /// The oracle: the same substitution by rational composition ([`Poly::subst`]);
        /// and the compiled frames' own algorithm gives the same polynomial.
        #[test]
        fn taylor_shift_equals_the_rational_composition(p in poly(), m in prop::collection::vec(map(), 0..4)) {
            let fast = taylor_shift(&p, &m);
            let slow = p.subst(&|v| {
                m.get(v as usize).cloned().flatten().map(|(c, s)| Poly::var(v).scale(&s).add(&Poly::constant(c)))
            });
            prop_assert_eq!(&fast, &slow);
            prop_assert_eq!(fast, super::super::affine_subst(&p, &m));
        }
    }
}
