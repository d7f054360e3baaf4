//! Seeded sampling of parameter distributions (docs/design.md §7.1), via `rand_distr`.

use super::{Distribution, MomentError};
use crate::poly::rational_to_f64;
use rand::distr::weighted::WeightedIndex;
use rand::Rng;
use rand_distr::Distribution as _;

/// Draws one distribution in `f64`. Built once, sampled many times.
#[derive(Clone, Debug)]
pub enum Sampler {
    /// A constant (normal with σ = 0, or a one-point discrete).
    Constant(f64),
    /// Uniform on `[low, high)`.
    Uniform(rand_distr::Uniform<f64>),
    /// Normal.
    Normal(rand_distr::Normal<f64>),
    /// `low + width · Beta(α, β)`.
    Beta {
        /// Beta(α, β) on [0, 1].
        dist: rand_distr::Beta<f64>,
        /// Lower end.
        low: f64,
        /// `high − low`.
        width: f64,
    },
    /// Gamma (shape, scale).
    Gamma(rand_distr::Gamma<f64>),
    /// Exponential (rate).
    Exp(rand_distr::Exp<f64>),
    /// Laplace: `μ − b·sgn(U)·ln(1 − 2|U|)` with `U ~ U(−½, ½)`.
    Laplace {
        /// μ.
        mean: f64,
        /// b.
        scale: f64,
    },
    /// Finite support with cumulative weights.
    Discrete {
        /// Support.
        values: Vec<f64>,
        /// Index sampler.
        index: WeightedIndex<f64>,
    },
}

fn bad(field: &'static str, e: impl std::fmt::Display) -> MomentError {
    MomentError::InvalidParameter { field, message: format!("cannot be sampled: {e}") }
}

impl Sampler {
    /// Builds a sampler; `moments`-only distributions cannot be sampled.
    pub fn new(d: &Distribution) -> Result<Self, MomentError> {
        let f = rational_to_f64;
        Ok(match d {
            Distribution::Uniform { low, high } => {
                Sampler::Uniform(rand_distr::Uniform::new(f(low), f(high)).map_err(|e| bad("high", e))?)
            }
            Distribution::Normal { mean, std } if f(std) == 0.0 => Sampler::Constant(f(mean)),
            Distribution::Normal { mean, std } => {
                Sampler::Normal(rand_distr::Normal::new(f(mean), f(std)).map_err(|e| bad("std", e))?)
            }
            Distribution::Beta { alpha, beta, low, high } => Sampler::Beta {
                dist: rand_distr::Beta::new(f(alpha), f(beta)).map_err(|e| bad("alpha", e))?,
                low: f(low),
                width: f(high) - f(low),
            },
            Distribution::Gamma { shape, scale } => {
                Sampler::Gamma(rand_distr::Gamma::new(f(shape), f(scale)).map_err(|e| bad("shape", e))?)
            }
            Distribution::Exponential { rate } => {
                Sampler::Exp(rand_distr::Exp::new(f(rate)).map_err(|e| bad("rate", e))?)
            }
            Distribution::Laplace { mean, scale } => Sampler::Laplace { mean: f(mean), scale: f(scale) },
            Distribution::Discrete { values, weights } if values.len() == 1 => {
                let _ = weights;
                Sampler::Constant(f(&values[0]))
            }
            Distribution::Discrete { values, weights } => Sampler::Discrete {
                values: values.iter().map(f).collect(),
                index: WeightedIndex::new(weights.iter().map(f)).map_err(|e| bad("weights", e))?,
            },
            Distribution::Moments { .. } => return Err(MomentError::NotSampleable),
        })
    }

    /// One draw.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        match self {
            Sampler::Constant(c) => *c,
            Sampler::Uniform(d) => d.sample(rng),
            Sampler::Normal(d) => d.sample(rng),
            Sampler::Beta { dist, low, width } => low + width * dist.sample(rng),
            Sampler::Gamma(d) => d.sample(rng),
            Sampler::Exp(d) => d.sample(rng),
            Sampler::Laplace { mean, scale } => {
                let u: f64 = rng.random::<f64>() - 0.5;
                mean - scale * u.signum() * (1.0 - 2.0 * u.abs()).ln()
            }
            Sampler::Discrete { values, index } => values[index.sample(rng)],
        }
    }
}
