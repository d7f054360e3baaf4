//! The seeded scene generator: [`generate`]`(seed, index)` gives one scene, the same
//! for the same arguments on every machine (ChaCha12 seeded from both).
//!
//! Every scene is described twice: structurally ([`GeneratedScene`], [`ObstacleSpec`],
//! [`Shape`], [`Motion`], [`Dist`]), which the oracle and the audit evaluate directly,
//! and as scene-format v1 JSON text ([`GeneratedScene::json`]), which riskplan loads.
//! Every number is rounded to [`SIG_DIGITS`] significant digits *before* it is used in
//! either description, so the decimal written to the JSON is the exact value the
//! structured description holds (an `f64` prints as its shortest round-tripping
//! decimal, which the scene parser reads exactly).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha12Rng;
use rand_distr::Distribution as _;
use serde::Serialize;
use serde_json::{json, Value};
use std::f64::consts::PI;

/// Significant digits of every generated number (enough to place a 1-unit workspace at
/// ±1000 to 10⁻⁵, few enough to keep the parser's coefficient-size work small).
pub const SIG_DIGITS: usize = 9;
/// Smallest and largest workspace width (log-uniform in between).
pub const WIDTH_RANGE: (f64, f64) = (1.0, 100.0);
/// Largest absolute coordinate of the workspace's lower corner.
pub const MAX_OFFSET: f64 = 1000.0;
/// Range of the horizon's start t₀.
pub const T0_RANGE: (f64, f64) = (-20.0, 50.0);
/// Range of the horizon's length t_f − t₀ (log-uniform in between).
pub const HORIZON_LENGTH_RANGE: (f64, f64) = (0.2, 30.0);
/// Range of Δ.
pub const DELTA_RANGE: (f64, f64) = (0.01, 0.2);
/// Probability that a scene is generated to be feasible.
pub const FEASIBLE_SHARE: f64 = 0.82;
/// Probability that a scene is 2-D (else 3-D).
pub const TWO_D_SHARE: f64 = 2.0 / 3.0;
/// Probability that a scene has moving obstacles (wall scenes are always static).
pub const MOVING_SHARE: f64 = 0.45;
/// Probability that a feasible scene gets a speed limit.
pub const SPEED_LIMIT_SHARE: f64 = 0.2;
/// A feasible scene's speed limit over the straight-line speed |goal − start|/(t_f − t₀).
pub const FEASIBLE_SPEED_FACTOR: (f64, f64) = (2.0, 4.0);
/// An out-of-reach scene's speed limit over the straight-line speed.
pub const UNREACHABLE_SPEED_FACTOR: (f64, f64) = (0.3, 0.7);
/// Free space kept around start and goal at every time, as a share of the smallest
/// workspace side, on top of an obstacle's bounding radius (feasible placements).
pub const ENDPOINT_CLEARANCE: f64 = 0.04;
/// Times sampled over the horizon when checking an obstacle's clearance of start/goal.
pub const CLEARANCE_TIMES: usize = 21;
/// Tries to place one obstacle before giving it up.
pub const PLACEMENT_TRIES: usize = 60;
/// How many standard deviations of an uncertain size or offset the bounding radius
/// allows for.
pub const BOUND_SIGMAS: f64 = 3.0;
/// The tightened level Δ·TIGHT_FACTOR at which the oracle's clearance search judges cells
/// ([`crate::oracle`]); a pedestrian's bounding radius reaches at least its Cantelli radius
/// at that level ([`pedestrian_cantelli_radius`]), so that what the search keeps clear of
/// lies inside the bound.
pub const TIGHT_FACTOR: f64 = 0.5;
/// Most parameters of one obstacle other than a pedestrian (the generator makes the
/// uncertain quantities past it constant).
pub const MAX_PARAMS: usize = 3;
/// Most parameters of a pedestrian: a Gaussian position error and a Gaussian velocity
/// error per axis, and possibly an uncertain radius (2·3 + 1 in 3-D). The oracle's
/// quadrature folds the Gaussian errors into one Gaussian per axis at each time
/// (`oracle::ObstacleMoments`), so they cost 3^dim nodes, not 3^(2·dim).
pub const MAX_PEDESTRIAN_PARAMS: usize = 7;
/// Probability that a random obstacle of a scene with moving obstacles is a pedestrian
/// ([`Shape::Pedestrian`]: a disk/ball in linear motion with Gaussian position and
/// velocity errors).
pub const PEDESTRIAN_SHARE: f64 = 0.35;
/// A pedestrian's position error σ_p per axis, as a share of the scene's width (its
/// largest side), drawn uniformly in this range (≈ 1 %).
pub const PEDESTRIAN_POS_SD: (f64, f64) = (0.007, 0.013);
/// A pedestrian's velocity error σ_v per axis times the horizon length t_f − t₀, as a
/// share of the scene's width, drawn uniformly in this range (≈ 2 %).
pub const PEDESTRIAN_DRIFT_SD: (f64, f64) = (0.015, 0.025);
/// Probability that a pedestrian's radius is uncertain (else fixed).
pub const PEDESTRIAN_UNCERTAIN_RADIUS: f64 = 0.5;
/// A pedestrian's radius uncertainty (sd over radius), when uncertain, is this share of
/// the relative uncertainty drawn for other obstacles ("slightly uncertain").
pub const PEDESTRIAN_RADIUS_REL: f64 = 0.5;

/// Rounds to [`SIG_DIGITS`] significant digits.
pub fn q(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let r: f64 = format!("{:.*e}", SIG_DIGITS - 1, x).parse().unwrap_or(x);
    if r == 0.0 {
        0.0 // no "-0"
    } else {
        r
    }
}

/// A number as polynomial text: its shortest decimal, parenthesised when negative.
fn num(x: f64) -> String {
    if x < 0.0 {
        format!("({x})")
    } else {
        format!("{x}")
    }
}

/// The distribution of one parameter, in the numbers the JSON holds.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "dist", rename_all = "lowercase")]
pub enum Dist {
    /// Uniform on [low, high].
    Uniform {
        /// Lower end.
        low: f64,
        /// Upper end.
        high: f64,
    },
    /// Normal (mean, standard deviation).
    Normal {
        /// Mean.
        mean: f64,
        /// Standard deviation.
        std: f64,
    },
    /// Beta(α, β) on [low, high].
    Beta {
        /// α.
        alpha: f64,
        /// β.
        beta: f64,
        /// Lower end.
        low: f64,
        /// Upper end.
        high: f64,
    },
    /// Gamma (shape, scale).
    Gamma {
        /// Shape.
        shape: f64,
        /// Scale.
        scale: f64,
    },
    /// Exponential (rate).
    Exponential {
        /// Rate.
        rate: f64,
    },
    /// Laplace (mean, scale).
    Laplace {
        /// Mean.
        mean: f64,
        /// Scale.
        scale: f64,
    },
    /// Finitely many atoms.
    Discrete {
        /// Atoms.
        values: Vec<f64>,
        /// Probabilities (whole percents, summing to exactly 1).
        weights: Vec<f64>,
    },
    /// Only raw moments are written to the scene; `truth` is the distribution they are
    /// the moments of (the audit samples it, riskplan cannot).
    Moments {
        /// Raw moments E[w^k], k = 1…, as exact fractions (numerator, denominator).
        raw: Vec<(i128, i128)>,
        /// The distribution the moments come from.
        truth: Box<Dist>,
    },
    /// Raw moments E(w), E(w²), … as read from a scene's `moments` distribution
    /// ([`Dist::from_scene_json`]): no underlying distribution is known, so it cannot be
    /// sampled ([`Dist::sample`] gives NaN).
    RawMoments {
        /// E[w^k], k = 1….
        raw: Vec<f64>,
    },
}

/// The eight families, in the order the generator cycles through them.
pub const FAMILIES: [&str; 8] = ["uniform", "normal", "beta", "gamma", "exponential", "laplace", "discrete", "moments"];

/// Only every MOMENTS_SCENE_EVERY-th scene (by index) uses `moments` parameters, so
/// that most plans are audited by riskplan's own Monte Carlo (which cannot sample
/// them) and the rest by the runner's audit of the true distributions.
pub const MOMENTS_SCENE_EVERY: usize = 4;

/// Raw moments listed for a `moments` parameter: six (the oracle's 3-node rule needs
/// five; the format needs 2·degree = 4).
pub const MOMENTS_LISTED: usize = 6;

impl Dist {
    /// The family name of the scene format.
    pub fn family(&self) -> &'static str {
        match self {
            Dist::Uniform { .. } => "uniform",
            Dist::Normal { .. } => "normal",
            Dist::Beta { .. } => "beta",
            Dist::Gamma { .. } => "gamma",
            Dist::Exponential { .. } => "exponential",
            Dist::Laplace { .. } => "laplace",
            Dist::Discrete { .. } => "discrete",
            Dist::Moments { .. } | Dist::RawMoments { .. } => "moments",
        }
    }

    /// `U[lo/den, hi/den]` given as its first [`MOMENTS_LISTED`] raw moments, exactly:
    /// E[w^k] = (hi^{k+1} − lo^{k+1}) / ((k+1)(hi − lo)·den^k). The argument types keep
    /// every power within `i128`. `hi = lo` or `den = 0` gives zero denominators (not
    /// the moments of a distribution: the oracle's quadrature refuses them).
    pub fn moments_of_uniform(lo: i16, hi: i16, den: u16) -> Dist {
        let (lo, hi, den) = (lo as i128, hi as i128, den as i128);
        let raw = (1..=MOMENTS_LISTED as u32)
            .map(|k| {
                let n = hi.pow(k + 1) - lo.pow(k + 1);
                let d = (k as i128 + 1) * (hi - lo) * den.pow(k);
                let g = gcd(n.abs(), d);
                (n / g, d / g)
            })
            .collect();
        Dist::Moments {
            raw,
            truth: Box::new(Dist::Uniform { low: lo as f64 / den as f64, high: hi as f64 / den as f64 }),
        }
    }

    /// Mean and standard deviation (closed forms; the generator scales by them).
    pub fn mean_sd(&self) -> (f64, f64) {
        match self {
            Dist::Uniform { low, high } => (0.5 * (low + high), (high - low) / 12f64.sqrt()),
            Dist::Normal { mean, std } => (*mean, *std),
            Dist::Beta { alpha, beta, low, high } => {
                let s = alpha + beta;
                let m = alpha / s;
                let v = alpha * beta / (s * s * (s + 1.0));
                (low + (high - low) * m, (high - low) * v.sqrt())
            }
            Dist::Gamma { shape, scale } => (shape * scale, shape.sqrt() * scale),
            Dist::Exponential { rate } => (1.0 / rate, 1.0 / rate),
            Dist::Laplace { mean, scale } => (*mean, 2f64.sqrt() * scale),
            Dist::Discrete { values, weights } => {
                let m: f64 = values.iter().zip(weights).map(|(v, w)| v * w).sum();
                let v: f64 = values.iter().zip(weights).map(|(x, w)| w * (x - m) * (x - m)).sum();
                (m, v.sqrt())
            }
            Dist::Moments { truth, .. } => truth.mean_sd(),
            Dist::RawMoments { raw } => {
                let m1 = raw.first().copied().unwrap_or(f64::NAN);
                let m2 = raw.get(1).copied().unwrap_or(f64::NAN);
                (m1, (m2 - m1 * m1).sqrt())
            }
        }
    }

    /// One draw (a `moments` parameter draws from its `truth`).
    pub fn sample(&self, rng: &mut impl Rng) -> f64 {
        match self {
            Dist::Uniform { low, high } => low + (high - low) * rng.random::<f64>(),
            Dist::Normal { mean, std } => {
                let z: f64 = rand_distr::StandardNormal.sample(rng);
                mean + std * z
            }
            Dist::Beta { alpha, beta, low, high } => {
                let y = rand_distr::Beta::new(*alpha, *beta).map(|b| b.sample(rng)).unwrap_or(f64::NAN);
                low + (high - low) * y
            }
            Dist::Gamma { shape, scale } => {
                rand_distr::Gamma::new(*shape, *scale).map(|g| g.sample(rng)).unwrap_or(f64::NAN)
            }
            Dist::Exponential { rate } => -(1.0 - rng.random::<f64>()).ln() / rate,
            Dist::Laplace { mean, scale } => {
                // inverse CDF: u ∈ (−½, ½), w = μ − b·sgn(u)·ln(1 − 2|u|)
                let u = rng.random::<f64>() - 0.5;
                mean - scale * u.signum() * (1.0 - 2.0 * u.abs()).ln()
            }
            Dist::Discrete { values, weights } => {
                let mut u = rng.random::<f64>();
                for (v, w) in values.iter().zip(weights) {
                    if u < *w {
                        return *v;
                    }
                    u -= w;
                }
                *values.last().unwrap_or(&f64::NAN)
            }
            Dist::Moments { truth, .. } => truth.sample(rng),
            Dist::RawMoments { .. } => f64::NAN,
        }
    }

    /// The scene-format JSON object.
    pub fn json(&self) -> Value {
        match self {
            Dist::Moments { raw, .. } => {
                json!({"dist": "moments", "raw": raw.iter().map(|(p, q)| format!("{p}/{q}")).collect::<Vec<_>>()})
            }
            Dist::RawMoments { raw } => json!({"dist": "moments", "raw": raw}),
            d => serde_json::to_value(d).unwrap_or(Value::Null),
        }
    }
}

fn gcd(mut a: i128, mut b: i128) -> i128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a.max(1)
}

/// An uncertain quantity `base + scale·ω` (ω the obstacle's parameter `param`), or the
/// constant `base`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Unc {
    /// Constant part.
    pub base: f64,
    /// Factor of the parameter.
    pub scale: f64,
    /// Index into the obstacle's parameters, if uncertain.
    pub param: Option<usize>,
}

impl Unc {
    /// A constant.
    pub fn fixed(v: f64) -> Unc {
        Unc { base: q(v), scale: 0.0, param: None }
    }

    /// The value for parameter values `w` (the obstacle's, in order).
    pub fn value(&self, w: &[f64]) -> f64 {
        match self.param {
            // a missing parameter value is not a number (never a panic)
            Some(i) => self.base + self.scale * w.get(i).copied().unwrap_or(f64::NAN),
            None => self.base,
        }
    }

    fn text(&self, names: &[String]) -> String {
        match self.param {
            Some(i) => {
                let name = names.get(i).map_or("?", String::as_str); // "?" does not parse
                format!("({} + {}*{})", num(self.base), num(self.scale), name)
            }
            None => num(self.base),
        }
    }
}

/// `v[d]`, or NaN when `v` is shorter (hand-made input of the wrong dimension).
fn at(v: &[f64], d: usize) -> f64 {
    v.get(d).copied().unwrap_or(f64::NAN)
}

/// How an obstacle's reference point c(t) moves, in absolute time t.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MotionKind {
    /// c(t) = c₀.
    Static,
    /// c(t) = c₀ + v·t.
    Linear,
    /// c(t) = c₀ + v·t + a·t².
    Quadratic,
}

/// The motion of an obstacle's reference point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Motion {
    /// Kind.
    pub kind: MotionKind,
    /// c₀ (position at t = 0).
    pub c0: Vec<f64>,
    /// Velocity (zero when static).
    pub v: Vec<f64>,
    /// Acceleration coefficient (zero unless quadratic).
    pub a: Vec<f64>,
}

impl Motion {
    /// c(t) (a coordinate missing from `v` or `a` gives NaN, never a panic).
    pub fn centre(&self, t: f64) -> Vec<f64> {
        (0..self.c0.len()).map(|d| self.c0[d] + at(&self.v, d) * t + at(&self.a, d) * t * t).collect()
    }

    fn text(&self, d: usize) -> String {
        let (c0, v, a) = (at(&self.c0, d), at(&self.v, d), at(&self.a, d));
        match self.kind {
            MotionKind::Static => num(c0),
            MotionKind::Linear => format!("({} + {}*t)", num(c0), num(v)),
            MotionKind::Quadratic => format!("({} + {}*t + {}*t^2)", num(c0), num(v), num(a)),
        }
    }
}

/// The shape of an obstacle around its moving reference point c(t); u = x − c(t).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum Shape {
    /// Disk/ball `r² − Σ_d (u_d − o_d)²`: uncertain radius, uncertain offsets.
    Ball {
        /// Radius r.
        radius: Unc,
        /// Offset per axis (mostly constant 0).
        offset: Vec<Unc>,
    },
    /// Ellipse/ellipsoid `s² − Σ_k D_k·y_k²` with y = Rᵀ(u − o), R a rotation by
    /// `rot = (cos, sin)` in the (x1, x2) plane: uncertain scale s, uncertain offsets.
    Ellipsoid {
        /// Scale s (≈ 1).
        size: Unc,
        /// D_k = 1/(semi-axis k)².
        inv_sq: Vec<f64>,
        /// (cos θ, sin θ); (1, 0) is axis-aligned.
        rot: (f64, f64),
        /// Offset per axis.
        offset: Vec<Unc>,
    },
    /// Nonconvex "peanut" `k − f₁·f₂`, f₁ = |u − shift·e₁|² − r₁², f₂ = |u − b|² − r₂²:
    /// two lobes joined by a waist; uncertain lobe shift (degree 2), r₁² and k (degree 1).
    Peanut {
        /// Shift of lobe 1 along x1.
        shift: Unc,
        /// Centre of lobe 2 relative to c(t).
        lobe: Vec<f64>,
        /// r₁².
        r1sq: Unc,
        /// r₂².
        r2sq: f64,
        /// k > 0.
        k: Unc,
    },
    /// Superellipse `R⁴ − Σ_d u_d⁴` with uncertain R⁴ (degree 1).
    Superellipse {
        /// R⁴.
        r4: Unc,
    },
    /// "Pedestrian": a disk/ball `r² − Σ_d (u_d − p_d − v_d·(t − t_ref))²` whose centre
    /// c(t) + p + v·(t − t_ref) carries a position error p and a velocity error v (in
    /// generated scenes independent zero-mean Gaussian parameters per axis, c(t) linear:
    /// the centre is p₀ + ω_p + (v₀ + ω_v)·(t − t₀)); radius fixed or uncertain.
    Pedestrian {
        /// Radius r.
        radius: Unc,
        /// Position error per axis (at t = t_ref).
        pos: Vec<Unc>,
        /// Velocity error per axis.
        vel: Vec<Unc>,
        /// The time at which the position error is the whole error (the horizon's t₀).
        t_ref: f64,
    },
}

impl Shape {
    /// Short name: `ball`, `ellipsoid`, `quartic`.
    pub fn class(&self) -> &'static str {
        match self {
            Shape::Ball { .. } => "ball",
            Shape::Ellipsoid { .. } => "ellipsoid",
            Shape::Peanut { .. } | Shape::Superellipse { .. } => "quartic",
            Shape::Pedestrian { .. } => "pedestrian",
        }
    }
}

/// `r² − Σ_d (u_d − z_d)²` (a missing `z_d` gives NaN).
fn disk(r: f64, u: &[f64], z: &[f64]) -> f64 {
    r * r - u.iter().enumerate().map(|(d, u)| (u - at(z, d)).powi(2)).sum::<f64>()
}

/// The radius around a pedestrian's nominal centre outside which it is safe at level
/// `delta` by Cantelli's inequality (paper, eq. 10), for radius `r` taken as fixed and
/// an isotropic Gaussian centre error of sd `s` per axis in `dim` dimensions: with
/// ρ = |u|, E\[P\] = r² − ρ² − dim·s² and Var\[P\] = 4ρ²s² + 2·dim·s⁴, the point is safe
/// when E\[P\] < 0 and E\[P\]² ≥ k²·Var\[P\], k² = (1 − Δ)/Δ: ρ² at least the larger root of
/// (ρ² + a)² − k²(4s²ρ² + 2·dim·s⁴), a = dim·s² − r².
pub fn pedestrian_cantelli_radius(r: f64, s: f64, dim: usize, delta: f64) -> f64 {
    let n = dim as f64;
    let k2 = (1.0 - delta) / delta;
    let a = n * s * s - r * r;
    let b = a - 2.0 * k2 * s * s;
    let disc = (b * b - a * a + 2.0 * n * k2 * s.powi(4)).max(0.0);
    let y = (-b + disc.sqrt()).max(-a).max(0.0);
    y.sqrt()
}

/// One uncertain parameter.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParamSpec {
    /// Name in the scene (`o3_r`, …).
    pub name: String,
    /// Distribution.
    pub dist: Dist,
}

/// One obstacle: `{x : P(x, ω, t) ≥ 0}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ObstacleSpec {
    /// Id in the scene.
    pub id: String,
    /// Shape around c(t).
    pub shape: Shape,
    /// Motion of c(t).
    pub motion: Motion,
    /// Its parameters (≤ [`MAX_PARAMS`], a pedestrian ≤ [`MAX_PEDESTRIAN_PARAMS`]), in
    /// the order `Unc::param` indexes.
    pub params: Vec<ParamSpec>,
    /// Radius around c(t) outside which P < 0 for all but rare parameter values
    /// (bounding radius with [`BOUND_SIGMAS`] of the uncertainty).
    pub bound: f64,
    /// Smallest feature size (smallest semi-axis or lobe radius).
    pub feature: f64,
}

impl ObstacleSpec {
    /// P(x, ω, t) evaluated directly from the structure (no polynomial expansion).
    pub fn eval(&self, x: &[f64], t: f64, w: &[f64]) -> f64 {
        let c = self.motion.centre(t);
        let u: Vec<f64> = x.iter().zip(&c).map(|(x, c)| x - c).collect();
        match &self.shape {
            Shape::Ball { radius, offset } => {
                let r = radius.value(w);
                r * r - u.iter().zip(offset).map(|(u, o)| (u - o.value(w)).powi(2)).sum::<f64>()
            }
            Shape::Ellipsoid { size, inv_sq, rot, offset } => {
                let s = size.value(w);
                let y: Vec<f64> = u.iter().zip(offset).map(|(u, o)| u - o.value(w)).collect();
                let (co, si) = *rot;
                let mut z = y.clone();
                if let [y0, y1, ..] = y[..] {
                    z[0] = co * y0 + si * y1;
                    z[1] = -si * y0 + co * y1;
                }
                s * s - z.iter().zip(inv_sq).map(|(z, d)| d * z * z).sum::<f64>()
            }
            Shape::Peanut { shift, lobe, r1sq, r2sq, k } => {
                let sh = shift.value(w);
                let f1: f64 =
                    u.iter().enumerate().map(|(d, u)| (u - if d == 0 { sh } else { 0.0 }).powi(2)).sum::<f64>()
                        - r1sq.value(w);
                let f2: f64 = u.iter().zip(lobe).map(|(u, b)| (u - b).powi(2)).sum::<f64>() - r2sq;
                k.value(w) - f1 * f2
            }
            Shape::Superellipse { r4 } => r4.value(w) - u.iter().map(|u| u.powi(4)).sum::<f64>(),
            Shape::Pedestrian { radius, pos, vel, t_ref } => {
                let z: Vec<f64> = pos.iter().zip(vel).map(|(p, v)| p.value(w) + v.value(w) * (t - t_ref)).collect();
                disk(radius.value(w), &u, &z)
            }
        }
    }

    /// A pedestrian's P(x, ω, t) with its centre error at time t given as `z` (per axis:
    /// p + v·(t − t_ref)) instead of computed from the position and velocity errors'
    /// parameters; `w` gives the others (the radius's). NaN for the other shapes. The
    /// oracle's quadrature of Gaussian errors uses it.
    pub fn eval_with_centre_error(&self, x: &[f64], t: f64, w: &[f64], z: &[f64]) -> f64 {
        match &self.shape {
            Shape::Pedestrian { radius, .. } => {
                let c = self.motion.centre(t);
                let u: Vec<f64> = x.iter().zip(&c).map(|(x, c)| x - c).collect();
                disk(radius.value(w), &u, z)
            }
            _ => f64::NAN,
        }
    }

    /// The polynomial text of the scene format, in absolute coordinates and time.
    pub fn poly_text(&self) -> String {
        let names: Vec<String> = self.params.iter().map(|p| p.name.clone()).collect();
        let dim = self.motion.c0.len();
        let u = |d: usize| format!("(x{} - {})", d + 1, self.motion.text(d));
        let uo = |d: usize, o: &Unc| {
            if o.param.is_none() && o.base == 0.0 {
                u(d)
            } else {
                format!("(x{} - {} - {})", d + 1, self.motion.text(d), o.text(&names))
            }
        };
        match &self.shape {
            Shape::Ball { radius, offset } => {
                let mut s = format!("{}^2", radius.text(&names));
                for (d, o) in offset.iter().enumerate() {
                    s += &format!(" - {}^2", uo(d, o));
                }
                s
            }
            Shape::Ellipsoid { size, inv_sq, rot, offset } => {
                let y: Vec<String> = offset.iter().enumerate().map(|(d, o)| uo(d, o)).collect();
                let (co, si) = *rot;
                let mut s = format!("{}^2", size.text(&names));
                for (d, dk) in inv_sq.iter().enumerate() {
                    let z = match d {
                        0 if si != 0.0 && y.len() >= 2 => format!("({}*{} + {}*{})", num(co), y[0], num(si), y[1]),
                        1 if si != 0.0 && y.len() >= 2 => format!("({}*{} + {}*{})", num(-si), y[0], num(co), y[1]),
                        _ => y.get(d).cloned().unwrap_or_else(|| "?".into()),
                    };
                    s += &format!(" - {}*{}^2", num(*dk), z);
                }
                s
            }
            Shape::Peanut { shift, lobe, r1sq, r2sq, k } => {
                let mut f1 = format!("(x1 - {} - {})^2", self.motion.text(0), shift.text(&names));
                for d in 1..dim {
                    f1 += &format!(" + {}^2", u(d));
                }
                f1 += &format!(" - {}", r1sq.text(&names));
                let f2: Vec<String> = (0..dim)
                    .map(|d| format!("(x{} - {} - {})^2", d + 1, self.motion.text(d), num(at(lobe, d))))
                    .collect();
                format!("{} - ({f1})*({} - {})", k.text(&names), f2.join(" + "), num(*r2sq))
            }
            Shape::Superellipse { r4 } => {
                let mut s = r4.text(&names);
                for d in 0..dim {
                    s += &format!(" - {}^4", u(d));
                }
                s
            }
            Shape::Pedestrian { radius, pos, vel, t_ref } => {
                let mut s = format!("{}^2", radius.text(&names));
                for d in 0..dim {
                    let mut ud = format!("x{} - {}", d + 1, self.motion.text(d));
                    match pos.get(d) {
                        Some(p) if p.param.is_some() || p.base != 0.0 => ud += &format!(" - {}", p.text(&names)),
                        Some(_) => {}
                        None => ud += " - ?", // a missing axis does not parse
                    }
                    match vel.get(d) {
                        Some(v) if v.param.is_some() || v.base != 0.0 => {
                            ud += &format!(" - {}*(t - {})", v.text(&names), num(*t_ref));
                        }
                        Some(_) => {}
                        None => ud += " - ?", // a missing axis does not parse
                    }
                    s += &format!(" - ({ud})^2");
                }
                s
            }
        }
    }
}

/// What the generator meant a scene to be.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Intent {
    /// Obstacles placed clear of start and goal, no wall, reachable.
    Feasible,
    /// An obstacle covers the start at t₀ or the goal at t_f.
    EndpointInObstacle,
    /// A static wall of obstacles cuts the workspace between start and goal.
    Wall,
    /// |goal − start| > max_speed·(t_f − t₀).
    OutOfReach,
}

impl Intent {
    /// Whether the scene is meant to be feasible.
    pub fn feasible(self) -> bool {
        self == Intent::Feasible
    }
}

/// One generated scene.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GeneratedScene {
    /// Suite seed.
    pub seed: u64,
    /// Index within the suite.
    pub index: usize,
    /// Scene name.
    pub name: String,
    /// Dimension (2 or 3).
    pub dim: usize,
    /// Workspace lower corner.
    pub lower: Vec<f64>,
    /// Workspace upper corner.
    pub upper: Vec<f64>,
    /// [t₀, t_f].
    pub horizon: (f64, f64),
    /// Δ.
    pub delta: f64,
    /// Start (at t₀).
    pub start: Vec<f64>,
    /// Goal (at t_f).
    pub goal: Vec<f64>,
    /// The speed limit, if the scene has one (also in the JSON's `planner.max_speed`).
    pub max_speed: Option<f64>,
    /// Obstacles.
    pub obstacles: Vec<ObstacleSpec>,
    /// What it was meant to be.
    pub intent: Intent,
}

impl GeneratedScene {
    /// Whether any obstacle moves.
    pub fn moving(&self) -> bool {
        self.obstacles.iter().any(|o| o.motion.kind != MotionKind::Static)
    }

    /// The largest workspace side.
    pub fn width(&self) -> f64 {
        self.lower.iter().zip(&self.upper).map(|(l, u)| u - l).fold(0.0, f64::max)
    }

    /// Whether some parameter has only moments (riskplan's Monte Carlo cannot sample it).
    pub fn has_moments_param(&self) -> bool {
        self.obstacles.iter().flat_map(|o| &o.params).any(|p| matches!(p.dist, Dist::Moments { .. }))
    }

    /// The shape classes present, sorted and joined with `+` (e.g. `ball+quartic`).
    pub fn shape_mix(&self) -> String {
        let mut v: Vec<&str> = self.obstacles.iter().map(|o| o.shape.class()).collect();
        v.sort();
        v.dedup();
        v.join("+")
    }

    /// The scene as scene-format v1 JSON.
    pub fn json_value(&self) -> Value {
        let mut params = serde_json::Map::new();
        for o in &self.obstacles {
            for p in &o.params {
                params.insert(p.name.clone(), p.dist.json());
            }
        }
        let obstacles: Vec<Value> = self.obstacles.iter().map(|o| json!({"id": o.id, "poly": o.poly_text()})).collect();
        let mut v = json!({
            "format": "riskplan-scene/1",
            "name": self.name,
            "description": format!("robustness suite seed {} scene {}: {:?}", self.seed, self.index, self.intent),
            "dim": self.dim,
            "workspace": {"lower": self.lower, "upper": self.upper},
            "horizon": [self.horizon.0, self.horizon.1],
            "risk": self.delta,
            "params": params,
            "obstacles": obstacles,
            "start": self.start,
            "goal": self.goal,
            "expected": {"intent": self.intent},
        });
        if let Some(s) = self.max_speed {
            v["planner"] = json!({"max_speed": s});
        }
        v
    }

    /// The scene as scene-format v1 JSON text.
    pub fn json(&self) -> String {
        serde_json::to_string_pretty(&self.json_value()).unwrap_or_default()
    }
}

fn log_uniform(rng: &mut ChaCha12Rng, (lo, hi): (f64, f64)) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * rng.random::<f64>()).exp()
}

fn unif(rng: &mut ChaCha12Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// SplitMix64 finaliser: one well-mixed RNG seed per (seed, index).
fn mix(seed: u64, index: u64) -> u64 {
    let mut z = seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(0x6A09_E667_F3BC_C909);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Draws a distribution of `family` with random parameters.
fn draw_dist(rng: &mut ChaCha12Rng, family: &str) -> Dist {
    let r1 = |rng: &mut ChaCha12Rng, lo: f64, hi: f64| (unif(rng, lo, hi) * 100.0).round() / 100.0;
    match family {
        "uniform" => {
            let low = r1(rng, -1.0, 0.5);
            Dist::Uniform { low, high: low + r1(rng, 0.3, 2.0) }
        }
        "normal" => Dist::Normal { mean: r1(rng, -1.0, 1.0), std: r1(rng, 0.1, 1.0) },
        "beta" => {
            let (low, high) = if rng.random::<bool>() { (0.0, 1.0) } else { (r1(rng, -2.0, 0.0), r1(rng, 0.5, 2.0)) };
            Dist::Beta { alpha: r1(rng, 0.6, 5.0), beta: r1(rng, 0.6, 5.0), low, high }
        }
        "gamma" => Dist::Gamma { shape: r1(rng, 0.8, 6.0), scale: r1(rng, 0.2, 2.0) },
        "exponential" => Dist::Exponential { rate: r1(rng, 0.5, 3.0) },
        "laplace" => Dist::Laplace { mean: r1(rng, -1.0, 1.0), scale: r1(rng, 0.1, 1.0) },
        "discrete" => {
            let n = rng.random_range(2..=5usize);
            let mut values: Vec<f64> = (0..n).map(|_| r1(rng, -2.0, 2.0)).collect();
            values.sort_by(f64::total_cmp);
            values.dedup();
            if values.len() < 2 {
                values.push(values[0] + 1.0);
            }
            // whole percents summing to exactly 100
            let n = values.len();
            let mut pct: Vec<u32> = (0..n).map(|_| rng.random_range(5..=40u32)).collect();
            let total: u32 = pct.iter().sum();
            let mut acc = 0;
            for p in pct.iter_mut().take(n - 1) {
                *p = (*p * 100 / total).max(1);
                acc += *p;
            }
            pct[n - 1] = 100 - acc;
            Dist::Discrete { values, weights: pct.iter().map(|&p| p as f64 / 100.0).collect() }
        }
        _ => {
            let lo = rng.random_range(-40..=10i64);
            let hi = lo + rng.random_range(5..=40i64);
            // −40 ≤ lo < hi ≤ 50: the casts are exact (drawn as i64 so the stream of draws stays as it was)
            Dist::moments_of_uniform(lo as i16, hi as i16, 20)
        }
    }
}

struct Builder<'a> {
    rng: &'a mut ChaCha12Rng,
    family_counter: usize,
    /// Whether this scene may use `moments` parameters (see [`MOMENTS_SCENE_EVERY`]).
    allow_moments: bool,
    obstacle: usize,
    params: Vec<ParamSpec>,
}

impl Builder<'_> {
    /// A quantity of mean `mean` and standard deviation `sd`, through a fresh
    /// parameter of the next family (or constant when sd = 0).
    fn unc(&mut self, role: &str, mean: f64, sd: f64) -> Unc {
        if sd == 0.0 || self.params.len() >= MAX_PARAMS {
            return Unc::fixed(mean);
        }
        let mut family = FAMILIES[self.family_counter % FAMILIES.len()];
        self.family_counter += 1;
        if family == "moments" && !self.allow_moments {
            family = FAMILIES[self.family_counter % FAMILIES.len()];
            self.family_counter += 1;
        }
        let dist = draw_dist(self.rng, family);
        let (m, s) = dist.mean_sd();
        let scale = q(sd / s);
        let base = q(mean - scale * m);
        self.params.push(ParamSpec { name: format!("o{}_{role}", self.obstacle), dist });
        Unc { base, scale, param: Some(self.params.len() - 1) }
    }

    /// A zero-mean Gaussian quantity of standard deviation `sd` (already rounded): a
    /// fresh `normal` parameter of mean 0 and that sd, entering with factor 1 (no family
    /// of the cycle is used up; constant 0 when sd = 0).
    fn gaussian(&mut self, role: &str, sd: f64) -> Unc {
        if sd == 0.0 || self.params.len() >= MAX_PEDESTRIAN_PARAMS {
            return Unc::fixed(0.0);
        }
        let dist = Dist::Normal { mean: 0.0, std: sd };
        self.params.push(ParamSpec { name: format!("o{}_{role}", self.obstacle), dist });
        Unc { base: 0.0, scale: 1.0, param: Some(self.params.len() - 1) }
    }
}

/// Parameters of one obstacle to build.
struct ObstaclePlan {
    shape: &'static str,
    size: f64,
    centre: Vec<f64>,
    motion: MotionKind,
    /// displacement scale over the horizon
    travel: f64,
    /// relative uncertainty (sd of size over size)
    rel_sd: f64,
    /// semi-axes for ellipsoids (overrides random ones)
    axes: Option<Vec<f64>>,
    /// may use `moments` parameters
    allow_moments: bool,
    /// the scene's width (a pedestrian's errors scale with it)
    width: f64,
    /// the scene's Δ (a pedestrian's bounding radius is its Cantelli radius at Δ/2)
    delta: f64,
}

fn build_obstacle(
    rng: &mut ChaCha12Rng,
    family_counter: &mut usize,
    index: usize,
    p: &ObstaclePlan,
    horizon: (f64, f64),
) -> ObstacleSpec {
    let dim = p.centre.len();
    let (t0, tf) = horizon;
    let len = tf - t0;
    let tm = 0.5 * (t0 + tf);
    // motion: c(t) = cm + v (t − tm) + a (t − tm)², rewritten in absolute t
    let dir = |rng: &mut ChaCha12Rng| {
        let v: Vec<f64> = (0..dim).map(|_| unif(rng, -1.0, 1.0)).collect();
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-9);
        v.into_iter().map(|x| x / n).collect::<Vec<f64>>()
    };
    let mut vel = vec![0.0; dim];
    let mut acc = vec![0.0; dim];
    if p.motion != MotionKind::Static {
        let d = dir(rng);
        let speed = p.travel / len;
        vel = d.iter().map(|x| x * speed).collect();
    }
    if p.motion == MotionKind::Quadratic {
        let d = dir(rng);
        let a = 2.0 * p.travel / (len * len);
        acc = d.iter().map(|x| x * a).collect();
    }
    let c0: Vec<f64> = (0..dim).map(|d| q(p.centre[d] - vel[d] * tm + acc[d] * tm * tm)).collect();
    let v: Vec<f64> = (0..dim).map(|d| q(vel[d] - 2.0 * acc[d] * tm)).collect();
    let a: Vec<f64> = acc.iter().map(|x| q(*x)).collect();
    let motion = Motion { kind: p.motion, c0, v, a };

    let allow_moments = p.allow_moments;
    let mut b = Builder { rng, family_counter: *family_counter, allow_moments, obstacle: index, params: vec![] };
    let s = p.size;
    let rel = p.rel_sd;
    let (shape, bound, feature) = match p.shape {
        "ball" => {
            let radius = b.unc("r", s, rel * s);
            let off_axis = b.rng.random_range(0..dim);
            let with_offset = b.rng.random::<f64>() < 0.6;
            let offset: Vec<Unc> = (0..dim)
                .map(|d| {
                    if with_offset && d == off_axis {
                        b.unc(&format!("d{}", d + 1), 0.0, rel * s)
                    } else {
                        Unc::fixed(0.0)
                    }
                })
                .collect();
            let bound = s * (1.0 + BOUND_SIGMAS * rel) + if with_offset { BOUND_SIGMAS * rel * s } else { 0.0 };
            (Shape::Ball { radius, offset }, bound, s)
        }
        "ellipsoid" => {
            let axes: Vec<f64> = p
                .axes
                .clone()
                .unwrap_or_else(|| (0..dim).map(|d| if d == 0 { s } else { q(s * unif(b.rng, 0.35, 1.0)) }).collect());
            let inv_sq: Vec<f64> = axes.iter().map(|a| q(1.0 / (a * a))).collect();
            let rot = if p.axes.is_none() && b.rng.random::<bool>() {
                let th = unif(b.rng, 0.0, PI);
                (q(th.cos()), q(th.sin()))
            } else {
                (1.0, 0.0)
            };
            let size = b.unc("s", 1.0, rel);
            let off_axis = b.rng.random_range(0..dim);
            let with_offset = p.axes.is_none() && b.rng.random::<f64>() < 0.5;
            let amax = axes.iter().cloned().fold(0.0, f64::max);
            let amin = axes.iter().cloned().fold(f64::INFINITY, f64::min);
            let offset: Vec<Unc> = (0..dim)
                .map(|d| {
                    if with_offset && d == off_axis {
                        b.unc(&format!("d{}", d + 1), 0.0, rel * amin)
                    } else {
                        Unc::fixed(0.0)
                    }
                })
                .collect();
            let bound =
                amax * (1.0 + BOUND_SIGMAS * rel) * 1.01 + if with_offset { BOUND_SIGMAS * rel * amin } else { 0.0 };
            (Shape::Ellipsoid { size, inv_sq, rot, offset }, bound, amin)
        }
        "peanut" => {
            // lobe radii r and ρ·r, centres 2.4·r apart, waist k ≈ 0.3 r⁴ (bridged)
            let r = s * 0.45;
            let rho = unif(b.rng, 0.7, 1.0);
            let d = dir(b.rng);
            let sep = 2.4 * r * (1.0 + rho) / 2.0;
            let lobe: Vec<f64> = d.iter().map(|x| q(x * sep)).collect();
            let shift = b.unc("sh", 0.0, rel * r);
            let r1sq = b.unc("r1", r * r, 2.0 * rel * r * r);
            let r2sq = q((rho * r).powi(2));
            let k = b.unc("k", 0.3 * r.powi(4) * rho * rho, 0.3 * r.powi(4) * rho * rho * 2.0 * rel);
            let bound = (sep + rho * r) * (1.0 + BOUND_SIGMAS * rel) + r * 0.2;
            (Shape::Peanut { shift, lobe, r1sq, r2sq, k }, bound, rho * r)
        }
        "pedestrian" => {
            let uncertain = b.rng.random::<f64>() < PEDESTRIAN_UNCERTAIN_RADIUS;
            let rel = rel * PEDESTRIAN_RADIUS_REL;
            let radius = if uncertain { b.unc("r", s, rel * s) } else { Unc::fixed(s) };
            let sp = q(p.width * unif(b.rng, PEDESTRIAN_POS_SD.0, PEDESTRIAN_POS_SD.1));
            let sv = q(p.width * unif(b.rng, PEDESTRIAN_DRIFT_SD.0, PEDESTRIAN_DRIFT_SD.1) / len);
            let pos: Vec<Unc> = (0..dim).map(|d| b.gaussian(&format!("p{}", d + 1), sp)).collect();
            let vel: Vec<Unc> = (0..dim).map(|d| b.gaussian(&format!("v{}", d + 1), sv)).collect();
            // the centre error's sd per axis at the horizon's end (the largest)
            let s_end = (sp * sp + sv * sv * len * len).sqrt();
            let r_max = s * (1.0 + if uncertain { BOUND_SIGMAS * rel } else { 0.0 });
            let tight = p.delta * TIGHT_FACTOR;
            let bound = pedestrian_cantelli_radius(r_max, s_end, dim, tight)
                .max(r_max + BOUND_SIGMAS * s_end * (dim as f64).sqrt());
            (Shape::Pedestrian { radius, pos, vel, t_ref: t0 }, bound, s)
        }
        _ => {
            let r4 = b.unc("r4", s.powi(4), 4.0 * rel * s.powi(4));
            let bound = s * (dim as f64).powf(0.25) * (1.0 + 4.0 * BOUND_SIGMAS * rel).powf(0.25);
            (Shape::Superellipse { r4 }, bound, s)
        }
    };
    *family_counter = b.family_counter;
    ObstacleSpec { id: format!("o{index}"), shape, motion, params: b.params, bound, feature }
}

/// Whether the obstacle's bounding sphere plus `margin` keeps clear of `p` at the times
/// `times`.
fn clear_of(o: &ObstacleSpec, p: &[f64], times: &[f64], margin: f64) -> bool {
    // the peanut's second lobe is offset from c(t): test distance to both lobes' span
    times.iter().all(|&t| {
        let c = o.motion.centre(t);
        let dist = c.iter().zip(p).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        dist > o.bound + margin
    })
}

/// Generates scene `index` of the suite with seed `seed`.
pub fn generate(seed: u64, index: usize) -> GeneratedScene {
    let mut rng = ChaCha12Rng::seed_from_u64(mix(seed, index as u64));
    let rng = &mut rng;
    let dim = if rng.random::<f64>() < TWO_D_SHARE { 2 } else { 3 };
    let width = log_uniform(rng, WIDTH_RANGE);
    let sides: Vec<f64> = (0..dim).map(|d| if d == 0 { width } else { width * unif(rng, 0.7, 1.0) }).collect();
    let lower: Vec<f64> = sides.iter().map(|s| q(unif(rng, -MAX_OFFSET, MAX_OFFSET - s))).collect();
    let upper: Vec<f64> = lower.iter().zip(&sides).map(|(l, s)| q(l + s)).collect();
    let sides: Vec<f64> = lower.iter().zip(&upper).map(|(l, u)| u - l).collect();
    let min_side = sides.iter().cloned().fold(f64::INFINITY, f64::min);
    let scene_width = sides.iter().cloned().fold(0.0, f64::max);
    let mut t0 = (unif(rng, T0_RANGE.0, T0_RANGE.1) * 100.0).round() / 100.0;
    if t0 == 0.0 {
        t0 = 0.25;
    }
    let len = (log_uniform(rng, HORIZON_LENGTH_RANGE) * 100.0).round().max(20.0) / 100.0;
    let horizon = (t0, q(t0 + len));
    let len = horizon.1 - horizon.0;
    let delta = (unif(rng, DELTA_RANGE.0, DELTA_RANGE.1) * 1000.0).round() / 1000.0;

    let intent = if rng.random::<f64>() < FEASIBLE_SHARE {
        Intent::Feasible
    } else {
        [Intent::EndpointInObstacle, Intent::Wall, Intent::OutOfReach][rng.random_range(0..3usize)]
    };
    let moving = intent != Intent::Wall && rng.random::<f64>() < MOVING_SHARE;

    // start and goal near opposite sides, along a random diagonal
    let mut start = vec![0.0; dim];
    let mut goal = vec![0.0; dim];
    for d in 0..dim {
        let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let mid = 0.5 * (lower[d] + upper[d]);
        let (fs, fg) = if d == 0 {
            (unif(rng, 0.35, 0.45), unif(rng, 0.35, 0.45))
        } else {
            (unif(rng, 0.1, 0.45), unif(rng, 0.1, 0.45))
        };
        start[d] = q(mid - sign * sides[d] * fs);
        goal[d] = q(mid + sign * sides[d] * fg);
    }
    let dist = start.iter().zip(&goal).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
    let straight_speed = dist / len;
    let max_speed = match intent {
        Intent::OutOfReach => {
            Some(q(straight_speed * unif(rng, UNREACHABLE_SPEED_FACTOR.0, UNREACHABLE_SPEED_FACTOR.1)))
        }
        Intent::Feasible if rng.random::<f64>() < SPEED_LIMIT_SHARE => {
            Some(q(straight_speed * unif(rng, FEASIBLE_SPEED_FACTOR.0, FEASIBLE_SPEED_FACTOR.1)))
        }
        _ => None,
    };

    let times: Vec<f64> =
        (0..CLEARANCE_TIMES).map(|k| horizon.0 + len * k as f64 / (CLEARANCE_TIMES - 1) as f64).collect();
    let mut family_counter = index * 3;
    let allow_moments = index % MOMENTS_SCENE_EVERY == 0;
    let mut obstacles: Vec<ObstacleSpec> = vec![];
    let n_max = if dim == 2 { 8 } else { 6 };
    let n_random = rng.random_range(1..=n_max);

    // the intended obstruction first
    match intent {
        Intent::EndpointInObstacle => {
            let at_start = rng.random::<bool>();
            let (p, t) = if at_start { (&start, horizon.0) } else { (&goal, horizon.1) };
            let size = min_side * unif(rng, 0.06, 0.1);
            let kind = if moving { MotionKind::Linear } else { MotionKind::Static };
            let plan = ObstaclePlan {
                shape: "ball",
                size,
                centre: p.clone(),
                motion: kind,
                travel: min_side * 0.2,
                rel_sd: 0.03,
                axes: None,
                allow_moments,
                width: scene_width,
                delta,
            };
            let mut o = build_obstacle(rng, &mut family_counter, 0, &plan, horizon);
            // re-anchor so that c(t) = p exactly at the endpoint's time
            let c = o.motion.centre(t);
            for d in 0..dim {
                o.motion.c0[d] = q(o.motion.c0[d] + p[d] - c[d]);
            }
            obstacles.push(o);
        }
        Intent::Wall => {
            // 2 or 3 flat ellipses/ellipsoids across the axis of largest separation
            let axis = (0..dim)
                .max_by(|&a, &b| (goal[a] - start[a]).abs().total_cmp(&(goal[b] - start[b]).abs()))
                .unwrap_or(0);
            let other = (axis + 1) % dim;
            let pos = 0.5 * (start[axis] + goal[axis]);
            let parts = rng.random_range(2..=3usize);
            let thick = sides[axis] * 0.06;
            for k in 0..parts {
                let mut centre: Vec<f64> = (0..dim).map(|d| 0.5 * (lower[d] + upper[d])).collect();
                centre[axis] = pos;
                centre[other] = lower[other] + sides[other] * (k as f64 + 0.5) / parts as f64;
                let mut axes = vec![0.0; dim];
                for d in 0..dim {
                    axes[d] = q(if d == axis {
                        thick
                    } else if d == other {
                        sides[other] * 1.1 / parts as f64
                    } else {
                        sides[d] * 1.5
                    });
                }
                // the x1 axis of an ellipsoid is its first semi-axis: write axes per coordinate
                let plan = ObstaclePlan {
                    shape: "ellipsoid",
                    size: axes[0],
                    centre,
                    motion: MotionKind::Static,
                    travel: 0.0,
                    rel_sd: 0.02,
                    axes: Some(axes),
                    allow_moments,
                    width: scene_width,
                    delta,
                };
                let o = build_obstacle(rng, &mut family_counter, obstacles.len(), &plan, horizon);
                obstacles.push(o);
            }
        }
        _ => {}
    }
    let crowd = ((n_random as f64) / 4.0).sqrt().max(1.0);
    let mut any_moving = false;
    for k in 0..n_random {
        if obstacles.len() >= n_max {
            break;
        }
        let u = rng.random::<f64>();
        let mut shape = if u < 0.4 {
            "ball"
        } else if u < 0.72 {
            "ellipsoid"
        } else if rng.random::<f64>() < 0.7 {
            "peanut"
        } else {
            "superellipse"
        };
        let mut motion = if !moving {
            MotionKind::Static
        } else if !any_moving && k + 1 == n_random {
            MotionKind::Linear
        } else {
            let m = rng.random::<f64>();
            if m < 0.3 {
                MotionKind::Static
            } else if m < 0.7 {
                MotionKind::Linear
            } else {
                MotionKind::Quadratic
            }
        };
        // quartics move at most linearly, and only in 2-D (term limits of the format)
        if (shape == "peanut" || shape == "superellipse")
            && (motion == MotionKind::Quadratic || (dim == 3 && motion != MotionKind::Static))
        {
            shape = if rng.random::<bool>() { "ball" } else { "ellipsoid" };
        }
        // pedestrians only in scenes with moving obstacles (static scenes draw nothing
        // more, so they are the scenes they were before pedestrians)
        if moving && rng.random::<f64>() < PEDESTRIAN_SHARE {
            shape = "pedestrian";
            motion = MotionKind::Linear;
        }
        let size = min_side * unif(rng, 0.05, 0.13) / crowd;
        let rel_sd = unif(rng, 0.03, 0.12);
        let travel = min_side * unif(rng, 0.1, 0.5);
        for _ in 0..PLACEMENT_TRIES {
            let centre: Vec<f64> = (0..dim).map(|d| unif(rng, lower[d], upper[d])).collect();
            let plan = ObstaclePlan {
                shape,
                size,
                centre,
                motion,
                travel,
                rel_sd,
                axes: None,
                allow_moments,
                width: scene_width,
                delta,
            };
            let mut fc = family_counter;
            let o = build_obstacle(rng, &mut fc, obstacles.len(), &plan, horizon);
            let margin = ENDPOINT_CLEARANCE * min_side;
            if clear_of(&o, &start, &times, margin) && clear_of(&o, &goal, &times, margin) {
                family_counter = fc;
                any_moving |= motion != MotionKind::Static;
                obstacles.push(o);
                break;
            }
        }
    }
    GeneratedScene {
        seed,
        index,
        name: format!("robust-{seed}-{index}"),
        dim,
        lower,
        upper,
        horizon,
        delta,
        start,
        goal,
        max_speed,
        obstacles,
        intent,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic() {
        for i in [0, 7, 55] {
            assert_eq!(generate(3, i), generate(3, i));
            assert_eq!(generate(3, i).json(), generate(3, i).json());
        }
        assert_ne!(generate(3, 1).json(), generate(4, 1).json());
    }

    /// Every generated obstacle's polynomial text, read by the crate's own parser
    /// ([`crate::expr`]), agrees with the structural [`ObstacleSpec::eval`] at random
    /// points, times and parameter values, for every shape class including pedestrians.
    #[test]
    fn poly_text_matches_structure() {
        let mut rng = ChaCha12Rng::seed_from_u64(17);
        let mut classes = std::collections::BTreeSet::new();
        for i in 0..120 {
            let g = generate(1, i);
            for o in &g.obstacles {
                classes.insert(o.shape.class());
                let e = crate::expr::Expr::parse(&o.poly_text()).unwrap_or_else(|e| panic!("scene {i} {}: {e}", o.id));
                for _ in 0..4 {
                    let w: Vec<f64> = o.params.iter().map(|p| p.dist.sample(&mut rng)).collect();
                    let t = unif(&mut rng, g.horizon.0, g.horizon.1);
                    let c = o.motion.centre(t);
                    let x: Vec<f64> = c.iter().map(|c| c + o.bound * unif(&mut rng, -1.5, 1.5)).collect();
                    let lookup = |name: &str| -> Option<f64> {
                        if name == "t" {
                            return Some(t);
                        }
                        if let Some(d) = name.strip_prefix('x').and_then(|d| d.parse::<usize>().ok()) {
                            return x.get(d - 1).copied();
                        }
                        o.params.iter().position(|p| p.name == name).map(|k| w[k])
                    };
                    let text = e.eval(&lookup).unwrap_or(f64::NAN);
                    let direct = o.eval(&x, t, &w);
                    // cancellation scale: the terms are of the size of the squared or
                    // fourth-power coordinates relative to the origin
                    let big = x.iter().chain(&c).fold(1.0f64, |m, v| m.max(v.abs())) + t.abs();
                    let scale = 1.0 + direct.abs() + big.powi(if o.shape.class() == "quartic" { 4 } else { 2 });
                    assert!((direct - text).abs() <= 1e-9 * scale, "scene {i} {}: {direct} vs {text}", o.id);
                }
            }
        }
        assert_eq!(classes.len(), 4, "{classes:?}");
    }

    /// A pedestrian: its text and structure agree (with fixed and uncertain parts, a
    /// negative t_ref), the centre error shifts the disk as p + v·(t − t_ref), and
    /// [`ObstacleSpec::eval_with_centre_error`] is `eval` with that error.
    #[test]
    fn pedestrian_structure() {
        let n = |name: &str, std: f64| ParamSpec { name: name.into(), dist: Dist::Normal { mean: 0.0, std } };
        let g = |i: usize| Unc { base: 0.0, scale: 1.0, param: Some(i) };
        let o = ObstacleSpec {
            id: "o0".into(),
            shape: Shape::Pedestrian {
                radius: Unc { base: 0.5, scale: 0.02, param: Some(0) },
                pos: vec![g(1), Unc::fixed(0.25)],
                vel: vec![g(2), g(3)],
                t_ref: -2.5,
            },
            motion: Motion { kind: MotionKind::Linear, c0: vec![100.0, -40.0], v: vec![0.5, -0.25], a: vec![0.0; 2] },
            params: vec![
                ParamSpec { name: "o0_r".into(), dist: Dist::Uniform { low: -1.0, high: 1.0 } },
                n("o0_p1", 0.1),
                n("o0_v1", 0.05),
                n("o0_v2", 0.05),
            ],
            bound: 1.0,
            feature: 0.5,
        };
        let text = o.poly_text();
        let e = crate::expr::Expr::parse(&text).unwrap();
        let w = [0.3, -0.2, 0.1, -0.05];
        let (x, t) = ([101.0, -41.5], 1.5);
        let lookup = |name: &str| match name {
            "x1" => Some(x[0]),
            "x2" => Some(x[1]),
            "t" => Some(t),
            _ => o.params.iter().position(|p| p.name == name).map(|k| w[k]),
        };
        let direct = o.eval(&x, t, &w);
        assert!((e.eval(&lookup).unwrap() - direct).abs() < 1e-9, "{text}");
        // by hand: centre (100 + 0.5·1.5 − 0.2 + 0.1·4, −40 − 0.25·1.5 + 0.25 − 0.05·4)
        let r = 0.5 + 0.02 * 0.3;
        let c = [100.0 + 0.75 - 0.2 + 0.4, -40.0 - 0.375 + 0.25 - 0.2];
        let by_hand = r * r - (x[0] - c[0]).powi(2) - (x[1] - c[1]).powi(2);
        assert!((direct - by_hand).abs() < 1e-12, "{direct} vs {by_hand}");
        let z = [-0.2 + 0.1 * 4.0, 0.25 - 0.05 * 4.0];
        assert_eq!(o.eval_with_centre_error(&x, t, &w, &z), direct);
        assert_eq!(o.shape.class(), "pedestrian");
    }

    /// The suite has pedestrians (linear motion, Gaussian position and velocity errors
    /// per axis, σ scaled by the width and horizon), and its other obstacles keep at
    /// most [`MAX_PARAMS`] parameters.
    #[test]
    fn suite_has_pedestrians() {
        let (mut scenes, mut count) = (0, 0);
        for i in 0..120 {
            let g = generate(1, i);
            let mut any = false;
            for o in &g.obstacles {
                let Shape::Pedestrian { pos, vel, t_ref, .. } = &o.shape else {
                    assert!(o.params.len() <= MAX_PARAMS, "scene {i} {}", o.id);
                    continue;
                };
                any = true;
                count += 1;
                assert!(o.params.len() <= MAX_PEDESTRIAN_PARAMS);
                assert_eq!((pos.len(), vel.len()), (g.dim, g.dim));
                assert_eq!(*t_ref, g.horizon.0);
                assert_eq!(o.motion.kind, MotionKind::Linear);
                let len = g.horizon.1 - g.horizon.0;
                for (u, (lo, hi)) in
                    pos.iter().map(|u| (u, PEDESTRIAN_POS_SD)).chain(vel.iter().map(|u| (u, PEDESTRIAN_DRIFT_SD)))
                {
                    let i = u.param.expect("uncertain");
                    let Dist::Normal { mean, std } = o.params[i].dist else { panic!("not normal") };
                    let share = if (lo, hi) == PEDESTRIAN_POS_SD { std / g.width() } else { std * len / g.width() };
                    assert!(mean == 0.0 && share >= lo * 0.999 && share <= hi * 1.001, "{share}");
                }
            }
            scenes += any as usize;
        }
        eprintln!("pedestrians: {count} in {scenes} scenes of 120");
        assert!((15..=60).contains(&scenes), "{scenes} scenes with pedestrians");
    }

    /// The Cantelli radius of a pedestrian is where the closed-form Cantelli condition
    /// changes.
    #[test]
    fn pedestrian_cantelli_radius_is_the_boundary() {
        for (r, s, dim, delta) in [(1.0, 0.1, 2, 0.05), (0.3, 0.05, 3, 0.001), (2.0, 0.01, 2, 0.2), (0.1, 0.3, 3, 0.01)]
        {
            let n = dim as f64;
            let safe = |rho: f64| {
                let ep = r * r - rho * rho - n * s * s;
                let var = 4.0 * rho * rho * s * s + 2.0 * n * s.powi(4);
                ep < 0.0 && ep * ep * delta > (1.0 - delta) * var
            };
            let rho = pedestrian_cantelli_radius(r, s, dim, delta);
            assert!(rho > r && safe(rho * 1.001) && !safe(rho * 0.999), "{r} {s} {dim} {delta}: {rho}");
        }
    }

    /// A peanut contains both lobe centres and its waist, not the far side.
    #[test]
    fn peanut_is_two_bridged_lobes() {
        let r = 1.0;
        let o = ObstacleSpec {
            id: "p".into(),
            shape: Shape::Peanut {
                shift: Unc::fixed(0.0),
                lobe: vec![2.4, 0.0],
                r1sq: Unc::fixed(1.0),
                r2sq: 1.0,
                k: Unc::fixed(0.3),
            },
            motion: Motion { kind: MotionKind::Static, c0: vec![0.0, 0.0], v: vec![0.0; 2], a: vec![0.0; 2] },
            params: vec![],
            bound: 4.0,
            feature: r,
        };
        let at = |x: f64, y: f64| o.eval(&[x, y], 0.0, &[]);
        assert!(at(0.0, 0.0) > 0.0 && at(2.4, 0.0) > 0.0 && at(1.2, 0.0) > 0.0);
        assert!(at(1.2, 1.0) < 0.0 && at(-1.2, 0.0) < 0.0 && at(5.0, 3.0) < 0.0);
    }
}
