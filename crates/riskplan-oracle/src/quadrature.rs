//! Gauss quadrature rules for the oracle, built from its **own** closed-form moments of
//! each distribution family (never from `riskplan::moments`).
//!
//! A rule with `n` nodes integrates polynomials of degree ≤ 2n − 1 exactly. The oracle
//! needs E\[P\] and E\[P²\] with P of degree ≤ 2 in each parameter, so P² has degree ≤ 4:
//! [`NODES`] = 3 nodes (exact to degree 5) suffice. The rule of a family is built for a
//! *standardised* variable z (mean 0, variance 1, or a fixed standard form) by the
//! Stieltjes procedure on its moments and the Golub–Welsch eigen-decomposition of the
//! Jacobi matrix, then mapped affinely onto the parameter (w = c + s·z keeps weights
//! and moves nodes), which keeps the Hankel moments well conditioned however far the
//! parameter sits from 0.
//!
//! Rules of any size ([`rule_with_nodes`], [`rule_exact_to`], up to [`MAX_NODES`]) for
//! the risk-bound oracle ([`super::bounds`], which integrates P⁸): built from the
//! families' closed-form three-term recurrences rather than from moments (Golub–Welsch
//! with Newton-polished nodes and Christoffel weights, [`jacobi_rule`]); the Laplace
//! recurrence by the discretised Stieltjes procedure; moments lists by Chebyshev's
//! algorithm on their standardised moments, with a check that the rule reproduces them.
//! Measured at n = 9 (`rule_with_nodes_is_exact_to_degree_2n_minus_1`, `--nocapture`):
//! every E[z^j], j ≤ 17, of the standard forms within ~2e-15 relative for the recurrence
//! families and ~2e-14 for moments lists.

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

/// A quadrature rule: Σ weights\[i\]·f(nodes\[i\]) ≈ E\[f(w)\].
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
    /// A node count outside 1 ..= [`MAX_NODES`].
    #[error("{n} nodes asked for; 1 to {max} are built")]
    BadNodeCount {
        /// The count asked for.
        n: usize,
        /// [`MAX_NODES`].
        max: usize,
    },
    /// A moments list too short for the rule asked for.
    #[error("{listed} raw moments listed, {needed} needed")]
    NotEnoughMoments {
        /// How many are listed (E\[w\] … E\[w^listed\]).
        listed: usize,
        /// How many the rule needs.
        needed: usize,
    },
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
        Dist::RawMoments { raw } => {
            if raw.len() < k {
                return Err(bad("moments", format!("{} raw moments listed, {k} needed", raw.len())));
            }
            let mut m = vec![1.0];
            m.extend(raw.iter().take(k));
            from_raw(&m)
        }
    }
}

/// Largest node count [`rule_with_nodes`] builds (exact to degree 2·16 − 1 = 31).
pub const MAX_NODES: usize = 16;

/// Largest Newton step that [`jacobi_rule`] accepts when polishing an eigenvalue, relative
/// to the spread of the Jacobi matrix (max |α| + 2·max √β). The symmetric QR algorithm
/// gives every eigenvalue to about 1e-15 of that scale already; a proposed correction
/// many orders larger means the Newton iteration left the root's basin (a nearly
/// degenerate matrix), and the eigenvalue is kept as it is.
pub const POLISH_MAX_STEP: f64 = 1e-8;

/// Newton steps per node in [`jacobi_rule`] (each roughly doubles the correct digits;
/// the first starts at ~1e-15 relative).
pub const POLISH_STEPS: usize = 3;

/// Gauss rule of a probability measure from its recurrence coefficients (Golub–Welsch):
/// `alphas` = α₀…α₍ₙ₋₁₎, `betas` = β₁…β₍ₙ₋₁₎ of the monic orthogonal polynomials
/// π₍ₖ₊₁₎ = (x − αₖ)πₖ − βₖπ₍ₖ₋₁₎. The nodes are the eigenvalues of the symmetric
/// tridiagonal Jacobi matrix J (diagonal αₖ, off-diagonal √βₖ), each polished by Newton
/// steps on πₙ evaluated through the orthonormal recurrence. The weights are the
/// Christoffel numbers wᵢ = 1 / Σₖ₌₀ⁿ⁻¹ p̃ₖ(xᵢ)² (p̃ₖ orthonormal), which keep full
/// relative accuracy even for the tiny weights of far nodes (the textbook "first
/// eigenvector component squared" is only accurate to ~1e-16 absolute), then normalised
/// to sum to 1.
pub fn jacobi_rule(alphas: &[f64], betas: &[f64]) -> Result<Rule, QuadratureError> {
    let n = alphas.len();
    if n == 0 || betas.len() + 1 < n {
        return Err(QuadratureError::NotMoments(format!(
            "{n} diagonal and {} off-diagonal recurrence coefficients",
            betas.len()
        )));
    }
    let betas = &betas[..n - 1];
    if alphas.iter().chain(betas).any(|x| !x.is_finite()) || betas.iter().any(|&b| b <= 0.0) {
        return Err(QuadratureError::NotMoments("recurrence coefficients not finite or β ≤ 0".into()));
    }
    let sqrt_b: Vec<f64> = betas.iter().map(|b| b.sqrt()).collect();
    let mut j = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        j[(i, i)] = alphas[i];
        if i + 1 < n {
            j[(i, i + 1)] = sqrt_b[i];
            j[(i + 1, i)] = sqrt_b[i];
        }
    }
    let scale = alphas.iter().fold(0.0f64, |m, a| m.max(a.abs())) + 2.0 * sqrt_b.iter().fold(0.0f64, |m, b| m.max(*b));
    let eig = SymmetricEigen::new(j);
    let mut nodes: Vec<f64> = eig.eigenvalues.iter().copied().collect();
    nodes.sort_by(f64::total_cmp);
    // p̃₀…p̃₍ₙ₋₁₎ at x, and q = (x − α₍ₙ₋₁₎)p̃₍ₙ₋₁₎ − √β₍ₙ₋₁₎ p̃₍ₙ₋₂₎ ∝ πₙ(x) with its derivative
    let eval = |x: f64| -> (f64, f64, f64) {
        let (mut p_prev, mut p) = (0.0, 1.0);
        let (mut d_prev, mut d) = (0.0, 0.0);
        let mut sum_sq = 1.0;
        for k in 0..n {
            let b_k = if k == 0 { 0.0 } else { sqrt_b[k - 1] };
            let q = (x - alphas[k]) * p - b_k * p_prev;
            let dq = p + (x - alphas[k]) * d - b_k * d_prev;
            if k + 1 == n {
                return (q, dq, sum_sq);
            }
            let norm = sqrt_b[k];
            (p_prev, p) = (p, q / norm);
            (d_prev, d) = (d, dq / norm);
            sum_sq += p * p;
        }
        (f64::NAN, f64::NAN, sum_sq)
    };
    let mut weights = Vec::with_capacity(n);
    for x in nodes.iter_mut() {
        for _ in 0..POLISH_STEPS {
            let (q, dq, _) = eval(*x);
            let step = q / dq;
            if !step.is_finite() || step.abs() > POLISH_MAX_STEP * scale || step == 0.0 {
                break;
            }
            *x -= step;
        }
        weights.push(1.0 / eval(*x).2);
    }
    let total: f64 = weights.iter().sum();
    if !(total.is_finite() && total > 0.0) || nodes.iter().any(|x| !x.is_finite()) {
        return Err(QuadratureError::NotMoments("the Jacobi matrix gives no finite rule".into()));
    }
    for w in weights.iter_mut() {
        *w /= total;
    }
    Ok(Rule { nodes, weights })
}

/// Recurrence coefficients from raw moments m₀…m_M of a (preferably standardised)
/// variable by Chebyshev's algorithm (Gautschi, *Orthogonal Polynomials*, 2004, §2.1.7)
/// on the table σₖ,ₗ = E[πₖ(w)·wˡ]: σ₀,ₗ = mₗ,
/// σₖ,ₗ = σₖ₋₁,ₗ₊₁ − αₖ₋₁σₖ₋₁,ₗ − βₖ₋₁σₖ₋₂,ₗ,
/// αₖ = σₖ,ₖ₊₁/σₖ,ₖ − σₖ₋₁,ₖ/σₖ₋₁,ₖ₋₁, βₖ = σₖ,ₖ/σₖ₋₁,ₖ₋₁.
/// Returns (α₀…, β₁…): every αₖ with 2k + 1 ≤ M and every βₖ with 2k ≤ M, stopping early
/// when βₖ ≤ [`DEGENERATE_NORM`] (the measure has k atoms: k nodes are exact for every
/// degree; then exactly k alphas and k − 1 betas). The conditioning grows exponentially
/// with M (that of the Hankel matrix): for standardised variables and M ≤ 17 a few
/// digits are lost, not all (measured in the tests).
pub fn recurrence_from_moments(m: &[f64]) -> Result<(Vec<f64>, Vec<f64>), QuadratureError> {
    if m.len() < 2 {
        return Err(QuadratureError::NotMoments(format!("{} moments given, at least m₀ and m₁ needed", m.len())));
    }
    if m.iter().any(|x| !x.is_finite()) || m[0] <= 0.0 {
        return Err(QuadratureError::NotMoments("a moment is not finite, or m₀ ≤ 0".into()));
    }
    let top = m.len() - 1; // M
    let mut alphas = vec![m[1] / m[0]];
    let mut betas: Vec<f64> = Vec::new();
    let mut older = vec![0.0; m.len()]; // σ₍ₖ₋₂₎
    let mut prev = m.to_vec(); // σ₍ₖ₋₁₎
    let mut beta_prev = m[0]; // β₀ = m₀ multiplies σ₋₁ = 0
    let mut k = 1;
    while 2 * k <= top {
        let mut cur = vec![0.0; m.len()];
        for l in k..=top - k {
            cur[l] = prev[l + 1] - alphas[k - 1] * prev[l] - beta_prev * older[l];
        }
        let beta = cur[k] / prev[k - 1];
        if !beta.is_finite() || beta < -DEGENERATE_NORM {
            return Err(QuadratureError::NotMoments(format!("β_{k} = {beta} < 0")));
        }
        if beta <= DEGENERATE_NORM {
            break; // k atoms
        }
        betas.push(beta);
        if 2 * k < top {
            alphas.push(cur[k + 1] / cur[k] - prev[k] / prev[k - 1]);
        } else {
            break;
        }
        older = prev;
        prev = cur;
        beta_prev = beta;
        k += 1;
    }
    if alphas.iter().chain(&betas).any(|x| !x.is_finite()) {
        return Err(QuadratureError::NotMoments("recurrence coefficients are not finite".into()));
    }
    Ok((alphas, betas))
}

/// A rule for raw moments m₀…m_M (m₀ = 1) of any variable, exact for polynomials of
/// degree ≤ `degree` (≤ M): standardised (mean 0, variance 1, [`standardise`]), Chebyshev's
/// algorithm, Golub–Welsch, mapped back. Odd `degree` = 2n − 1: the n-node Gauss rule.
/// Even `degree` = 2n: n + 1 nodes from α₀…α₍ₙ₋₁₎, β₁…βₙ (which mₙ… m₂ₙ determine) and a
/// free last diagonal entry αₙ := 0 (the standardised mean): any real αₙ gives a
/// symmetric Jacobi matrix with positive weights whose rule matches m₀…m₂ₙ — the
/// moment m₂ₙ₊₁ is the only one that αₙ changes. Fewer nodes when the moments are those
/// of fewer atoms (then exact for every degree).
pub fn rule_from_raw_moments(raw: &[f64], degree: usize) -> Result<Rule, QuadratureError> {
    if raw.len() < degree + 1 || raw.len() < 3 {
        return Err(QuadratureError::NotMoments(format!(
            "{} moments given (with m₀), {} needed",
            raw.len(),
            (degree + 1).max(3)
        )));
    }
    let (c, s, z) = standardise(&raw[..(degree + 1).max(3)])?;
    if s == 0.0 {
        return Ok(Rule { nodes: vec![c], weights: vec![1.0] });
    }
    let (mut alphas, betas) = recurrence_from_moments(&z[..degree + 1])?;
    // as many betas as alphas only for an even degree without early stop (atoms)
    if betas.len() == alphas.len() {
        alphas.push(0.0);
    }
    let r = affine(jacobi_rule(&alphas, &betas)?, c, s);
    // The check that the rule reproduces the listed moments: standardising raw moments
    // of a variable whose mean is large against its spread cancels digits (the error of
    // the j-th standardised moment grows like (|mean|/sd)^j·ε), which can give a wrong
    // rule without any negative β to show it.
    for (j, mj) in raw.iter().enumerate().take(degree + 1) {
        let (q, scale) = r.nodes.iter().zip(&r.weights).fold((0.0, 0.0), |(q, a), (x, w)| {
            let t = w * powi_u(*x, j);
            (q + t, a + t.abs())
        });
        let err = (q - mj).abs();
        if err.is_nan() || err > MOMENT_CHECK_TOL * scale.max(mj.abs()) {
            return Err(QuadratureError::NotMoments(format!(
                "the rule reproduces E[w^{j}] = {mj:e} only as {q:e} (f64 cancellation, or not moments)"
            )));
        }
    }
    Ok(r)
}

/// x^j for a usize exponent (the moment checks; j ≤ 2·[`MAX_NODES`]).
fn powi_u(x: f64, j: usize) -> f64 {
    x.powi(i32::try_from(j).unwrap_or(i32::MAX))
}

/// Relative tolerance of the check that a rule built from a moments list reproduces
/// every listed moment it is meant to be exact for, against Σ wᵢ|xᵢ|^j (the size of
/// the terms). Measured reproduction is ~1e-14 for well-conditioned lists; 1e-10 lets
/// those pass and refuses rules that cancellation has made wrong.
pub const MOMENT_CHECK_TOL: f64 = 1e-10;

/// Recurrence coefficients of the standard Laplace distribution (density e^{−|z|}/2),
/// α₀…α₍ₙ₋₁₎ (all 0: symmetric) and β₁…β₍ₙ₋₁₎, by the discretised Stieltjes procedure
/// (Gautschi 2004, §2.2.3): |z| ~ Exp(1), so the n-node Gauss–Laguerre rule
/// (α = 2k + 1, β = k², polished, [`jacobi_rule`]) mirrored to ±nodes with halved
/// weights is a 2n-point measure with the Laplace moments up to degree 2n − 1 — exactly
/// the moments that αₖ, βₖ for k < n depend on. Stieltjes on it: βₖ = ‖πₖ‖²/‖πₖ₋₁‖²,
/// π₍ₖ₊₁₎ = x·πₖ − βₖπ₍ₖ₋₁₎, evaluated at the points. Unlike the Chebyshev algorithm
/// on the moments k!, no cancellation grows with n.
fn laplace_recurrence(n: usize) -> Result<(Vec<f64>, Vec<f64>), QuadratureError> {
    let la: Vec<f64> = (0..n).map(|k| 2.0 * k as f64 + 1.0).collect();
    let lb: Vec<f64> = (1..n).map(|k| (k * k) as f64).collect();
    let lag = jacobi_rule(&la, &lb)?;
    let pts: Vec<f64> = lag.nodes.iter().flat_map(|&x| [x, -x]).collect();
    let wts: Vec<f64> = lag.weights.iter().flat_map(|&w| [0.5 * w, 0.5 * w]).collect();
    // π₋₁ = 0, π₀ = 1 at the points; ‖π₀‖² = 1
    let mut p_prev = vec![0.0; pts.len()];
    let mut p = vec![1.0; pts.len()];
    let mut norm = 1.0;
    let mut betas: Vec<f64> = Vec::with_capacity(n.saturating_sub(1));
    for k in 0..n.saturating_sub(1) {
        let beta_k = if k == 0 { 0.0 } else { betas[k - 1] };
        let next: Vec<f64> = pts.iter().zip(p.iter().zip(&p_prev)).map(|(x, (a, b))| x * a - beta_k * b).collect();
        let norm_next: f64 = wts.iter().zip(&next).map(|(w, v)| w * v * v).sum();
        betas.push(norm_next / norm); // β₍ₖ₊₁₎
        norm = norm_next;
        p_prev = std::mem::replace(&mut p, next);
    }
    Ok((vec![0.0; n], betas))
}

/// Recurrence coefficients of Beta(α, β) on [−1, 1], i.e. the Jacobi weight
/// (1 − x)^a (1 + x)^b with a = β − 1, b = α − 1 (closed form, Gautschi 2004, Table 1.1):
/// α₀ = (b − a)/(a + b + 2), αₖ = (b − a)(b + a)/((2k + a + b)(2k + a + b + 2)),
/// β₁ = 4(1 + a)(1 + b)/((2 + a + b)²(3 + a + b)),
/// βₖ = 4k(k + a)(k + b)(k + a + b)/((2k + a + b)²(2k + a + b + 1)(2k + a + b − 1)), k ≥ 2.
fn jacobi_recurrence(alpha: f64, beta: f64, n: usize) -> (Vec<f64>, Vec<f64>) {
    let (a, b) = (beta - 1.0, alpha - 1.0);
    let mut al = Vec::with_capacity(n);
    let mut be = Vec::with_capacity(n.saturating_sub(1));
    for k in 0..n {
        let kf = k as f64;
        let s = 2.0 * kf + a + b;
        al.push(if k == 0 { (b - a) / (a + b + 2.0) } else { (b - a) * (b + a) / (s * (s + 2.0)) });
        if k >= 1 {
            be.push(if k == 1 {
                4.0 * (1.0 + a) * (1.0 + b) / ((2.0 + a + b).powi(2) * (3.0 + a + b))
            } else {
                4.0 * kf * (kf + a) * (kf + b) * (kf + a + b) / (s * s * (s + 1.0) * (s - 1.0))
            });
        }
    }
    (al, be)
}

/// The oracle's n-node Gauss rule for one distribution: exact for polynomials of degree
/// ≤ 2n − 1 in the parameter, 1 ≤ n ≤ [`MAX_NODES`]. Built from closed-form three-term
/// recurrences (Golub–Welsch with polished nodes and Christoffel weights,
/// [`jacobi_rule`]) for a standard form, then mapped affinely onto the parameter:
///
/// * uniform: Legendre on [−1, 1], αₖ = 0, βₖ = k²/(4k² − 1);
/// * normal: probabilists' Hermite, αₖ = 0, βₖ = k (std 0: one node at the mean);
/// * beta: Jacobi on [−1, 1] (`jacobi_recurrence`), then onto [low, high];
/// * gamma: generalised Laguerre for Gamma(shape κ, 1), αₖ = 2k + κ, βₖ = k(k + κ − 1),
///   nodes times the scale; exponential: κ = 1, scale 1/rate;
/// * laplace: discretised Stieltjes on the mirrored Gauss–Laguerre rule
///   (`laplace_recurrence`), times the scale;
/// * discrete: the atoms themselves (exact for every degree, whatever n);
/// * moments: Chebyshev's algorithm on the listed moments only
///   ([`rule_from_raw_moments`]); needs 2n − 1 listed moments (E(w) … E(w^{2n−1})).
pub fn rule_with_nodes(d: &Dist, n: usize) -> Result<Rule, QuadratureError> {
    if n == 0 || n > MAX_NODES {
        return Err(QuadratureError::BadNodeCount { n, max: MAX_NODES });
    }
    let jacobi = |al: Vec<f64>, be: Vec<f64>, c: f64, s: f64| Ok(affine(jacobi_rule(&al, &be)?, c, s));
    match d {
        Dist::Uniform { low, high } => {
            if low.partial_cmp(high) != Some(std::cmp::Ordering::Less) || !(high - low).is_finite() {
                return Err(bad("uniform", "low must be < high, both finite"));
            }
            let be = (1..n).map(|k| (k * k) as f64 / (4.0 * (k * k) as f64 - 1.0)).collect();
            jacobi(vec![0.0; n], be, 0.5 * low + 0.5 * high, 0.5 * (high - low))
        }
        Dist::Normal { mean, std } => {
            if !(mean.is_finite() && std.is_finite() && *std >= 0.0) {
                return Err(bad("normal", "needs a finite mean and a finite std ≥ 0"));
            }
            if *std == 0.0 {
                return Ok(Rule { nodes: vec![*mean], weights: vec![1.0] });
            }
            jacobi(vec![0.0; n], (1..n).map(|k| k as f64).collect(), *mean, *std)
        }
        Dist::Beta { alpha, beta, low, high } => {
            if !(positive(*alpha) && positive(*beta) && low < high && (high - low).is_finite()) {
                return Err(bad("beta", "needs finite α > 0, β > 0, low < high"));
            }
            let (al, be) = jacobi_recurrence(*alpha, *beta, n);
            jacobi(al, be, 0.5 * low + 0.5 * high, 0.5 * (high - low))
        }
        Dist::Gamma { shape, scale } => {
            if !(positive(*shape) && positive(*scale)) {
                return Err(bad("gamma", "needs finite shape > 0, scale > 0"));
            }
            let al = (0..n).map(|k| 2.0 * k as f64 + shape).collect();
            let be = (1..n).map(|k| k as f64 * (k as f64 + shape - 1.0)).collect();
            jacobi(al, be, 0.0, *scale)
        }
        Dist::Exponential { rate } => {
            if !positive(*rate) {
                return Err(bad("exponential", "needs a finite rate > 0"));
            }
            let al = (0..n).map(|k| 2.0 * k as f64 + 1.0).collect();
            let be = (1..n).map(|k| (k * k) as f64).collect();
            jacobi(al, be, 0.0, 1.0 / rate)
        }
        Dist::Laplace { mean, scale } => {
            if !(positive(*scale) && mean.is_finite()) {
                return Err(bad("laplace", "needs a finite mean and a finite scale > 0"));
            }
            let (al, be) = laplace_recurrence(n)?;
            jacobi(al, be, *mean, *scale)
        }
        Dist::Discrete { values, weights } => discrete_rule(values, weights),
        Dist::Moments { raw, .. } => {
            let mut m = vec![1.0];
            m.extend(raw.iter().map(|&(p, q)| p as f64 / q as f64));
            moments_gauss(&m, n)
        }
        Dist::RawMoments { raw } => {
            let mut m = vec![1.0];
            m.extend(raw.iter().copied());
            moments_gauss(&m, n)
        }
    }
}

/// x finite and > 0.
fn positive(x: f64) -> bool {
    x > 0.0 && x.is_finite()
}

/// The n-node Gauss rule of a moments list m₀…m_M: needs M ≥ 2n − 1.
fn moments_gauss(m: &[f64], n: usize) -> Result<Rule, QuadratureError> {
    if m.len() < 2 * n {
        return Err(QuadratureError::NotEnoughMoments { listed: m.len() - 1, needed: 2 * n - 1 });
    }
    rule_from_raw_moments(m, 2 * n - 1)
}

/// The atoms of a discrete distribution as a rule (weights normalised to sum 1).
fn discrete_rule(values: &[f64], weights: &[f64]) -> Result<Rule, QuadratureError> {
    if values.is_empty()
        || values.len() != weights.len()
        || weights.iter().any(|w| !w.is_finite() || *w < 0.0)
        || values.iter().any(|v| !v.is_finite())
    {
        return Err(bad("discrete", "needs as many finite non-negative weights as finite values"));
    }
    let total: f64 = weights.iter().sum();
    if !positive(total) {
        return Err(bad("discrete", "weights sum to 0"));
    }
    Ok(Rule { nodes: values.to_vec(), weights: weights.iter().map(|w| w / total).collect() })
}

/// A rule exact for polynomials of degree ≤ `degree` in the parameter: the atoms of a
/// discrete distribution and the single node of a normal with std 0 (exact for every
/// degree); for the other families but moments lists, [`rule_with_nodes`] with
/// ⌊degree/2⌋ + 1 nodes (error past [`MAX_NODES`]); for a moments list, [`rule_from_raw_moments`] (which needs only the
/// moments up to `degree`, one fewer than a Gauss rule when `degree` is even).
pub fn rule_exact_to(d: &Dist, degree: usize) -> Result<Rule, QuadratureError> {
    let n = degree / 2 + 1;
    let raw: Option<Vec<f64>> = match d {
        Dist::Moments { raw, .. } => Some(raw.iter().map(|&(p, q)| p as f64 / q as f64).collect()),
        Dist::RawMoments { raw } => Some(raw.clone()),
        // exact for every degree whatever n: no node limit
        Dist::Discrete { values, weights } => return discrete_rule(values, weights),
        Dist::Normal { mean, std } if *std == 0.0 && mean.is_finite() => {
            return Ok(Rule { nodes: vec![*mean], weights: vec![1.0] })
        }
        _ => None,
    };
    match raw {
        Some(raw) => {
            if n > MAX_NODES {
                return Err(QuadratureError::BadNodeCount { n, max: MAX_NODES });
            }
            if raw.len() < degree {
                return Err(QuadratureError::NotEnoughMoments { listed: raw.len(), needed: degree });
            }
            if degree <= 1 {
                // one node at the mean is exact to degree 1
                return match raw.first() {
                    Some(&mean) if mean.is_finite() => Ok(Rule { nodes: vec![mean], weights: vec![1.0] }),
                    _ => Err(QuadratureError::NotEnoughMoments { listed: raw.len(), needed: 1 }),
                };
            }
            let mut m = vec![1.0];
            m.extend(raw);
            rule_from_raw_moments(&m, degree)
        }
        None => rule_with_nodes(d, n),
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

    /// Relative error of E[z^j], j = 0 … 2n − 1, under `r` against the closed-form
    /// moments `m` (m[0..=2n]): |Q_j − m_j| / scale_j, scale_j = m_j for even j and
    /// max(|m_j|, √(m_{j−1}·m_{j+1})) ≥ E|z|^j for odd j (Cauchy–Schwarz), so that odd
    /// moments that vanish are judged on the size of their terms.
    fn worst_moment_error(r: &Rule, m: &[f64], n: usize) -> (f64, usize) {
        let mut worst = (0.0, 0);
        for j in 0..2 * n {
            let q = r.expect(|z| z.powi(j as i32));
            let scale = if j % 2 == 0 { m[j].abs() } else { m[j].abs().max((m[j - 1] * m[j + 1]).sqrt()) };
            let e = (q - m[j]).abs() / scale;
            if e > worst.0 || e.is_nan() {
                worst = (e, j);
            }
        }
        worst
    }

    fn fact(j: usize) -> f64 {
        (1..=j).map(|i| i as f64).product()
    }

    /// The closed-form moments m₀ … m₂ₙ of each family's standard form, and the rule of
    /// that standard form (beta on [0, 1], gamma with scale 1, …).
    fn standard_cases(n: usize) -> Vec<(String, Dist, Vec<f64>)> {
        let k = 2 * n;
        let even = |f: &dyn Fn(usize) -> f64| (0..=k).map(|j| if j % 2 == 0 { f(j) } else { 0.0 }).collect::<Vec<_>>();
        let mut cases = vec![
            ("uniform[-1,1]".to_string(), Dist::Uniform { low: -1.0, high: 1.0 }, even(&|j| 1.0 / (j + 1) as f64)),
            (
                "normal(0,1)".into(),
                Dist::Normal { mean: 0.0, std: 1.0 },
                even(&|j| (1..j).step_by(2).map(|i| i as f64).product()),
            ),
            ("exponential(1)".into(), Dist::Exponential { rate: 1.0 }, (0..=k).map(fact).collect()),
            ("laplace(0,1)".into(), Dist::Laplace { mean: 0.0, scale: 1.0 }, even(&fact)),
        ];
        for (a, b) in [(2.5, 1.5), (9.0, 0.5), (0.5, 0.5), (3.0, 3.0), (1.0, 1.0)] {
            cases.push((
                format!("beta({a},{b})"),
                Dist::Beta { alpha: a, beta: b, low: 0.0, high: 1.0 },
                beta_raw(a, b, k),
            ));
        }
        for shape in [0.5, 1.0, 2.5, 7.0] {
            cases.push((format!("gamma({shape},1)"), Dist::Gamma { shape, scale: 1.0 }, gamma_raw(shape, k)));
        }
        let (v, w): (Vec<f64>, Vec<f64>) = (vec![-1.0, 0.25, 0.5, 2.0, 3.0], vec![0.1, 0.15, 0.2, 0.25, 0.3]);
        let disc: Vec<f64> = (0..=k).map(|j| v.iter().zip(&w).map(|(x, p)| p * x.powi(j as i32)).sum()).collect();
        cases.push(("discrete(5 atoms)".into(), Dist::Discrete { values: v, weights: w }, disc));
        // moments lists: exactly the moments the n-node rule needs (E[w] … E[w^{2n−1}])
        let uni: Vec<f64> = even(&|j| 1.0 / (j + 1) as f64);
        cases.push(("moments of uniform[-1,1]".into(), Dist::RawMoments { raw: uni[1..2 * n].to_vec() }, uni));
        let nor: Vec<f64> = even(&|j| (1..j).step_by(2).map(|i| i as f64).product());
        cases.push(("moments of normal(0,1)".into(), Dist::RawMoments { raw: nor[1..2 * n].to_vec() }, nor));
        let bet = beta_raw(2.0, 5.0, k);
        cases.push(("moments of beta(2,5)".into(), Dist::RawMoments { raw: bet[1..2 * n].to_vec() }, bet));
        cases
    }

    /// Every family's n-node rule against closed-form moments up to degree 2n − 1, n = 9
    /// (and n = 16 for the recurrence families), measured and printed (`--nocapture`).
    #[test]
    fn rule_with_nodes_is_exact_to_degree_2n_minus_1() {
        for n in [9usize, 3, 16] {
            for (name, d, m) in standard_cases(n) {
                let moments_list = matches!(d, Dist::RawMoments { .. });
                let r = match rule_with_nodes(&d, n) {
                    Ok(r) => r,
                    // 31 moments through a Hankel matrix: not claimed (an error or a rule)
                    Err(e) if moments_list && n == 16 => {
                        eprintln!("n = {n:2}  {name:28} refused: {e}");
                        continue;
                    }
                    Err(e) => panic!("{name}, n = {n}: {e}"),
                };
                let (e, j) = worst_moment_error(&r, &m, n);
                eprintln!("n = {n:2}  {name:28} worst relative error {e:.2e} (degree {j})");
                let tol = match (moments_list, n) {
                    (false, _) => RECURRENCE_TOL,
                    (true, 16) => continue,
                    (true, _) => MOMENTS_LIST_TOL,
                };
                assert!(e <= tol, "{name}, n = {n}: error {e:e} at degree {j}");
                assert_eq!(r.nodes.len(), if matches!(d, Dist::Discrete { .. }) { 5 } else { n });
                assert!(r.weights.iter().all(|w| *w > 0.0));
            }
        }
        // mapped parameters: central moments E[(w − c)^j] of N(μ, σ²) and Laplace(μ, b),
        // and raw moments of U[0.3, 0.4] (the affine map keeps the accuracy)
        let n = 9;
        let (mu, s) = (-3.7, 0.05);
        let r = rule_with_nodes(&Dist::Normal { mean: mu, std: s }, n).unwrap();
        for j in (0..2 * n).step_by(2) {
            let exact = s.powi(j as i32) * (1..j).step_by(2).map(|i| i as f64).product::<f64>();
            let q = r.expect(|w| (w - mu).powi(j as i32));
            assert!((q - exact).abs() <= 1e-11 * exact, "normal central moment {j}: {q} vs {exact}");
        }
        let r = rule_with_nodes(&Dist::Uniform { low: 0.3, high: 0.4 }, n).unwrap();
        for j in 0..2 * n {
            let p = j as i32 + 1;
            let exact = (0.4f64.powi(p) - 0.3f64.powi(p)) / (p as f64 * 0.1);
            let q = r.expect(|w| w.powi(j as i32));
            assert!((q - exact).abs() <= 1e-12 * exact, "uniform raw moment {j}: {q} vs {exact}");
        }
    }

    /// The Laplace rule through Chebyshev's algorithm on the moments j! (what
    /// `gauss_from_moments` does) against the discretised Stieltjes procedure used by
    /// [`rule_with_nodes`]: the moments route loses digits quickly with n.
    #[test]
    fn laplace_stieltjes_beats_the_moments_route() {
        for n in [5usize, 9] {
            let m: Vec<f64> = (0..=2 * n).map(|j| if j % 2 == 0 { fact(j) } else { 0.0 }).collect();
            let via_moments = gauss_from_moments(&m[..2 * n], n).unwrap();
            let via_stieltjes = rule_with_nodes(&Dist::Laplace { mean: 0.0, scale: 1.0 }, n).unwrap();
            let (em, _) = worst_moment_error(&via_moments, &m, n);
            let (es, _) = worst_moment_error(&via_stieltjes, &m, n);
            eprintln!("laplace n = {n}: moments route {em:.2e}, discretised Stieltjes {es:.2e}");
            assert!(es <= RECURRENCE_TOL);
        }
    }

    /// Measured worst error of the recurrence families at n ≤ 16 is a few 1e-14 (printed
    /// by the test above); 1e-12 leaves room for other platforms' `ln`/`sqrt`.
    const RECURRENCE_TOL: f64 = 1e-12;
    /// Moments lists go through Chebyshev's algorithm, whose conditioning grows
    /// exponentially with n: at n = 9 (17 moments) the measured worst error is ~2e-14
    /// (beta(2, 5), printed above); 1e-10 leaves a wide margin for other moment lists.
    const MOMENTS_LIST_TOL: f64 = 1e-10;

    #[test]
    fn rule_exact_to_even_degrees_from_moments() {
        // U[0.3, 0.4] given by E[w] … E[w⁴] only: a 3-node rule exact to degree 4
        let raw: Vec<f64> =
            (1..=4).map(|k| (0.4f64.powi(k + 1) - 0.3f64.powi(k + 1)) / ((k + 1) as f64 * 0.1)).collect();
        let r = rule_exact_to(&Dist::RawMoments { raw: raw.clone() }, 4).unwrap();
        assert_eq!(r.nodes.len(), 3);
        for (k, m) in raw.iter().enumerate() {
            let q = r.expect(|w| w.powi(k as i32 + 1));
            assert!((q - m).abs() <= 1e-12 * m, "E[w^{}] {q} vs {m}", k + 1);
        }
        assert!(r.weights.iter().all(|w| *w > 0.0));
        // not enough moments for degree 5; degree 1 needs only the mean
        assert!(matches!(
            rule_exact_to(&Dist::RawMoments { raw: raw.clone() }, 5),
            Err(QuadratureError::NotEnoughMoments { .. })
        ));
        assert_eq!(rule_exact_to(&Dist::RawMoments { raw: vec![0.35] }, 1).unwrap().nodes, vec![0.35]);
        // two atoms (Bernoulli ½) listed with many moments: two nodes, exact
        let r = rule_exact_to(&Dist::RawMoments { raw: vec![0.5; 8] }, 8).unwrap();
        assert_eq!(r.nodes.len(), 2);
        // other families: ⌊degree/2⌋ + 1 Gauss nodes
        assert_eq!(rule_exact_to(&Dist::Normal { mean: 0.0, std: 1.0 }, 16).unwrap().nodes.len(), 9);
        assert!(rule_exact_to(&Dist::Normal { mean: 0.0, std: 1.0 }, 32).is_err());
        // node counts out of range, non-moments
        assert!(matches!(
            rule_with_nodes(&Dist::Exponential { rate: 1.0 }, 0),
            Err(QuadratureError::BadNodeCount { .. })
        ));
        assert!(rule_with_nodes(&Dist::Exponential { rate: 1.0 }, 17).is_err());
        assert!(rule_with_nodes(&Dist::Uniform { low: 1.0, high: f64::NAN }, 3).is_err());
        assert!(rule_with_nodes(&Dist::RawMoments { raw: vec![0.0, -1.0, 0.0] }, 2).is_err());
        assert!(rule_with_nodes(&Dist::RawMoments { raw: vec![0.0, 1.0] }, 2).is_err());
        assert!(jacobi_rule(&[], &[]).is_err());
        assert!(jacobi_rule(&[0.0, 0.0], &[-1.0]).is_err());
        assert!(recurrence_from_moments(&[1.0, f64::NAN, 1.0]).is_err());
    }
}
