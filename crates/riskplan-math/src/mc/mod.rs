//! Monte Carlo estimates of the true risk Prob(P(x, ω, t) ≥ 0) (docs/design.md §7) —
//! layer L1. These are *estimates* used to audit the certified bounds, never to
//! certify anything.
//!
//! Scenarios are drawn with a seeded ChaCha RNG; each parameter is sampled once per
//! scenario and shared by every obstacle that names it. The same scenarios are
//! reused at every query point, as the paper's Example 1 script does.

use crate::contour::Layout;
use crate::moments::Sampler;
use crate::poly::{Poly, Var};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha12Rng;

/// Default two-sided confidence level of reported intervals.
pub const DEFAULT_CONFIDENCE: f64 = 0.99;

/// An estimate of a probability from `hits` out of `samples` Bernoulli trials.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct McEstimate {
    /// `hits / samples`.
    pub estimate: f64,
    /// Clopper–Pearson lower bound at the stated confidence.
    pub lower: f64,
    /// Clopper–Pearson upper bound at the stated confidence.
    pub upper: f64,
    /// Trials.
    pub samples: u64,
    /// Successes (P ≥ 0).
    pub hits: u64,
}

impl McEstimate {
    /// Estimate with the exact (Clopper–Pearson) interval at two-sided `confidence`.
    pub fn new(hits: u64, samples: u64, confidence: f64) -> Self {
        let (lower, upper) = clopper_pearson(hits, samples, confidence);
        let estimate = if samples == 0 { f64::NAN } else { hits as f64 / samples as f64 };
        McEstimate { estimate, lower, upper, samples, hits }
    }
}

/// The exact binomial confidence interval of Clopper and Pearson at two-sided level
/// `confidence`: `[B⁻¹(α/2; k, n−k+1), B⁻¹(1−α/2; k+1, n−k)]`, with 0 when `k = 0`
/// and 1 when `k = n` (docs/design.md §7.1).
pub fn clopper_pearson(k: u64, n: u64, confidence: f64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let alpha = 1.0 - confidence;
    let (kf, nf) = (k as f64, n as f64);
    let lower = if k == 0 { 0.0 } else { inverse_beta_cdf(alpha / 2.0, kf, nf - kf + 1.0) };
    let upper = if k == n { 1.0 } else { inverse_beta_cdf(1.0 - alpha / 2.0, kf + 1.0, nf - kf) };
    (lower, upper)
}

/// `x` with `I_x(a, b) = p`, by bisection on the regularized incomplete beta
/// function (monotone in x). 200 halvings reach the resolution of f64.
fn inverse_beta_cdf(p: f64, a: f64, b: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if statrs::function::beta::beta_reg(a, b, mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// A term `c · Π ω^e` of a polynomial in the parameters only.
type ParamTerm = (f64, Vec<(usize, u32)>);

/// The obstacles of a scene, ready for sampling.
#[derive(Clone, Debug)]
pub struct McModel {
    layout: Layout,
    nvars: usize,
    polys: Vec<Poly<f64>>,
    samplers: Vec<(Var, Sampler)>,
    center: Vec<f64>,
    /// The robot's body radius: contact is `max_{‖y‖≤ρ} P(x + y) ≥ 0` (0: `P(x) ≥ 0`).
    body: f64,
}

/// Directions on the circle (2-D) or sphere (3-D, a Fibonacci lattice), or random ones
/// in other dimensions, at which the body's boundary is sampled; with the centre and a
/// half-radius ring. 64 directions on the circle place every boundary point within
/// π/64 of one: a large obstacle grazing the body less than 0.12 % of ρ deep can be missed
/// in 2-D, 2.8 % in 3-D (128 directions), and an obstacle smaller than about ρ/4 lying
/// wholly inside the body between the rings (docs/design.md §7.2).
pub const BODY_DIRECTIONS: usize = 64;

/// Points of the ball of radius `rho` in `dim` dimensions at which an audit looks for
/// contact (see [`BODY_DIRECTIONS`]).
pub fn ball_points(dim: usize, rho: f64) -> Vec<Vec<f64>> {
    let mut out = vec![vec![0.0; dim]];
    if rho <= 0.0 || dim == 0 {
        return out;
    }
    let dirs: Vec<Vec<f64>> = match dim {
        1 => vec![vec![1.0], vec![-1.0]],
        2 => (0..BODY_DIRECTIONS)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / BODY_DIRECTIONS as f64;
                vec![a.cos(), a.sin()]
            })
            .collect(),
        3 => {
            let n = 2 * BODY_DIRECTIONS;
            let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
            (0..n)
                .map(|k| {
                    let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
                    let r = (1.0 - z * z).sqrt();
                    let a = golden * k as f64;
                    vec![r * a.cos(), r * a.sin(), z]
                })
                .collect()
        }
        _ => {
            let mut rng = ChaCha12Rng::seed_from_u64(0x6f64);
            let mut d: Vec<Vec<f64>> = (0..dim)
                .flat_map(|i| {
                    let mut a = vec![0.0; dim];
                    a[i] = 1.0;
                    let mut b = vec![0.0; dim];
                    b[i] = -1.0;
                    [a, b]
                })
                .collect();
            for _ in 0..4 * BODY_DIRECTIONS {
                let v: Vec<f64> = (0..dim).map(|_| rng.random_range(-1.0..1.0)).collect();
                let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                if n > 1e-3 {
                    d.push(v.iter().map(|x| x / n).collect());
                }
            }
            d
        }
    };
    for (i, d) in dirs.iter().enumerate() {
        out.push(d.iter().map(|c| c * rho).collect());
        if i % 2 == 0 || dim == 1 {
            out.push(d.iter().map(|c| c * 0.5 * rho).collect());
        }
    }
    out
}

/// Whether some point of the body meets the obstacle in scenario `w`: P (reduced to the
/// parameters at each point of the body) ≥ 0 at one of them.
fn contact(per_offset: &[Vec<ParamTerm>], w: &[f64]) -> bool {
    per_offset.iter().any(|terms| {
        let v: f64 = terms.iter().map(|(c, m)| m.iter().fold(*c, |acc, &(i, e)| acc * w[i].powi(e as i32))).sum();
        v >= 0.0
    })
}

impl McModel {
    /// From obstacle polynomials over all `nvars` scene variables and one sampler per
    /// parameter. The polynomials are in centred variables `(x − c, t − t_c)` with
    /// `center = (c, t_c)` (an empty centre: the origin): far from the origin the
    /// expanded polynomial's terms cancel by many orders of magnitude in `f64`, so the
    /// scene centres them exactly before rounding (docs/design.md §7.1).
    pub fn new(
        layout: Layout,
        nvars: usize,
        polys: Vec<Poly<f64>>,
        samplers: Vec<(Var, Sampler)>,
        center: Vec<f64>,
    ) -> Self {
        McModel { layout, nvars, polys, samplers, center, body: 0.0 }
    }

    /// The same model for a robot whose body is a ball of radius `rho` around its
    /// reference point: a point counts as a contact when some point of the body meets an
    /// obstacle (sampled by [`ball_points`]; the polynomials must be the obstacles
    /// themselves, not grown).
    pub fn with_body(mut self, rho: f64) -> Self {
        self.body = rho;
        self
    }

    /// Number of obstacles.
    pub fn obstacles(&self) -> usize {
        self.polys.len()
    }

    /// Substitutes (x, t) and keeps a polynomial in the parameters only.
    fn reduce(&self, obstacle: usize, xt: &[f64]) -> Vec<ParamTerm> {
        let mut p = self.polys[obstacle].clone();
        for v in 0..self.layout.xt_len() {
            let value = xt.get(v).unwrap_or(&0.0) - self.center.get(v).unwrap_or(&0.0);
            p = p.partial_eval(v as Var, &value);
        }
        let index: Vec<usize> = {
            let mut idx = vec![usize::MAX; self.nvars];
            for (i, (v, _)) in self.samplers.iter().enumerate() {
                idx[*v as usize] = i;
            }
            idx
        };
        p.terms().map(|(m, c)| (*c, m.pairs().iter().map(|&(v, e)| (index[v as usize], e)).collect())).collect()
    }

    /// Hit counts `hits[point][obstacle]` of `P ≥ 0` over `samples` scenarios shared by
    /// all points. Each point is `(x1..xn, t)`.
    pub fn hits(&self, points: &[Vec<f64>], samples: u64, seed: u64) -> Vec<Vec<u64>> {
        self.hits_and_any(points, samples, seed).0
    }

    /// Per point, per obstacle, per point of the body: P reduced to the parameters.
    fn reduced(&self, points: &[Vec<f64>]) -> Vec<Vec<Vec<Vec<ParamTerm>>>> {
        let ball = ball_points(self.layout.dim, self.body);
        points
            .iter()
            .map(|xt| {
                (0..self.polys.len())
                    .map(|o| {
                        ball.iter()
                            .map(|y| {
                                let mut z = xt.clone();
                                for (zi, yi) in z.iter_mut().zip(y) {
                                    *zi += yi;
                                }
                                self.reduce(o, &z)
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }

    /// Draws `samples` scenarios of the parameters (seeded) and hands each to `f`.
    fn scenarios(&self, samples: u64, seed: u64, mut f: impl FnMut(&[f64])) {
        let mut rng = ChaCha12Rng::seed_from_u64(seed);
        let mut w = vec![0.0; self.samplers.len()];
        for _ in 0..samples {
            for (slot, (_, s)) in w.iter_mut().zip(&self.samplers) {
                *slot = s.sample(&mut rng);
            }
            f(&w);
        }
    }

    /// [`McModel::hits`], and per point the number of scenarios in which *any*
    /// obstacle contains it (the joint event; parameters shared between obstacles are
    /// one random variable, so correlations are kept).
    pub fn hits_and_any(&self, points: &[Vec<f64>], samples: u64, seed: u64) -> (Vec<Vec<u64>>, Vec<u64>) {
        let reduced = self.reduced(points);
        let mut hits = vec![vec![0u64; self.polys.len()]; points.len()];
        let mut any = vec![0u64; points.len()];
        self.scenarios(samples, seed, |w| {
            for (pi, per_point) in reduced.iter().enumerate() {
                let mut hit_any = false;
                for (oi, per_offset) in per_point.iter().enumerate() {
                    if contact(per_offset, w) {
                        hits[pi][oi] += 1;
                        hit_any = true;
                    }
                }
                any[pi] += u64::from(hit_any);
            }
        });
        (hits, any)
    }

    /// The whole-path event (docs/design.md §5.14): per obstacle, the number of
    /// scenarios in which it contains *some* of `points` (one draw of the parameters per
    /// scenario, shared by every point and obstacle), and the number in which some
    /// obstacle contains some point. With dense times along a trajectory this estimates
    /// P(∃ t : collision) from below (a contact between two audited times can be missed).
    pub fn path_hits(&self, points: &[Vec<f64>], samples: u64, seed: u64) -> (Vec<u64>, u64) {
        let reduced = self.reduced(points);
        let mut per_obstacle = vec![0u64; self.polys.len()];
        let mut any = 0u64;
        self.scenarios(samples, seed, |w| {
            let mut hit_any = false;
            for (oi, count) in per_obstacle.iter_mut().enumerate() {
                if reduced.iter().any(|per_point| contact(&per_point[oi], w)) {
                    *count += 1;
                    hit_any = true;
                }
            }
            any += u64::from(hit_any);
        });
        (per_obstacle, any)
    }

    /// Per-obstacle estimates of Prob(P(x, ω, t) ≥ 0) at one point.
    pub fn point_risk(&self, xt: &[f64], samples: u64, seed: u64, confidence: f64) -> Vec<McEstimate> {
        self.hits(&[xt.to_vec()], samples, seed)[0].iter().map(|&h| McEstimate::new(h, samples, confidence)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clopper_pearson_known_values() {
        // k = 0: upper bound 1 − (α/2)^(1/n)
        let (lo, hi) = clopper_pearson(0, 100, 0.95);
        assert_eq!(lo, 0.0);
        assert!((hi - (1.0 - 0.025f64.powf(0.01))).abs() < 1e-9);
        // symmetric: k = n/2
        let (lo, hi) = clopper_pearson(50, 100, 0.95);
        assert!((lo - 0.3983).abs() < 1e-3 && (hi - 0.6017).abs() < 1e-3, "{lo} {hi}");
        assert_eq!(clopper_pearson(10, 10, 0.9).1, 1.0);
    }
}
