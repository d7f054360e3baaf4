//! Exact expectations E[p] and E[p²] over the parameters, in integer arithmetic
//! (docs/design.md §2.1: a contour's mean and second moment, eq. (15)).
//!
//! [`Poly::mul`] and [`Poly::expect`] work in reduced rationals, a gcd after every product
//! and sum: on 512 uncertain disks forming E[P²] was most of a scene's load. Here the
//! polynomial is brought over one common denominator `D` first (integer numerators `N_m`);
//! the products of its terms (for p²) are integers; terms are grouped by their non-parameter
//! monomial `r` and parameter monomial `μ` with integer sums `S_{r,μ}`; and each coefficient
//! `Σ_μ S_{r,μ}·E[μ] / D^k` (`E[μ]` the product of the parameters' raw moments, formed once
//! per `μ`) is summed over the least common multiple of its `E[μ]`'s denominators and reduced
//! once. The same polynomials as the rational expressions (test
//! `expectations_equal_the_rational_expressions`).

use super::affine::OverDen;
use super::{Monomial, Poly, QPoly, Var};
use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::BigRational;
use num_traits::{One, Zero};
use std::collections::{BTreeMap, HashMap};

/// `(E[p], E[p²])` over the variables `is_param` says are parameters, with `moment(v, k)`
/// the k-th raw moment of parameter `v` (`Err((v, k))` for the first one missing): the same
/// as `p.expect(..)` and `p.mul(p).expect(..)`.
pub fn mean_and_second_moment(
    p: &QPoly,
    is_param: impl Fn(Var) -> bool,
    mut moment: impl FnMut(Var, u32) -> Option<BigRational>,
) -> Result<(QPoly, QPoly), (Var, u32)> {
    let od = OverDen::new(p);
    // (rest, μ) of each term, split once
    let split: Vec<(Monomial, Monomial, &BigInt)> = od
        .terms
        .iter()
        .map(|(m, n)| {
            let (mu, rest) = m.split(&is_param);
            (rest, mu, n)
        })
        .collect();
    let mut memo: HashMap<Monomial, BigRational> = HashMap::new();
    let mut mean: BTreeMap<Monomial, BTreeMap<Monomial, BigInt>> = BTreeMap::new();
    for (rest, mu, n) in &split {
        *mean.entry(rest.clone()).or_default().entry(mu.clone()).or_insert_with(BigInt::zero) += *n;
    }
    let mut second: BTreeMap<Monomial, BTreeMap<Monomial, BigInt>> = BTreeMap::new();
    for (i, (r1, mu1, n1)) in split.iter().enumerate() {
        // each pair once, the cross terms doubled
        for (j, (r2, mu2, n2)) in split.iter().enumerate().skip(i) {
            let mut v = *n1 * *n2;
            if j != i {
                v <<= 1usize;
            }
            *second.entry(r1.mul(r2)).or_default().entry(mu1.mul(mu2)).or_insert_with(BigInt::zero) += v;
        }
    }
    let d2 = &od.den * &od.den;
    let m = expectation(mean, &od.den, &mut moment, &mut memo)?;
    let s = expectation(second, &d2, &mut moment, &mut memo)?;
    Ok((m, s))
}

/// `Σ_r r · Σ_μ S_{r,μ}·E[μ] / den`, each coefficient reduced once.
fn expectation(
    grouped: BTreeMap<Monomial, BTreeMap<Monomial, BigInt>>,
    den: &BigInt,
    moment: &mut impl FnMut(Var, u32) -> Option<BigRational>,
    memo: &mut HashMap<Monomial, BigRational>,
) -> Result<QPoly, (Var, u32)> {
    let mut out = Poly::zero();
    for (rest, sums) in grouped {
        let mut values: Vec<(BigInt, BigRational)> = Vec::with_capacity(sums.len());
        for (mu, s) in sums {
            if s.is_zero() {
                continue;
            }
            let e = match memo.get(&mu) {
                Some(e) => e.clone(),
                None => {
                    let mut e = BigRational::one();
                    for &(v, k) in mu.pairs() {
                        e *= moment(v, k).ok_or((v, k))?;
                    }
                    memo.insert(mu, e.clone());
                    e
                }
            };
            values.push((s, e));
        }
        let l = values.iter().fold(BigInt::one(), |acc, (_, e)| acc.lcm(e.denom()));
        let num = values.iter().fold(BigInt::zero(), |acc, (s, e)| acc + s * e.numer() * (&l / e.denom()));
        if !num.is_zero() {
            out.add_term(rest, BigRational::new(num, &l * den));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::affine::tests::{poly, q};
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The oracle: the rational expressions `p.expect(..)` and `p.mul(p).expect(..)`,
        /// with variable 2 (and 1, when `two_params`) a parameter of rational moments.
        #[test]
        fn expectations_equal_the_rational_expressions(p in poly(), two_params: bool, a in 1i64..50, b in 1i64..50) {
            let is_param = |v: Var| v == 2 || (two_params && v == 1);
            // the k-th moment (v + 1)·a^k / (b^k + 1): any rationals will do
            let moment = |v: Var, k: u32| Some(q((v as i64 + 1) * a.pow(k), b.pow(k) + 1));
            let (m, s) = mean_and_second_moment(&p, is_param, moment).unwrap();
            prop_assert_eq!(m, p.expect(is_param, moment).unwrap());
            prop_assert_eq!(s, p.mul(&p).expect(is_param, moment).unwrap());
        }
    }

    /// A missing moment is reported as the rational expression reports it.
    #[test]
    fn a_missing_moment_is_an_error() {
        let mut p = QPoly::zero();
        p.add_term(Monomial::from_pairs([(0, 1), (2, 3)]), q(1, 3));
        let moment = |_: Var, k: u32| (k < 3).then(|| q(1, 2));
        assert_eq!(mean_and_second_moment(&p, |v| v == 2, moment).err(), Some((2, 3)));
    }
}
