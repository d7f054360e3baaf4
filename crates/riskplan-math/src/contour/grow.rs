//! Growing an obstacle by the robot's body (docs/design.md §3.12; beyond the paper). A
//! robot whose body is the ball of radius ρ around its reference point x
//! touches the obstacle `{P(·, ω, t) ≥ 0}` exactly when `max_{‖y‖≤ρ} P(x + y, ω, t) ≥ 0`.
//! A polynomial `Q` with
//!
//! ```text
//! max_{‖y‖≤ρ} P(x + y, ω, t) ≥ 0   ⟹   Q(x, ω, t) ≥ 0        (for all x, ω, t)
//! ```
//!
//! makes every bound on `Prob(Q ≥ 0)` a bound on the probability of body contact, so the
//! whole machinery (contours, certificates) runs on `Q` unchanged. Two constructions:
//!
//! - **Disks and balls, exactly**: `P = S(ω,t) − k·‖x‖² + b(ω,t)·x` with a constant k > 0
//!   is `k·(R² − ‖x − c‖²)` with `c = b/(2k)` and `R² = (S + ‖b‖²/(4k))/k`. When R² is
//!   the square of a polynomial R(ω, t) that is ≥ 0 wherever the parameters can be (its
//!   interval range over their supports), the body touches it iff `‖x − c‖ ≤ R + ρ`, iff
//!   `Q = P + k·(2ρR + ρ²) ≥ 0` — the same disk with radius R + ρ.
//! - **Any polynomial, soundly**: Taylor's formula is exact for polynomials,
//!   `P(x + y) = Σ_j T_j(y)` with `T_j(y) = Σ_{|α|=j} D_α y^α`, `D_α = ∂^αP/α!`; by
//!   Cauchy–Schwarz and `Σ_{|α|=j} y^{2α} ≤ ‖y‖^{2j}`, `|T_j| ≤ ρ^j·√S_j` with
//!   `S_j = Σ_{|α|=j} D_α²`, and `√S ≤ (S/ε + ε)/2` for any ε > 0 (AM–GM), so
//!   `Q = P + Σ_{j≥1} ρ^j·(S_j/ε_j + ε_j)/2` bounds the maximum from above. ε_j is a
//!   typical value of √S_j (any positive value is sound; a typical one is tight where
//!   √S_j ≈ ε_j). Its degree is up to `2·deg P − 2`.

use super::Layout;
use crate::poly::{rational_to_f64, Interval, Monomial, Poly, QPoly, Var};
use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use thiserror::Error;

/// Why an obstacle cannot be grown.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum GrowError {
    /// The envelope's degree in (x, t) exceeds the limit.
    #[error("grown by the body its polynomial has degree {degree} in (x, t), over the limit {limit}")]
    Degree {
        /// Degree of the envelope.
        degree: u32,
        /// The limit.
        limit: u32,
    },
    /// The envelope has too many terms.
    #[error("grown by the body its polynomial has {terms} terms, over the limit {limit}")]
    Terms {
        /// Terms of the envelope.
        terms: usize,
        /// The limit.
        limit: usize,
    },
}

/// How an obstacle was grown.
#[derive(Clone, Debug, PartialEq)]
pub struct Grown {
    /// `Q` (module docs).
    pub poly: QPoly,
    /// Whether `Q ≥ 0` is exactly body contact (a disk or ball grown by ρ).
    pub exact: bool,
}

/// The disk/ball form of `p` (module docs): `(k, R)` with `p = k·(R² − ‖x − c‖²)` and
/// `R ≥ 0` over the parameters' ranges (`range`: an interval enclosure of a variable's
/// values: x and t are not in R), or `None`.
pub fn disk_form(p: &QPoly, layout: Layout, range: &dyn Fn(Var) -> Interval) -> Option<(BigRational, QPoly)> {
    let n = layout.dim;
    let is_x = |v: Var| (v as usize) < n;
    // the x-quadratic part must be −k·Σ x_i², with no other variable in those terms
    let mut k: Option<BigRational> = None;
    let mut b: Vec<QPoly> = vec![Poly::zero(); n];
    let mut s = Poly::zero();
    for (m, c) in p.terms() {
        let (xm, rest) = m.split(is_x);
        match xm.degree() {
            0 => s.add_term(rest, c.clone()),
            1 => {
                let i = xm.pairs()[0].0 as usize;
                b[i].add_term(rest, c.clone());
            }
            2 => {
                let pairs = xm.pairs();
                if pairs.len() != 1 || rest.degree() != 0 {
                    return None;
                }
                let kk = -c.clone();
                if !kk.is_positive() || k.as_ref().is_some_and(|k0| *k0 != kk) {
                    return None;
                }
                k = Some(kk);
            }
            _ => return None,
        }
    }
    let k = k?;
    // every x_i² present
    let count = p.terms().filter(|(m, _)| m.split(is_x).0.degree() == 2).count();
    if count != n {
        return None;
    }
    // R² = (s + ‖b‖²/(4k))/k
    let four_k = &k * BigRational::from_integer(4.into());
    let mut r2 = s;
    for bi in &b {
        r2 = r2.add(&bi.mul(bi).scale(&(BigRational::one() / &four_k)));
    }
    let r2 = r2.scale(&(BigRational::one() / &k));
    let r = poly_sqrt(&r2)?;
    // the sign for which R ≥ 0 over the ranges
    let lo = |q: &QPoly| {
        let top = q.vars().into_iter().max().map_or(0, |v| v as usize + 1);
        let vals: Vec<Interval> = (0..top).map(|v| range(v as Var)).collect();
        q.map_coeffs(Interval::enclose_rational).eval(&vals).lo
    };
    if lo(&r) >= 0.0 {
        Some((k, r))
    } else if lo(&r.neg()) >= 0.0 {
        Some((k, r.neg()))
    } else {
        None
    }
}

/// The square root of a polynomial that is the square of one, exactly (`None`
/// otherwise): leading terms in the graded order, as in long division.
pub fn poly_sqrt(q: &QPoly) -> Option<QPoly> {
    if q.is_zero() {
        return Some(Poly::zero());
    }
    let lead = |p: &QPoly| -> Option<(Monomial, BigRational)> {
        p.terms()
            .max_by(|a, b| a.0.degree().cmp(&b.0.degree()).then_with(|| a.0.lex_cmp(b.0)))
            .map(|(m, c)| (m.clone(), c.clone()))
    };
    let (m0, c0) = lead(q)?;
    if m0.pairs().iter().any(|&(_, e)| e % 2 != 0) {
        return None;
    }
    let root_m = Monomial::from_pairs(m0.pairs().iter().map(|&(v, e)| (v, e / 2)));
    let root_c = rational_sqrt(&c0)?;
    let mut r = Poly::monomial(root_m.clone(), root_c.clone());
    let two_lead = (root_m, &root_c * BigRational::from_integer(2.into()));
    // at most as many steps as q has terms, each adding one term of r
    for _ in 0..=q.len() {
        let rem = q.sub(&r.mul(&r));
        let Some((m, c)) = lead(&rem) else { return Some(r) };
        // the next term: lt(rem) / (2·lt(r)), which must divide
        let pairs: Option<Vec<(Var, u32)>> = {
            let mut out = Vec::new();
            let mut ok = true;
            for &(v, e) in m.pairs() {
                let d = two_lead.0.exp(v);
                if e < d {
                    ok = false;
                    break;
                }
                if e > d {
                    out.push((v, e - d));
                }
            }
            ok = ok && two_lead.0.pairs().iter().all(|&(v, d)| m.exp(v) >= d);
            ok.then_some(out)
        };
        let pairs = pairs?;
        let t = Monomial::from_pairs(pairs);
        r = r.add(&Poly::monomial(t, c / &two_lead.1));
    }
    q.sub(&r.mul(&r)).is_zero().then_some(r)
}

fn rational_sqrt(c: &BigRational) -> Option<BigRational> {
    if c.is_negative() {
        return None;
    }
    let s = |n: &BigInt| -> Option<BigInt> {
        let r = n.sqrt();
        (&r * &r == *n).then_some(r)
    };
    Some(BigRational::new(s(c.numer())?, s(c.denom())?))
}

/// Grows `p` by a body of radius `rho` (≥ 0), exactly for a disk or ball form and by the
/// Taylor envelope otherwise (module docs). `range`: enclosures of the parameters' values
/// (for the sign of R); `samples`: points `(x, t, parameter values)` at which the typical
/// sizes ε_j of the envelope's terms are taken (any points: a poor choice loosens the
/// envelope, never its soundness); `limits`: (degree in (x, t), terms).
pub fn grow(
    p: &QPoly,
    layout: Layout,
    rho: &BigRational,
    range: &dyn Fn(Var) -> Interval,
    samples: &[Vec<f64>],
    limits: (u32, usize),
) -> Result<Grown, GrowError> {
    if rho.is_zero() {
        return Ok(Grown { poly: p.clone(), exact: true });
    }
    if let Some((k, r)) = disk_form(p, layout, range) {
        let two = BigRational::from_integer(2.into());
        let extra = r.scale(&(&two * rho)).add(&Poly::constant(rho * rho)).scale(&k);
        return Ok(Grown { poly: p.add(&extra), exact: true });
    }
    let n = layout.dim;
    // P(x + y): y_i as fresh variables after every variable of p
    let top = p.vars().into_iter().max().unwrap_or(0).max(layout.t());
    let y = |i: usize| (top as usize + 1 + i) as Var;
    let shifted = p.subst(&|v| ((v as usize) < n).then(|| Poly::var(v).add(&Poly::var(y(v as usize)))));
    let is_y = |v: Var| v > top;
    // D_α by the y-exponent α, grouped by |α| = j
    let mut by_alpha: Vec<(Monomial, QPoly)> = Vec::new();
    for (m, c) in shifted.terms() {
        let (ym, rest) = m.split(is_y);
        if ym.degree() == 0 {
            continue;
        }
        match by_alpha.iter_mut().find(|(a, _)| *a == ym) {
            Some((_, d)) => d.add_term(rest, c.clone()),
            None => by_alpha.push((ym, Poly::monomial(rest, c.clone()))),
        }
    }
    let max_j = by_alpha.iter().map(|(a, _)| a.degree()).max().unwrap_or(0);
    let mut q = p.clone();
    let mut rho_j = BigRational::one();
    let half = BigRational::new(1.into(), 2.into());
    for j in 1..=max_j {
        rho_j = &rho_j * rho;
        let mut s = Poly::zero();
        for (_, d) in by_alpha.iter().filter(|(a, _)| a.degree() == j) {
            s = s.add(&d.mul(d));
        }
        if s.is_zero() {
            continue;
        }
        let eps = typical_root(&s, samples);
        // ρ^j (S/ε + ε)/2
        q = q.add(&s.scale(&(&rho_j * &half / &eps)).add(&Poly::constant(&rho_j * &half * &eps)));
    }
    let degree = q.degree_in_vars(|v| !layout.is_param(v));
    if degree > limits.0 {
        return Err(GrowError::Degree { degree, limit: limits.0 });
    }
    if q.len() > limits.1 {
        return Err(GrowError::Terms { terms: q.len(), limit: limits.1 });
    }
    Ok(Grown { poly: q, exact: false })
}

/// The median of √S over `samples`, as a positive rational (1 when no sample gives a
/// positive finite value).
fn typical_root(s: &QPoly, samples: &[Vec<f64>]) -> BigRational {
    let f = s.map_coeffs(rational_to_f64);
    let mut v: Vec<f64> =
        samples.iter().map(|x| f.eval(x).max(0.0).sqrt()).filter(|r| r.is_finite() && *r > 0.0).collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).and_then(|&m| BigRational::from_float(m)).unwrap_or_else(BigRational::one)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::poly::parse;

    fn poly(text: &str, names: &[&str]) -> QPoly {
        let mut resolve = |n: &str| names.iter().position(|m| *m == n).map(|i| i as Var).ok_or_else(|| n.to_string());
        parse(text, &mut resolve).unwrap()
    }

    fn q(x: f64) -> BigRational {
        BigRational::from_float(x).unwrap()
    }

    #[test]
    fn square_roots_of_squares_and_not_of_others() {
        let names = ["x1", "x2", "t", "w", "v"];
        for text in ["(w + 2*v - 3*t + 1/2)^2", "(3/7*w^2 - v)^2", "9/4", "(t*w)^2"] {
            let p = poly(text, &names);
            let r = poly_sqrt(&p).unwrap_or_else(|| panic!("{text}"));
            assert_eq!(r.mul(&r), p, "{text}");
        }
        for text in ["w^2 + 1", "2*w^2", "w^2 + w", "w^3"] {
            assert_eq!(poly_sqrt(&poly(text, &names)), None, "{text}");
        }
    }

    /// A disk grows into the disk of radius R + ρ, exactly; its sign is taken where the
    /// radius is positive.
    #[test]
    fn disks_grow_by_the_radius_exactly() {
        let names = ["x1", "x2", "t", "w", "u"];
        let layout = Layout { dim: 2 };
        let range = |v: Var| if v == 3 { Interval::new(0.2, 0.4) } else { Interval::new(-1.0, 1.0) };
        let p = poly("w^2 - (x1 - (t + 0.4 + u))^2 - (x2 - 1)^2", &names);
        let g = grow(&p, layout, &q(0.25), &range, &[], (8, 500)).unwrap();
        assert!(g.exact);
        assert_eq!(g.poly, poly("(w + 0.25)^2 - (x1 - (t + 0.4 + u))^2 - (x2 - 1)^2", &names));
        // a scaled disk, constant radius
        let p = poly("3*(0.09 - x1^2 - x2^2)", &names);
        let g = grow(&p, layout, &q(0.5), &range, &[], (8, 500)).unwrap();
        assert_eq!(g.poly, poly("3*(0.8^2 - x1^2 - x2^2)", &names));
        // a radius of either sign (u ∈ [−1, 1]): not a disk form; the envelope instead
        let p = poly("u^2 - x1^2 - x2^2", &names);
        let g = grow(&p, layout, &q(0.5), &range, &[], (8, 500)).unwrap();
        assert!(!g.exact);
    }

    /// The envelope bounds the maximum of P over the ball: checked at random points
    /// against a dense search of the ball (an independent oracle: no Taylor expansion).
    #[test]
    fn the_envelope_bounds_the_maximum_over_the_ball() {
        use rand::{Rng, SeedableRng};
        let names = ["x1", "x2", "t", "w"];
        let layout = Layout { dim: 2 };
        let range = |_: Var| Interval::new(-1.0, 1.0);
        let p = poly("1 - x1^4 - 2*x2^2*x1 + w*x1*x2 - x2^4 + t*x1", &names);
        let rho = 0.3;
        let samples: Vec<Vec<f64>> = (0..20).map(|k| vec![k as f64 / 20.0, 0.5, 0.0, 0.1]).collect();
        let g = grow(&p, layout, &q(rho), &range, &samples, (8, 500)).unwrap();
        assert!(!g.exact);
        let (pf, qf) = (p.map_coeffs(rational_to_f64), g.poly.map_coeffs(rational_to_f64));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..2000 {
            let x: Vec<f64> = vec![
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(0.0..1.0),
                rng.random_range(-1.0..1.0),
            ];
            let mut best = f64::NEG_INFINITY;
            for a in 0..48 {
                for r in [0.0, 0.5, 1.0] {
                    let th = a as f64 * std::f64::consts::TAU / 48.0;
                    let mut z = x.clone();
                    z[0] += r * rho * th.cos();
                    z[1] += r * rho * th.sin();
                    best = best.max(pf.eval(&z));
                }
            }
            assert!(qf.eval(&x) >= best - 1e-9, "{x:?}: envelope {} below {best}", qf.eval(&x));
        }
    }
}
