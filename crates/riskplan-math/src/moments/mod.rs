//! Distributions of uncertain parameters and their raw moments (layer L0).
//!
//! Every family of scene format v1 has rational moments when its parameters are
//! rational, so moments are computed exactly as [`BigRational`]s with the
//! recurrences of docs/design.md §2.1. This sidesteps the cancellation in
//! E\[P²\] − E\[P\]² that floats suffer when a mean dominates its spread (§1.4).
//! [`Sampler`] draws the same distributions with `rand_distr` for Monte Carlo.

pub mod cdf;
pub mod incomplete;
mod sample;

pub use sample::Sampler;

use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use thiserror::Error;

/// Tolerance on `|Σ weights − 1|` for a discrete distribution. Decimal weights such
/// as three times `0.3333333333333333` cannot sum to 1 exactly; within this
/// tolerance the weights are renormalised exactly (divided by their sum), beyond it
/// the scene is rejected. 1e-9 is far below any meaningful probability difference
/// yet well above the rounding of 17-digit decimals.
pub const WEIGHT_SUM_TOLERANCE: f64 = 1e-9;

/// A distribution of one uncertain parameter, with exact rational parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum Distribution {
    /// Uniform on `[low, high]`.
    Uniform {
        /// Lower end.
        low: BigRational,
        /// Upper end.
        high: BigRational,
    },
    /// Normal with mean and **standard deviation** (not variance).
    Normal {
        /// Mean μ.
        mean: BigRational,
        /// Standard deviation σ ≥ 0.
        std: BigRational,
    },
    /// Beta(α, β) scaled affinely onto `[low, high]` (default `[0, 1]`).
    Beta {
        /// α > 0.
        alpha: BigRational,
        /// β > 0.
        beta: BigRational,
        /// Lower end of the support.
        low: BigRational,
        /// Upper end of the support.
        high: BigRational,
    },
    /// Gamma with shape κ and scale θ.
    Gamma {
        /// κ > 0.
        shape: BigRational,
        /// θ > 0.
        scale: BigRational,
    },
    /// Exponential with rate λ.
    Exponential {
        /// λ > 0.
        rate: BigRational,
    },
    /// Laplace with mean μ and scale b.
    Laplace {
        /// μ.
        mean: BigRational,
        /// b > 0.
        scale: BigRational,
    },
    /// Finite distribution: `values[i]` with probability `weights[i]`.
    Discrete {
        /// Support points.
        values: Vec<BigRational>,
        /// Probabilities (sum to 1 after validation).
        weights: Vec<BigRational>,
    },
    /// Only raw moments `E[w^1], E[w^2], ...` are known; no sampling possible.
    Moments {
        /// `raw[k-1] = E[w^k]`.
        raw: Vec<BigRational>,
    },
}

/// What is wrong with a distribution. `field` names the scene field at fault.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MomentError {
    /// A parameter value outside its domain.
    #[error("{field}: {message}")]
    InvalidParameter {
        /// The offending field (`std`, `alpha`, `weights`, ...).
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A `moments` distribution lists fewer raw moments than the obstacles need.
    #[error("raw: {needed} raw moments are needed (twice the largest degree of an obstacle in this parameter), {given} given")]
    TooFewMoments {
        /// Moments needed.
        needed: u32,
        /// Moments listed.
        given: usize,
    },
    /// The raw moments are not those of any real distribution.
    #[error("raw: not a moment sequence of any distribution (the Hankel matrix [m(i+j)] up to order {order} is not positive semidefinite)")]
    NotMomentSequence {
        /// Half the order checked.
        order: usize,
    },
    /// Sampling was asked of a distribution known only by its moments.
    #[error("a parameter given only by raw moments cannot be sampled for Monte Carlo")]
    NotSampleable,
}

fn q(n: i64) -> BigRational {
    BigRational::from_integer(BigInt::from(n))
}

fn invalid(field: &'static str, message: String) -> MomentError {
    MomentError::InvalidParameter { field, message }
}

/// `C(n, k)` exactly.
pub fn binomial(n: u32, k: u32) -> BigRational {
    let mut c = BigInt::one();
    for i in 0..k {
        c = c * BigInt::from(n - i) / BigInt::from(i + 1);
    }
    BigRational::from_integer(c)
}

fn factorial(n: u32) -> BigRational {
    (1..=n).fold(q(1), |acc, i| acc * q(i as i64))
}

impl Distribution {
    /// The family name used in scene files.
    pub fn kind(&self) -> &'static str {
        match self {
            Distribution::Uniform { .. } => "uniform",
            Distribution::Normal { .. } => "normal",
            Distribution::Beta { .. } => "beta",
            Distribution::Gamma { .. } => "gamma",
            Distribution::Exponential { .. } => "exponential",
            Distribution::Laplace { .. } => "laplace",
            Distribution::Discrete { .. } => "discrete",
            Distribution::Moments { .. } => "moments",
        }
    }

    /// The smallest interval `[lo, hi]` that holds the parameter with probability 1,
    /// when it is bounded (docs/design.md §3.7): uniform and beta on their ends, discrete on
    /// its smallest and largest value, a normal with σ = 0 on its mean. `None` for the
    /// unbounded families and for a moment list (its support is not known).
    pub fn support(&self) -> Option<(BigRational, BigRational)> {
        match self {
            Distribution::Uniform { low, high } | Distribution::Beta { low, high, .. } => {
                Some((low.clone(), high.clone()))
            }
            Distribution::Discrete { values, .. } => {
                let lo = values.iter().min()?.clone();
                let hi = values.iter().max()?.clone();
                Some((lo, hi))
            }
            Distribution::Normal { mean, std } if std.is_zero() => Some((mean.clone(), mean.clone())),
            _ => None,
        }
    }

    /// Checks the parameters of the family; for `discrete`, renormalises the
    /// weights exactly when they sum to 1 within [`WEIGHT_SUM_TOLERANCE`].
    pub fn validated(self) -> Result<Self, MomentError> {
        let pos = |field: &'static str, v: &BigRational| {
            if v.is_positive() {
                Ok(())
            } else {
                Err(invalid(field, format!("must be > 0, got {}", show(v))))
            }
        };
        match &self {
            Distribution::Uniform { low, high } if low >= high => {
                return Err(invalid("high", format!("must be greater than low ({} ≥ {})", show(low), show(high))))
            }
            Distribution::Normal { std, .. } if std.is_negative() => {
                return Err(invalid("std", format!("must be ≥ 0, got {}", show(std))))
            }
            Distribution::Beta { alpha, beta, low, high } => {
                pos("alpha", alpha)?;
                pos("beta", beta)?;
                if low >= high {
                    return Err(invalid("high", format!("must be greater than low ({} ≥ {})", show(low), show(high))));
                }
            }
            Distribution::Gamma { shape, scale } => {
                pos("shape", shape)?;
                pos("scale", scale)?;
            }
            Distribution::Exponential { rate } => pos("rate", rate)?,
            Distribution::Laplace { scale, .. } => pos("scale", scale)?,
            Distribution::Discrete { values, weights } => return validate_discrete(values, weights),
            Distribution::Moments { raw } if raw.len() > MAX_RAW_MOMENTS => {
                return Err(invalid("raw", format!("at most {MAX_RAW_MOMENTS} raw moments, got {}", raw.len())))
            }
            _ => {}
        }
        Ok(self)
    }

    /// Raw moments `m_0 = 1, m_1, ..., m_k` (exact). For `moments`, fails when fewer
    /// than `k` are given or when they are not a moment sequence (Hankel check, §1.4).
    pub fn raw_moments(&self, k: u32) -> Result<Vec<BigRational>, MomentError> {
        let k = k as usize;
        let mut m = vec![q(1)];
        match self {
            Distribution::Uniform { low, high } => {
                // m_n = S_n/(n+1), S_n = Σ_j a^j b^(n-j): the sum form, no cancellation,
                // by S_n = b·S_(n-1) + a^n, in integers over a common denominator D
                // (a = A/D, b = B/D: S_n = T_n/Dⁿ, T_n = B·T_(n-1) + Aⁿ), each moment
                // reduced once (the sum term by term in rationals, each power formed anew,
                // was two thirds of loading a scene of 512 uncertain disks)
                let ([a, b], d) = over_common_denominator([low, high]);
                let (mut t, mut a_n, mut d_n) = (BigInt::one(), BigInt::one(), BigInt::one());
                for n in 1..=k {
                    a_n *= &a;
                    d_n *= &d;
                    t = &b * &t + &a_n;
                    m.push(BigRational::new(t.clone(), &d_n * BigInt::from(n + 1)));
                }
            }
            Distribution::Normal { mean, std } => {
                // m_n = μ·m_(n-1) + (n−1)·σ²·m_(n-2), in integers over a common denominator
                // L (μ = M/L, σ² = V/L: m_n = N_n/Lⁿ, N_n = M·N_(n-1) + (n−1)·V·L·N_(n-2)),
                // each moment reduced once
                let var = std * std;
                let ([mu, v], l) = over_common_denominator([mean, &var]);
                let vl = &v * &l;
                let (mut prev2, mut prev, mut l_n) = (BigInt::zero(), BigInt::one(), BigInt::one());
                for n in 1..=k {
                    let next = &mu * &prev + BigInt::from(n - 1) * &vl * &prev2;
                    l_n *= &l;
                    m.push(BigRational::new(next.clone(), l_n.clone()));
                    (prev2, prev) = (prev, next);
                }
            }
            Distribution::Beta { alpha, beta, low, high } => {
                let mut b = vec![q(1)];
                for n in 1..=k {
                    let nn = q(n as i64 - 1);
                    let v = &b[n - 1] * (alpha + &nn) / (alpha + beta + &nn);
                    b.push(v);
                }
                let width = high - low;
                // m_n = Σ_j C(n, j)·low^(n-j)·width^j·b_j, the powers formed once
                let (lows, widths) = (powers(low, k), powers(&width, k));
                for n in 1..=k {
                    let mut s = BigRational::zero();
                    for (j, bj) in b.iter().enumerate().take(n + 1) {
                        s += binomial(n as u32, j as u32) * &lows[n - j] * &widths[j] * bj;
                    }
                    m.push(s);
                }
            }
            Distribution::Gamma { shape, scale } => {
                for n in 1..=k {
                    let v = scale * (shape + q(n as i64 - 1)) * &m[n - 1];
                    m.push(v);
                }
            }
            Distribution::Exponential { rate } => {
                for n in 1..=k {
                    let v = q(n as i64) / rate * &m[n - 1];
                    m.push(v);
                }
            }
            Distribution::Laplace { mean, scale } => {
                // m_n = Σ_(j even) C(n, j)·μ^(n-j)·j!·b^j, the powers formed once
                let (means, scales) = (powers(mean, k), powers(scale, k));
                for n in 1..=k {
                    let mut s = BigRational::zero();
                    for j in (0..=n).step_by(2) {
                        s += binomial(n as u32, j as u32) * &means[n - j] * factorial(j as u32) * &scales[j];
                    }
                    m.push(s);
                }
            }
            Distribution::Discrete { values, weights } => {
                // Σ w·v^n, each atom's power carried from n − 1
                let mut at: Vec<BigRational> = weights.clone();
                for _ in 1..=k {
                    for (a, v) in at.iter_mut().zip(values) {
                        *a *= v;
                    }
                    m.push(at.iter().sum());
                }
            }
            Distribution::Moments { raw } => {
                if raw.len() < k {
                    return Err(MomentError::TooFewMoments { needed: k as u32, given: raw.len() });
                }
                m.extend(raw[..k].iter().cloned());
                check_hankel(&m)?;
            }
        }
        Ok(m)
    }

    /// The mean E\[w\] (exact).
    pub fn mean(&self) -> Result<BigRational, MomentError> {
        match self {
            Distribution::Moments { raw } if raw.is_empty() => Err(MomentError::TooFewMoments { needed: 1, given: 0 }),
            Distribution::Moments { raw } => Ok(raw[0].clone()),
            _ => Ok(self.raw_moments(1)?[1].clone()),
        }
    }

    /// A sampler for Monte Carlo, or [`MomentError::NotSampleable`] for `moments`.
    pub fn sampler(&self) -> Result<Sampler, MomentError> {
        Sampler::new(self)
    }
}

fn show(v: &BigRational) -> String {
    let f = crate::poly::rational_to_f64(v);
    format!("{f}")
}

/// `xs` as integers over their least common denominator: `([x·L for x in xs], L)`.
fn over_common_denominator<const N: usize>(xs: [&BigRational; N]) -> ([BigInt; N], BigInt) {
    use num_integer::Integer;
    let l = xs.iter().fold(BigInt::one(), |acc, x| acc.lcm(x.denom()));
    (xs.map(|x| x.numer() * (&l / x.denom())), l)
}

/// `[1, v, v², ..., v^k]`, exact.
fn powers(v: &BigRational, k: usize) -> Vec<BigRational> {
    let mut out = Vec::with_capacity(k + 1);
    out.push(q(1));
    for j in 1..=k {
        let next = &out[j - 1] * v;
        out.push(next);
    }
    out
}

/// Most atoms of a `discrete` distribution.
pub const MAX_DISCRETE_ATOMS: usize = 64;

/// Largest common denominator, in bits, of a `discrete` distribution's values, and of
/// its weights. Its raw moments Σ w·vᵏ (k ≤ 16) carry such denominators to the
/// power k: 300 weights with unrelated denominators took 18 s to expand; within this
/// bound the moments stay cheap.
pub const MAX_DISCRETE_DENOMINATOR_BITS: u64 = 1024;

/// Most raw moments a `moments` distribution may list (obstacles need at most 2·8).
pub const MAX_RAW_MOMENTS: usize = 64;

/// The least common multiple of the denominators, or `None` once it exceeds
/// [`MAX_DISCRETE_DENOMINATOR_BITS`].
fn common_denominator(xs: &[BigRational]) -> Option<BigInt> {
    use num_integer::Integer;
    let mut l = BigInt::one();
    for x in xs {
        l = l.lcm(x.denom());
        if l.bits() > MAX_DISCRETE_DENOMINATOR_BITS {
            return None;
        }
    }
    Some(l)
}

fn validate_discrete(values: &[BigRational], weights: &[BigRational]) -> Result<Distribution, MomentError> {
    if values.is_empty() {
        return Err(invalid("values", "must list at least one value".into()));
    }
    if values.len() > MAX_DISCRETE_ATOMS {
        return Err(invalid("values", format!("at most {MAX_DISCRETE_ATOMS} values, got {}", values.len())));
    }
    for (field, xs) in [("values", values), ("weights", weights)] {
        if common_denominator(xs).is_none() {
            return Err(invalid(
                field,
                format!("the common denominator of the {field} exceeds {MAX_DISCRETE_DENOMINATOR_BITS} bits"),
            ));
        }
    }
    if values.len() != weights.len() {
        return Err(invalid("weights", format!("has {} entries but values has {}", weights.len(), values.len())));
    }
    if let Some(w) = weights.iter().find(|w| w.is_negative()) {
        return Err(invalid("weights", format!("must be ≥ 0, got {}", show(w))));
    }
    let sum: BigRational = weights.iter().sum();
    let gap = crate::poly::rational_to_f64(&(&sum - q(1))).abs();
    if gap > WEIGHT_SUM_TOLERANCE {
        return Err(invalid("weights", format!("must sum to 1, they sum to {}", show(&sum))));
    }
    Ok(Distribution::Discrete { values: values.to_vec(), weights: weights.iter().map(|w| w / &sum).collect() })
}

/// Exact test that the Hankel matrix `[m_{i+j}]`, `i, j ≤ ⌊K/2⌋`, is positive
/// semidefinite, by symmetric elimination with diagonal pivots (a PSD matrix with a
/// zero pivot has a zero row). A necessary condition for raw moments of a real
/// distribution; without it E\[P²\] can come out negative.
fn check_hankel(m: &[BigRational]) -> Result<(), MomentError> {
    let n = (m.len() - 1) / 2 + 1;
    let mut a: Vec<Vec<BigRational>> = (0..n).map(|i| (0..n).map(|j| m[i + j].clone()).collect()).collect();
    for k in 0..n {
        let d = a[k][k].clone();
        if d.is_negative() {
            return Err(MomentError::NotMomentSequence { order: n - 1 });
        }
        if d.is_zero() {
            if a[k][k + 1..].iter().any(|x| !x.is_zero()) {
                return Err(MomentError::NotMomentSequence { order: n - 1 });
            }
            continue;
        }
        let pivot_row = a[k].clone();
        for row in a.iter_mut().skip(k + 1) {
            let f = &row[k] / &d;
            for (x, pk) in row.iter_mut().zip(&pivot_row).skip(k + 1) {
                *x -= pk * &f;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod oracle_tests;
#[cfg(test)]
mod tests;
