//! Gauss quadrature rules for the oracle, built from its **own** closed-form moments of
//! each distribution family (never from `riskplan::moments`).
//!
//! A rule with `n` nodes integrates polynomials of degree ≤ 2n − 1 exactly. The oracle
//! needs E[P] and E[P²] with P of degree ≤ 2 in each parameter, so P² has degree ≤ 4:
//! [`NODES`] = 3 nodes (exact to degree 5) suffice. The rule of a family is built for a
//! *standardised* variable z (mean 0, variance 1, or a fixed standard form) by the
//! Stieltjes procedure on its moments and the Golub–Welsch eigen-decomposition of the
//! Jacobi matrix, then mapped affinely onto the parameter (w = c + s·z keeps weights
//! and moves nodes), which keeps the Hankel moments well conditioned however far the
//! parameter sits from 0.

use super::generate::Dist;
use nalgebra::{DMatrix, SymmetricEigen};
use thiserror::Error;

/// Nodes per parameter: exact for polynomials of degree ≤ 5 in that parameter (P² has
/// degree ≤ 4 in each parameter since P has degree ≤ 2).
pub const NODES: usize = 3;

/// Relative size (against the zeroth moment) below which the squared norm of an
/// orthogonal polynomial counts as zero: the distribution then has fewer atoms than
/// requested nodes, and the rule with as many nodes as atoms is already exact.
/// Standardised moments are O(1), so 1e-10 is far above rounding (~1e-15) and far
/// below any real variance of a standardised variable (~1).
pub const DEGENERATE_NORM: f64 = 1e-10;

/// A quadrature rule: Σ weights[i]·f(nodes[i]) ≈ E[f(w)].
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    /// Nodes (values of the parameter).
    pub nodes: Vec<f64>,
    /// Weights (non-negative, summing to 1).
    pub weights: Vec<f64>,
}

impl Rule {
    /// E[f(w)] under the rule.
    pub fn expect(&self, f: impl Fn(f64) -> f64) -> f64 {
        self.nodes.iter().zip(&self.weights).map(|(&x, &w)| w * f(x)).sum()
    }
}

/// Why a rule cannot be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum QuadratureError {
    /// A distribution parameter out of its family's range.
    #[error("{family}: {message}")]
    BadParameter {
        /// The family.
        family: &'static str,
        /// What is wrong.
        message: String,
    },
    /// Moments that are not those of a distribution (negative variance or norm).
    #[error("moments are not those of a distribution: {0}")]
    NotMoments(String),
}

fn bad(family: &'static str, message: impl Into<String>) -> QuadratureError {
    QuadratureError::BadParameter { family, message: message.into() }
}

/// Raw moments m₀..m₍₂ₙ₋₁₎ (m₀ = 1) of a standardised variable → n-node Gauss rule
/// (fewer nodes when the distribution has fewer atoms).
pub fn gauss_from_moments(m: &[f64], n: usize) -> Result<Rule, QuadratureError> {
    if n == 0 || m.len() < 2 * n {
        return Err(QuadratureError::NotMoments(format!("{} moments given, {} needed", m.len(), 2 * n.max(1))));
    }
    if m.iter().any(|x| !x.is_finite()) {
        return Err(QuadratureError::NotMoments("a moment is not finite".into()));
    }
    // Polynomials as coefficient vectors (low degree first); <p, q> = Σ p_i q_j m_{i+j}.
    let inner = |p: &[f64], q: &[f64]| -> f64 {
        let mut s = 0.0;
        for (i, a) in p.iter().enumerate() {
            for (j, b) in q.iter().enumerate() {
                s += a * b * m[i + j];
            }
        }
        s
    };
    let times_x = |p: &[f64]| -> Vec<f64> {
        let mut r = vec![0.0; p.len() + 1];
        r[1..].copy_from_slice(p);
        r
    };
    let m0 = m[0];
    let mut alphas = Vec::with_capacity(n);
    let mut betas = Vec::with_capacity(n); // betas[k] = ||π_k||² / ||π_{k−1}||², k ≥ 1
    let mut prev: Vec<f64> = vec![];
    let mut cur: Vec<f64> = vec![1.0];
    let mut cur_norm = m0;
    let mut prev_norm = 0.0;
    for k in 0..n {
        if k > 0 {
            if cur_norm < -DEGENERATE_NORM * m0 {
                return Err(QuadratureError::NotMoments(format!("negative norm {cur_norm} of π_{k}")));
            }
            if cur_norm <= DEGENERATE_NORM * m0 {
                break; // k atoms: the k-node rule is exact
            }
            betas.push(cur_norm / prev_norm);
        }
        let xc = times_x(&cur);
        let a = inner(&xc, &cur) / cur_norm;
        alphas.push(a);
        // π_{k+1} = (x − a)π_k − β_k π_{k−1}
        let mut next = xc;
        for (i, c) in cur.iter().enumerate() {
            next[i] -= a * c;
        }
        if k > 0 {
            let b = *betas.last().unwrap_or(&0.0);
            for (i, c) in prev.iter().enumerate() {
                next[i] -= b * c;
            }
        }
        // only norms of degree ≤ n−1 polynomials are needed (moments up to 2n−2 for the
        // norm, 2n−1 for the next alpha)
        if k + 1 < n {
            prev_norm = cur_norm;
            cur_norm = inner(&next, &next);
        }
        prev = cur;
        cur = next;
    }
    // an eigen-decomposition of a matrix with NaN may not terminate: refuse it first
    if alphas.iter().chain(&betas).any(|x| !x.is_finite()) || betas.iter().any(|&b| b < 0.0) {
        return Err(QuadratureError::NotMoments("recurrence coefficients are not finite".into()));
    }
    let k = alphas.len();
    let mut j = DMatrix::<f64>::zeros(k, k);
    for i in 0..k {
        j[(i, i)] = alphas[i];
        if i + 1 < k {
            let b = betas[i].sqrt();
            j[(i, i + 1)] = b;
            j[(i + 1, i)] = b;
        }
    }
    let eig = SymmetricEigen::new(j);
    let nodes: Vec<f64> = eig.eigenvalues.iter().copied().collect();
    let weights: Vec<f64> = (0..k).map(|c| m0 * eig.eigenvectors[(0, c)].powi(2)).collect();
    Ok(Rule { nodes, weights })
}

/// Moments of z = (w − c)/s from raw moments of w, with c the mean and s the standard
/// deviation (binomial expansion of E[(w − c)^k]).
pub fn standardise(raw: &[f64]) -> Result<(f64, f64, Vec<f64>), QuadratureError> {
    if raw.len() < 3 {
        return Err(QuadratureError::NotMoments(format!("{} raw moments given, at least 3 needed", raw.len())));
    }
    let c = raw[1];
    let var = raw[2] - c * c;
    if var.is_nan() || var < 0.0 {
        return Err(QuadratureError::NotMoments(format!("variance {var} < 0")));
    }
    let s = var.sqrt();
    if s == 0.0 {
        let mut z = vec![0.0; raw.len()];
        z[0] = 1.0;
        return Ok((c, 0.0, z));
    }
    let mut z = Vec::with_capacity(raw.len());
    for k in 0..raw.len() {
        let mut sum = 0.0;
        let mut binom = 1.0;
        for (j, mj) in raw.iter().enumerate().take(k + 1) {
            sum += binom * mj * (-c).powi((k - j) as i32);
            binom = binom * (k - j) as f64 / (j + 1) as f64;
        }
        z.push(sum / s.powi(k as i32));
    }
    Ok((c, s, z))
}

/// Maps a rule for z onto w = c + s·z.
fn affine(r: Rule, c: f64, s: f64) -> Rule {
    Rule { nodes: r.nodes.iter().map(|z| c + s * z).collect(), weights: r.weights }
}

/// A rule for a standardised variable given its raw moments m₀..m₍₂ₙ₋₁₎: standardise,
/// build, map back.
fn from_raw(raw: &[f64]) -> Result<Rule, QuadratureError> {
    let (c, s, z) = standardise(raw)?;
    if s == 0.0 {
        return Ok(Rule { nodes: vec![c], weights: vec![1.0] });
    }
    Ok(affine(gauss_from_moments(&z, NODES)?, c, s))
}

/// Raw moments m₀..m₍ₖ₎ of Beta(α, β) on [0, 1]: m_j = Π_{i<j} (α + i)/(α + β + i).
pub fn beta_raw(alpha: f64, beta: f64, k: usize) -> Vec<f64> {
    let mut m = vec![1.0];
    for i in 0..k {
        let prev = m[i];
        m.push(prev * (alpha + i as f64) / (alpha + beta + i as f64));
    }
    m
}

/// Raw moments m₀..m₍ₖ₎ of Gamma(shape κ, scale 1): m_j = κ(κ+1)…(κ+j−1).
pub fn gamma_raw(shape: f64, k: usize) -> Vec<f64> {
    let mut m = vec![1.0];
    for i in 0..k {
        let prev = m[i];
        m.push(prev * (shape + i as f64));
    }
    m
}

/// The oracle's rule for one distribution.
pub fn rule(d: &Dist) -> Result<Rule, QuadratureError> {
    let k = 2 * NODES - 1; // highest moment the rule needs
    match d {
        Dist::Uniform { low, high } => {
            if low.partial_cmp(high) != Some(std::cmp::Ordering::Less) {
                return Err(bad("uniform", "low must be < high"));
            }
            // z ~ U[−1, 1]: E[z^j] = 1/(j+1) for even j, 0 for odd j.
            let z: Vec<f64> = (0..=k).map(|j| if j % 2 == 0 { 1.0 / (j + 1) as f64 } else { 0.0 }).collect();
            Ok(affine(gauss_from_moments(&z, NODES)?, 0.5 * (low + high), 0.5 * (high - low)))
        }
        Dist::Normal { mean, std } => {
            if std.is_nan() || *std < 0.0 {
                return Err(bad("normal", "std must be ≥ 0"));
            }
            if *std == 0.0 {
                return Ok(Rule { nodes: vec![*mean], weights: vec![1.0] });
            }
            // standard normal: E[z^j] = (j−1)!! for even j, 0 for odd j.
            let z: Vec<f64> =
                (0..=k).map(|j| if j % 2 == 0 { (1..j).step_by(2).map(|i| i as f64).product() } else { 0.0 }).collect();
            Ok(affine(gauss_from_moments(&z, NODES)?, *mean, *std))
        }
        Dist::Beta { alpha, beta, low, high } => {
            if !(*alpha > 0.0 && *beta > 0.0 && low < high) {
                return Err(bad("beta", "needs α > 0, β > 0, low < high"));
            }
            let r = from_raw(&beta_raw(*alpha, *beta, k))?;
            Ok(affine(r, *low, high - low))
        }
        Dist::Gamma { shape, scale } => {
            if !(*shape > 0.0 && *scale > 0.0) {
                return Err(bad("gamma", "needs shape > 0, scale > 0"));
            }
            Ok(affine(from_raw(&gamma_raw(*shape, k))?, 0.0, *scale))
        }
        Dist::Exponential { rate } => {
            if rate.is_nan() || *rate <= 0.0 {
                return Err(bad("exponential", "needs rate > 0"));
            }
            Ok(affine(from_raw(&gamma_raw(1.0, k))?, 0.0, 1.0 / rate))
        }
        Dist::Laplace { mean, scale } => {
            if scale.is_nan() || *scale <= 0.0 {
                return Err(bad("laplace", "needs scale > 0"));
            }
            // standard Laplace (b = 1): E[z^j] = j! for even j, 0 for odd j.
            let z: Vec<f64> =
                (0..=k).map(|j| if j % 2 == 0 { (1..=j).map(|i| i as f64).product() } else { 0.0 }).collect();
            Ok(affine(gauss_from_moments(&z, NODES)?, *mean, *scale))
        }
        Dist::Discrete { values, weights } => {
            if values.is_empty() || values.len() != weights.len() || weights.iter().any(|w| w.is_nan() || *w < 0.0) {
                return Err(bad("discrete", "needs as many non-negative weights as values"));
            }
            // The atoms themselves are an exact rule.
            let total: f64 = weights.iter().sum();
            Ok(Rule { nodes: values.clone(), weights: weights.iter().map(|w| w / total).collect() })
        }
        Dist::Moments { raw, .. } => {
            if raw.len() < k {
                return Err(bad("moments", format!("{} raw moments listed, {k} needed", raw.len())));
            }
            let mut m = vec![1.0];
            m.extend(raw.iter().take(k).map(|&(p, q)| p as f64 / q as f64));
            from_raw(&m)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-300)
    }

    /// E[w^4] and E[w^5] of each family against closed forms.
    #[test]
    fn quadrature_moments_match_closed_forms() {
        let (a, b) = (0.3, 1.7);
        let (mu, s) = (-0.4, 0.7);
        let (al, be, lo, hi): (f64, f64, f64, f64) = (2.5, 1.5, -1.0, 2.0);
        let (k, th) = (2.5, 0.8);
        let lam = 1.7;
        let fact = |n: u32| (1..=n).map(|i| i as f64).product::<f64>();
        // Beta on [lo, hi]: E[(lo + (hi−lo)Y)^4] expanded with raw moments of Y.
        let by = beta_raw(al, be, 5);
        let beta4: f64 = (0..=4)
            .map(|j| {
                let c = fact(4) / (fact(j) * fact(4 - j));
                c * lo.powi(4 - j as i32) * (hi - lo).powi(j as i32) * by[j as usize]
            })
            .sum();
        let cases: Vec<(Dist, f64)> = vec![
            (Dist::Uniform { low: a, high: b }, (b.powi(5) - a.powi(5)) / (5.0 * (b - a))),
            (Dist::Normal { mean: mu, std: s }, mu.powi(4) + 6.0 * mu * mu * s * s + 3.0 * s.powi(4)),
            (Dist::Beta { alpha: al, beta: be, low: lo, high: hi }, beta4),
            (Dist::Gamma { shape: k, scale: th }, th.powi(4) * k * (k + 1.0) * (k + 2.0) * (k + 3.0)),
            (Dist::Exponential { rate: lam }, 24.0 / lam.powi(4)),
            (Dist::Laplace { mean: mu, scale: s }, mu.powi(4) + 12.0 * mu * mu * s * s + 24.0 * s.powi(4)),
            (
                Dist::Discrete { values: vec![-1.0, 0.5, 2.0, 3.0], weights: vec![0.1, 0.2, 0.3, 0.4] },
                0.1 + 0.2 * 0.0625 + 0.3 * 16.0 + 0.4 * 81.0,
            ),
        ];
        for (d, e4) in cases {
            let r = rule(&d).unwrap();
            assert!(close(r.expect(|w| w.powi(4)), e4, 1e-10), "{d:?}: {} vs {e4}", r.expect(|w| w.powi(4)));
            assert!(close(r.weights.iter().sum::<f64>(), 1.0, 1e-12));
        }
        // moments list of U[a, b] written as exact fractions: E[w^5] too (degree 2n−1).
        let d = Dist::moments_of_uniform(-3, 5, 20);
        let r = rule(&d).unwrap();
        let (lo, hi): (f64, f64) = (-3.0 / 20.0, 5.0 / 20.0);
        for p in 1..=5 {
            let exact = (hi.powi(p + 1) - lo.powi(p + 1)) / ((p + 1) as f64 * (hi - lo));
            assert!(close(r.expect(|w| w.powi(p)), exact, 1e-9), "moments E[w^{p}]");
        }
        // degree-5 exactness for the normal: E[w^5] = μ^5 + 10μ³σ² + 15μσ⁴
        let r = rule(&Dist::Normal { mean: mu, std: s }).unwrap();
        let e5 = mu.powi(5) + 10.0 * mu.powi(3) * s * s + 15.0 * mu * s.powi(4);
        assert!(close(r.expect(|w| w.powi(5)), e5, 1e-10));
    }

    #[test]
    fn degenerate_and_bad_inputs() {
        let r = rule(&Dist::Normal { mean: 2.0, std: 0.0 }).unwrap();
        assert_eq!(r.nodes, vec![2.0]);
        // two atoms given as raw moments: a 2-node rule, still exact
        let raw = [1.0, 0.5, 0.5, 0.5, 0.5, 0.5]; // Bernoulli(1/2)
        let r = from_raw(&raw).unwrap();
        assert_eq!(r.nodes.len(), 2);
        assert!(close(r.expect(|w| w.powi(4)), 0.5, 1e-9));
        assert!(rule(&Dist::Gamma { shape: -1.0, scale: 1.0 }).is_err());
        assert!(standardise(&[1.0, 1.0, 0.5]).is_err());
        // too few or non-finite moments: errors, never an index panic or a NaN matrix
        assert!(standardise(&[1.0]).is_err());
        assert!(gauss_from_moments(&[], 0).is_err());
        assert!(gauss_from_moments(&[1.0, f64::NAN, 1.0, 0.0], 2).is_err());
        assert!(gauss_from_moments(&[-1.0, 0.0, 1.0, 0.0], 2).is_err());
    }
}
