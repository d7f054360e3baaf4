//! An independent oracle for the product's risk bounds at a point (x, t) on
//! Prob(P(x, ω, t) ≥ 0), computed from the node values of P under a tensor-product Gauss
//! rule and never from an expanded polynomial: it shares no code or derivation with
//! riskplan's moment, contour or certification modules.
//!
//! **Moments.** For an obstacle, each parameter ω_j that its text mentions gets a Gauss
//! rule exact for polynomials of degree 8·d_j in ω_j ([`crate::quadrature::rule_exact_to`];
//! d_j = [`Expr::degree_in`], so P⁸ has degree 8·d_j: 4·d_j + 1 nodes). Their tensor
//! product integrates every P^j, j ≤ 8, exactly (parameters are independent, so E
//! factorises over the monomials). When some parameter cannot have that many nodes
//! ([`MAX_NODES`], a short moments list) or the tensor product would exceed
//! [`MAX_TENSOR_NODES`], the obstacle's [`ObstacleBounds::max_order`] drops to the
//! largest even order 2k ∈ {6, 4, 2} for which the rule is exact for P^{2k}; below 2 the
//! obstacle is refused. At (x, t) the node values Pᵢ give μ = Σ wᵢPᵢ and the central
//! moments c_j = Σ wᵢ(Pᵢ − μ)^j ([`PointMoments`]).
//!
//! **Bounds** ([`PointMoments`]):
//! * Cantelli: σ²/(σ² + μ²) when μ < 0, else 1 (σ² = c₂);
//! * shifted moment bound of even order 2k with shift b < 1 and μ < 0: with
//!   a = (1 − b)(−μ) > 0, Prob(P ≥ 0) ≤ Prob(|P + a| ≥ a) ≤ E[(P + a)^{2k}]/a^{2k}
//!   (Markov), computed from the node values directly, not from the c_j;
//! * support: for bounded parameters, the risk is 0 where P < 0 on the whole support
//!   box; [`ObstacleBounds::max_on_support_grid`] gives evidence (a grid maximum, not a
//!   proof).
//!
//! **Sampling.** [`ObstacleBounds::mc_hits`] counts draws with P ≥ 0, and
//! [`binomial_lower_limit`]/[`binomial_upper_limit`] turn a count into one-sided
//! confidence limits (Chernoff–KL: valid at any n, conservative).

use super::expr::{pow_u, Bound, Expr, ExprError};
use super::generate::Dist;
use super::quadrature::{rule_exact_to, QuadratureError, Rule, MAX_NODES};
use super::scene_json::SceneJsonError;
use rand::Rng;
use serde_json::Value;
use std::sync::Arc;
use thiserror::Error;

/// Highest moment order the oracle integrates (P⁸).
pub const MAX_ORDER: u32 = 8;
/// Largest tensor-product rule of one obstacle (nodes = product of the per-parameter
/// node counts). 1e6 nodes cost ~10 ms per point; beyond it the order is lowered.
pub const MAX_TENSOR_NODES: usize = 1_000_000;
/// Largest spatial dimension of a scene (the format's limit).
pub const MAX_DIM: usize = 8;
/// Grid points of [`PointMoments::best_shifted`] over b ∈ [[`SHIFT_B_MIN`], [`SHIFT_B_MAX`]].
pub const SHIFT_GRID: usize = 2001;
/// Smallest shift parameter b searched (b < 0 means a > −μ).
pub const SHIFT_B_MIN: f64 = -4.0;
/// Largest shift parameter b searched (b → 1 makes a → 0 and the bound → 1).
pub const SHIFT_B_MAX: f64 = 0.9;
/// Golden-section steps refining the best grid point over its two neighbouring grid
/// intervals (the bracket shrinks by 0.618 per step: 60 steps take the 0.0049-wide
/// bracket below 1e-14).
pub const GOLDEN_STEPS: usize = 60;
/// Largest grid of [`ObstacleBounds::max_on_support_grid`]; beyond it the result is None.
pub const MAX_SUPPORT_GRID: usize = 10_000_000;
/// Bisection steps of the binomial limits (each halves an interval within [0, 1]; 200
/// steps reach adjacent floats for any p).
pub const BISECTION_STEPS: usize = 200;

/// Why a scene or an obstacle cannot be read into risk bounds.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum BoundsError {
    /// A malformed scene field.
    #[error("{path}: {message}")]
    Scene {
        /// JSON path of the field.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// An obstacle's polynomial text does not parse or names an unknown identifier.
    #[error("{path}: {source}")]
    Poly {
        /// JSON path of the `poly` field.
        path: String,
        /// The parser's error.
        source: ExprError,
    },
    /// A parameter's quadrature rule cannot be built.
    #[error("{path}: {source}")]
    Rule {
        /// Obstacle and parameter.
        path: String,
        /// The quadrature error.
        source: QuadratureError,
    },
}

fn scene_err(path: impl Into<String>, message: impl Into<String>) -> BoundsError {
    BoundsError::Scene { path: path.into(), message: message.into() }
}

impl From<SceneJsonError> for BoundsError {
    fn from(e: SceneJsonError) -> Self {
        BoundsError::Scene { path: e.path, message: e.message }
    }
}

/// One parameter of an obstacle, with its rule.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamRule {
    /// Name in the scene.
    pub name: String,
    /// Distribution.
    pub dist: Dist,
    /// Degree of the obstacle's text in it ([`Expr::degree_in`]).
    pub degree: u32,
    /// Its Gauss rule, exact to degree `max_order · degree`.
    pub rule: Rule,
}

/// The risk-bound oracle of one obstacle `{x : P(x, ω, t) ≥ 0}`.
#[derive(Clone, Debug)]
pub struct ObstacleBounds {
    /// The obstacle's id.
    pub id: String,
    /// The parsed text.
    pub expr: Expr,
    /// Spatial dimension n (the variables are x1 … xn, t, then the parameters).
    pub dim: usize,
    /// The parameters the text mentions, in the scene's order.
    pub params: Vec<ParamRule>,
    /// Highest even order 2k ≤ [`MAX_ORDER`] for which the rule integrates P^{2k} exactly.
    pub max_order: u32,
    bound: Bound,
    /// Tensor nodes, flattened: node i is `nodes[i·k .. (i+1)·k]` (k parameters).
    nodes: Vec<f64>,
    weights: Arc<[f64]>,
}

/// The risk-bound oracle of a whole scene: one [`ObstacleBounds`] per obstacle.
#[derive(Clone, Debug)]
pub struct SceneBounds {
    /// Spatial dimension.
    pub dim: usize,
    /// The obstacles, in the scene's order.
    pub obstacles: Vec<ObstacleBounds>,
}

/// Whether `name` is reserved for time or space (`t`, `x` followed by digits).
fn reserved(name: &str) -> bool {
    name == "t" || (name.len() > 1 && name.starts_with('x') && name[1..].bytes().all(|b| b.is_ascii_digit()))
}

impl SceneBounds {
    /// Reads a whole scene object (format v1): `dim`, `params` (optional) and
    /// `obstacles`; the other fields are not read. Every declared parameter's
    /// distribution is checked, used or not.
    pub fn from_scene_json(scene: &Value) -> Result<SceneBounds, BoundsError> {
        let obj = scene.as_object().ok_or_else(|| scene_err("", "a scene is a JSON object"))?;
        let dim =
            obj.get("dim").and_then(Value::as_u64).ok_or_else(|| scene_err("dim", "missing or not an integer"))?;
        let dim = usize::try_from(dim).ok().filter(|d| (1..=MAX_DIM).contains(d));
        let dim = dim.ok_or_else(|| scene_err("dim", format!("must be 1 to {MAX_DIM}")))?;
        let mut params: Vec<(String, Dist)> = Vec::new();
        match obj.get("params") {
            None | Some(Value::Null) => {}
            Some(Value::Object(m)) => {
                for (name, v) in m {
                    let path = format!("params.{name}");
                    let valid_ident = name.chars().next().is_some_and(|c| c == '_' || c.is_alphabetic())
                        && name.chars().all(|c| c == '_' || c.is_alphanumeric());
                    if !valid_ident || reserved(name) {
                        return Err(scene_err(path, "not an identifier, or reserved (t, x1, x2, …)"));
                    }
                    let d = Dist::from_scene_json(v).map_err(|e| BoundsError::Scene {
                        path: if e.path.is_empty() { path.clone() } else { format!("{path}.{}", e.path) },
                        message: e.message,
                    })?;
                    params.push((name.clone(), d));
                }
            }
            Some(_) => return Err(scene_err("params", "expected an object")),
        }
        let obstacles = obj
            .get("obstacles")
            .and_then(Value::as_array)
            .ok_or_else(|| scene_err("obstacles", "missing or not an array"))?;
        let mut out = Vec::with_capacity(obstacles.len());
        for (i, o) in obstacles.iter().enumerate() {
            let path = format!("obstacles[{i}]");
            let o = o.as_object().ok_or_else(|| scene_err(&path, "expected an object"))?;
            if let Some(k) = o.keys().find(|k| *k != "id" && *k != "poly") {
                return Err(scene_err(format!("{path}.{k}"), "unknown field"));
            }
            let id = o.get("id").and_then(Value::as_str).ok_or_else(|| scene_err(format!("{path}.id"), "missing"))?;
            let poly =
                o.get("poly").and_then(Value::as_str).ok_or_else(|| scene_err(format!("{path}.poly"), "missing"))?;
            out.push(ObstacleBounds::new(id, poly, dim, &params).map_err(|e| match e {
                BoundsError::Poly { source, .. } => BoundsError::Poly { path: format!("{path}.poly"), source },
                BoundsError::Rule { path: p, source } => BoundsError::Rule { path: format!("{path}.{p}"), source },
                BoundsError::Scene { path: p, message } => BoundsError::Scene { path: format!("{path}.{p}"), message },
            })?);
        }
        Ok(SceneBounds { dim, obstacles: out })
    }

    /// The obstacle with id `id`.
    pub fn obstacle(&self, id: &str) -> Option<&ObstacleBounds> {
        self.obstacles.iter().find(|o| o.id == id)
    }
}

/// Nodes of a parameter's rule exact to degree `deg`, or None when not buildable at
/// that degree (without building it).
fn nodes_needed(d: &Dist, deg: u64) -> Option<usize> {
    let gauss = usize::try_from(deg / 2 + 1).ok().filter(|&n| n <= MAX_NODES);
    match d {
        Dist::Discrete { values, .. } => Some(values.len()),
        Dist::Normal { std, .. } if *std == 0.0 => Some(1),
        Dist::Moments { raw, .. } => gauss.filter(|_| deg <= raw.len() as u64),
        Dist::RawMoments { raw } => gauss.filter(|_| deg <= raw.len() as u64),
        _ => gauss,
    }
}

impl ObstacleBounds {
    /// The oracle of one obstacle: `poly` over x1 … x`dim`, t and the parameters of
    /// `params` it mentions (any other identifier is an error). Errors on a parameter in
    /// a denominator (unknown degree) and when not even E(P²) can be integrated exactly.
    pub fn new(id: &str, poly: &str, dim: usize, params: &[(String, Dist)]) -> Result<ObstacleBounds, BoundsError> {
        let expr = Expr::parse(poly).map_err(|source| BoundsError::Poly { path: "poly".into(), source })?;
        let mut names: Vec<String> = (1..=dim).map(|i| format!("x{i}")).collect();
        names.push("t".into());
        let mut used: Vec<(String, Dist, u32)> = Vec::new();
        for (name, dist) in params {
            if !expr.mentions(name) || used.iter().any(|(n, _, _)| n == name) {
                continue;
            }
            let degree = expr.degree_in(name).ok_or_else(|| {
                scene_err(format!("poly.{name}"), "the parameter occurs in a denominator: its degree is unknown")
            })?;
            names.push(name.clone());
            used.push((name.clone(), dist.clone(), degree));
        }
        let bound = expr.bind(&names).map_err(|source| BoundsError::Poly { path: "poly".into(), source })?;
        // the highest even order whose rules can be built (a moments list may fail to give
        // a rule at a high order: too few moments, or f64 cancellation; then try lower)
        let mut failure: Option<BoundsError> = None;
        let mut chosen: Option<(u32, Vec<ParamRule>)> = None;
        for order in (2..=MAX_ORDER).rev().step_by(2) {
            let counts: Option<Vec<usize>> =
                used.iter().map(|(_, d, deg)| nodes_needed(d, u64::from(order) * u64::from(*deg))).collect();
            let Some(counts) = counts else { continue };
            let total = counts.iter().try_fold(1usize, |acc, &c| acc.checked_mul(c.max(1)));
            if total.is_none_or(|t| t > MAX_TENSOR_NODES) {
                continue;
            }
            let rules: Result<Vec<ParamRule>, BoundsError> = used
                .iter()
                .map(|(name, dist, degree)| {
                    let deg = order as usize * *degree as usize;
                    rule_exact_to(dist, deg)
                        .map(|rule| ParamRule { name: name.clone(), dist: dist.clone(), degree: *degree, rule })
                        .map_err(|source| BoundsError::Rule { path: name.clone(), source })
                })
                .collect();
            match rules {
                Ok(rules) => {
                    chosen = Some((order, rules));
                    break;
                }
                Err(e) => failure = Some(e), // the lowest order's failure is reported
            }
        }
        let Some((max_order, rules)) = chosen else {
            if let Some(e) = failure {
                return Err(e);
            }
            let worst = used.iter().max_by_key(|(_, _, d)| *d).map_or(String::new(), |(n, _, d)| format!("{n}: {d}"));
            return Err(scene_err(
                "poly",
                format!("E[P²] cannot be integrated exactly (degree {worst}, at most {MAX_NODES} nodes per parameter, {MAX_TENSOR_NODES} in all)"),
            ));
        };
        // tensor product, first parameter slowest
        let k = rules.len();
        let mut nodes: Vec<f64> = Vec::new();
        let mut weights: Vec<f64> = vec![1.0];
        for (j, r) in rules.iter().enumerate() {
            let mut nn = Vec::with_capacity(weights.len() * r.rule.nodes.len() * (j + 1));
            let mut ww = Vec::with_capacity(weights.len() * r.rule.nodes.len());
            for (i, w) in weights.iter().enumerate() {
                for (x, v) in r.rule.nodes.iter().zip(&r.rule.weights) {
                    nn.extend_from_slice(&nodes[i * j..(i + 1) * j]);
                    nn.push(*x);
                    ww.push(w * v);
                }
            }
            nodes = nn;
            weights = ww;
        }
        debug_assert_eq!(nodes.len(), weights.len() * k);
        Ok(ObstacleBounds {
            id: id.to_string(),
            expr,
            dim,
            params: rules,
            max_order,
            bound,
            nodes,
            weights: weights.into(),
        })
    }

    /// Number of tensor-product nodes.
    pub fn n_nodes(&self) -> usize {
        self.weights.len()
    }

    /// The variable vector [x1 … xn, t, 0 …] (missing coordinates NaN).
    fn vars(&self, x: &[f64], t: f64) -> Vec<f64> {
        let mut v: Vec<f64> = (0..self.dim).map(|i| x.get(i).copied().unwrap_or(f64::NAN)).collect();
        v.push(t);
        v.resize(self.dim + 1 + self.params.len(), 0.0);
        v
    }

    /// P(x, ω, t) for parameter values `w` (in the order of [`ObstacleBounds::params`];
    /// NaN when too few are given or x is shorter than the dimension).
    pub fn eval(&self, x: &[f64], t: f64, w: &[f64]) -> f64 {
        if w.len() < self.params.len() {
            return f64::NAN;
        }
        let mut v = self.vars(x, t);
        v[self.dim + 1..].copy_from_slice(&w[..self.params.len()]);
        self.bound.eval(&v)
    }

    /// μ, the central moments and the node values of P at (x, t).
    pub fn moments_at(&self, x: &[f64], t: f64) -> PointMoments {
        let k = self.params.len();
        let base = self.dim + 1;
        let mut v = self.vars(x, t);
        let mut stack = Vec::new();
        let values: Vec<f64> = (0..self.n_nodes())
            .map(|i| {
                v[base..].copy_from_slice(&self.nodes[i * k..(i + 1) * k]);
                self.bound.eval_with(&v, &mut stack)
            })
            .collect();
        let mu = neumaier(values.iter().zip(self.weights.iter()).map(|(p, w)| w * p));
        let mut c = [f64::NAN; 9];
        for (j, cj) in c.iter_mut().enumerate() {
            if j as u32 <= self.max_order {
                *cj = neumaier(values.iter().zip(self.weights.iter()).map(|(p, w)| w * pow_u(p - mu, j as u32)));
            }
        }
        PointMoments { mu, c, max_order: self.max_order, values, weights: Arc::clone(&self.weights) }
    }

    /// The support box of the parameters (in [`ObstacleBounds::params`] order) when every
    /// one is bounded: uniform and beta [low, high], discrete [min, max] of the atoms with
    /// positive weight, normal with std 0 [mean, mean]; None otherwise (moments lists
    /// included: their support is not known). An obstacle without parameters has the
    /// empty box.
    pub fn support_box(&self) -> Option<Vec<(f64, f64)>> {
        self.params.iter().map(|p| support_points(&p.dist, 2).map(|v| (v[0], v[v.len() - 1]))).collect()
    }

    /// The largest P(x, ω, t) over an evenly spaced grid of the support box with
    /// `per_axis` points per continuous parameter (at least 2: the corners are always
    /// included) and the atoms of discrete ones. Evidence, not proof: P < 0 at every grid
    /// point does not exclude a positive value between them. None when a parameter is
    /// unbounded or the grid would exceed [`MAX_SUPPORT_GRID`] points; NaN when P is NaN
    /// at a grid point.
    pub fn max_on_support_grid(&self, x: &[f64], t: f64, per_axis: usize) -> Option<f64> {
        if per_axis > MAX_SUPPORT_GRID {
            return None; // before allocating the axes
        }
        let axes: Vec<Vec<f64>> =
            self.params.iter().map(|p| support_points(&p.dist, per_axis.max(2))).collect::<Option<_>>()?;
        let total = axes.iter().try_fold(1usize, |acc, a| acc.checked_mul(a.len()))?;
        if total > MAX_SUPPORT_GRID {
            return None;
        }
        let base = self.dim + 1;
        let mut v = self.vars(x, t);
        let mut stack = Vec::new();
        let mut idx = vec![0usize; axes.len()];
        let mut best = f64::NEG_INFINITY;
        for _ in 0..total {
            for (j, a) in axes.iter().enumerate() {
                v[base + j] = a[idx[j]];
            }
            let p = self.bound.eval_with(&v, &mut stack);
            if p.is_nan() {
                return Some(f64::NAN);
            }
            best = best.max(p);
            // odometer increment, last axis fastest
            for j in (0..axes.len()).rev() {
                idx[j] += 1;
                if idx[j] < axes[j].len() {
                    break;
                }
                idx[j] = 0;
            }
        }
        Some(best)
    }

    /// Number of `n` independent draws of the parameters (each from its distribution,
    /// [`Dist::sample`]) with P(x, ω, t) ≥ 0. None when a parameter is a moments list
    /// (no distribution to sample).
    pub fn mc_hits<R: Rng>(&self, x: &[f64], t: f64, n: usize, rng: &mut R) -> Option<usize> {
        if self.params.iter().any(|p| matches!(p.dist, Dist::Moments { .. } | Dist::RawMoments { .. })) {
            return None;
        }
        let base = self.dim + 1;
        let mut v = self.vars(x, t);
        let mut stack = Vec::new();
        let mut hits = 0;
        for _ in 0..n {
            for (j, p) in self.params.iter().enumerate() {
                v[base + j] = p.dist.sample(rng);
            }
            if self.bound.eval_with(&v, &mut stack) >= 0.0 {
                hits += 1;
            }
        }
        Some(hits)
    }
}

/// Grid points of a bounded parameter's support: `m` evenly spaced points of [low, high]
/// (ends included), the atoms of positive weight (sorted), or the single point of a
/// normal with std 0. None for unbounded families and moments lists.
fn support_points(d: &Dist, m: usize) -> Option<Vec<f64>> {
    let even = |lo: f64, hi: f64| -> Vec<f64> {
        let m = m.max(2);
        (0..m).map(|i| if i + 1 == m { hi } else { lo + (hi - lo) * (i as f64 / (m - 1) as f64) }).collect()
    };
    match d {
        Dist::Uniform { low, high } | Dist::Beta { low, high, .. } => Some(even(*low, *high)),
        Dist::Normal { mean, std } if *std == 0.0 => Some(vec![*mean]),
        Dist::Discrete { values, weights } => {
            let mut atoms: Vec<f64> = values.iter().zip(weights).filter(|(_, w)| **w > 0.0).map(|(v, _)| *v).collect();
            atoms.sort_by(f64::total_cmp);
            if atoms.is_empty() {
                None
            } else {
                Some(atoms)
            }
        }
        _ => None,
    }
}

/// Neumaier's compensated sum (the error of a plain sum of n terms grows like n·ε·Σ|xᵢ|;
/// this one's stays ~2ε·Σ|xᵢ| whatever n).
fn neumaier(xs: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut c) = (0.0f64, 0.0f64);
    for x in xs {
        let t = s + x;
        c += if s.abs() >= x.abs() { (s - t) + x } else { (x - t) + s };
        s = t;
    }
    s + c
}

/// The moments of P at one point, and the node values they come from.
#[derive(Clone, Debug, PartialEq)]
pub struct PointMoments {
    /// μ = E(P) = Σ wᵢPᵢ.
    pub mu: f64,
    /// Central moments c_j = Σ wᵢ(Pᵢ − μ)^j, j = 0 … 8 (c₀ = 1, c₁ ≈ 0); NaN for
    /// j > [`PointMoments::max_order`] (not integrated exactly).
    pub c: [f64; 9],
    /// Highest even order the rule integrates exactly.
    pub max_order: u32,
    values: Vec<f64>,
    weights: Arc<[f64]>,
}

impl PointMoments {
    /// Highest even order 2k whose moments (and shifted bound) are exact.
    pub fn max_order(&self) -> u32 {
        self.max_order
    }

    /// The node values Pᵢ.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The node weights wᵢ (summing to 1).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Var P = c₂.
    pub fn variance(&self) -> f64 {
        self.c[2]
    }

    /// Cantelli's bound: Prob(P ≥ 0) ≤ σ²/(σ² + μ²) when μ < 0, else 1 (also for a NaN μ).
    pub fn cantelli(&self) -> f64 {
        let s2 = self.c[2];
        if self.mu < 0.0 {
            s2 / (s2 + self.mu * self.mu)
        } else {
            1.0
        }
    }

    /// The shifted moment bound of even order `order` (2 ≤ order ≤
    /// [`PointMoments::max_order`]; NaN otherwise) with shift b: with a = (1 − b)(−μ),
    /// Σ wᵢ((Pᵢ + a)/a)^order — the division by a before the power avoids overflow and is
    /// the same as Σ wᵢ(Pᵢ + a)^order / a^order — clamped to ≤ 1 (NaN stays NaN: a node
    /// value was NaN); 1 when μ ≥ 0, b ≥ 1 or a is not > 0 (NaN μ or b included). b = 0 is
    /// Markov's bound c_order/μ^order.
    pub fn shifted(&self, order: u32, b: f64) -> f64 {
        if order < 2 || order % 2 == 1 || order > self.max_order {
            return f64::NAN;
        }
        let a = (1.0 - b) * (-self.mu);
        if !(self.mu < 0.0 && b < 1.0 && a > 0.0) {
            return 1.0;
        }
        let s = neumaier(self.values.iter().zip(self.weights.iter()).map(|(p, w)| w * pow_u((p + a) / a, order)));
        if s.is_nan() {
            s
        } else {
            s.min(1.0)
        }
    }

    /// The smallest [`PointMoments::shifted`] over b ∈ [[`SHIFT_B_MIN`], [`SHIFT_B_MAX`]]:
    /// a grid of [`SHIFT_GRID`] points, then golden-section search over the two grid
    /// intervals around the best point ([`GOLDEN_STEPS`] steps). In s = 1/a the bound is
    /// E[(1 + sP)^{2k}], convex in s, and b ↦ s is monotone for b < 1: the bound is
    /// unimodal in b, so the refinement finds the minimum within the bracket. Returns
    /// (b, value); (0, 1) when μ ≥ 0 (every b gives 1); NaN value for an order that
    /// [`PointMoments::shifted`] refuses.
    pub fn best_shifted(&self, order: u32) -> (f64, f64) {
        if order < 2 || order % 2 == 1 || order > self.max_order {
            return (f64::NAN, f64::NAN);
        }
        if self.mu.is_nan() || self.mu >= 0.0 {
            return (0.0, 1.0);
        }
        let step = (SHIFT_B_MAX - SHIFT_B_MIN) / (SHIFT_GRID - 1) as f64;
        let grid = |i: usize| if i + 1 == SHIFT_GRID { SHIFT_B_MAX } else { SHIFT_B_MIN + step * i as f64 };
        let f = |b: f64| self.shifted(order, b);
        let mut best = (grid(0), f(grid(0)));
        let mut best_i = 0;
        for i in 1..SHIFT_GRID {
            let b = grid(i);
            let v = f(b);
            if v < best.1 {
                best = (b, v);
                best_i = i;
            }
        }
        let (mut lo, mut hi) = (grid(best_i.saturating_sub(1)), grid((best_i + 1).min(SHIFT_GRID - 1)));
        let g = (5f64.sqrt() - 1.0) / 2.0;
        let mut x1 = hi - g * (hi - lo);
        let mut x2 = lo + g * (hi - lo);
        let (mut f1, mut f2) = (f(x1), f(x2));
        for _ in 0..GOLDEN_STEPS {
            if f1 <= f2 {
                hi = x2;
                (x2, f2) = (x1, f1);
                x1 = hi - g * (hi - lo);
                f1 = f(x1);
            } else {
                lo = x1;
                (x1, f1) = (x2, f2);
                x2 = lo + g * (hi - lo);
                f2 = f(x2);
            }
        }
        for (b, v) in [(x1, f1), (x2, f2)] {
            if v < best.1 {
                best = (b, v);
            }
        }
        best
    }
}

/// Kullback–Leibler divergence KL(q ‖ p) of Bernoulli distributions, with 0·ln 0 = 0.
fn kl(q: f64, p: f64) -> f64 {
    let a = if q > 0.0 { q * (q / p).ln() } else { 0.0 };
    let b = if q < 1.0 { (1.0 - q) * ((-q).ln_1p() - (-p).ln_1p()) } else { 0.0 };
    a + b
}

/// A one-sided lower confidence limit at level 1 − `alpha` for a binomial proportion p
/// after `k` successes in `n` trials: the smallest p ≤ k/n with n·KL(k/n ‖ p) ≤ ln(1/α)
/// (Chernoff: Prob_p(X ≥ k) ≤ exp(−n·KL(k/n ‖ p)) for p < k/n, so the limit is below the
/// true p with probability ≥ 1 − α, at any n). Found by bisection and returned from the
/// conservative side. 0 when k = 0 or n = 0 or α ≤ 0; k/n when α ≥ 1; NaN when k > n or α
/// is NaN.
pub fn binomial_lower_limit(k: u64, n: u64, alpha: f64) -> f64 {
    if k > n || alpha.is_nan() {
        return f64::NAN;
    }
    if k == 0 || n == 0 || alpha <= 0.0 {
        return 0.0;
    }
    let q = k as f64 / n as f64;
    if alpha >= 1.0 {
        return q;
    }
    let c = (1.0 / alpha).ln() / n as f64;
    // KL(q ‖ p) decreases in p on [0, q]: lo stays outside (KL > c), hi inside
    let (mut lo, mut hi) = (0.0, q);
    for _ in 0..BISECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if kl(q, mid) > c {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The matching one-sided upper confidence limit: the largest p ≥ k/n with
/// n·KL(k/n ‖ p) ≤ ln(1/α), from the conservative side. For k = 0 it is exactly
/// 1 − α^{1/n} ≈ ln(1/α)/n (the Clopper–Pearson limit). 1 when k = n or n = 0 or α ≤ 0;
/// k/n when α ≥ 1; NaN when k > n or α is NaN.
pub fn binomial_upper_limit(k: u64, n: u64, alpha: f64) -> f64 {
    if k > n || alpha.is_nan() {
        return f64::NAN;
    }
    if k == n || n == 0 || alpha <= 0.0 {
        return 1.0;
    }
    let q = k as f64 / n as f64;
    if alpha >= 1.0 {
        return q;
    }
    let c = (1.0 / alpha).ln() / n as f64;
    let (mut lo, mut hi) = (q, 1.0);
    for _ in 0..BISECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if kl(q, mid) > c {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_json::number;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use serde_json::json;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * a.abs().max(b.abs())
    }

    fn scene(params: Value, polys: &[&str]) -> SceneBounds {
        let obstacles: Vec<Value> =
            polys.iter().enumerate().map(|(i, p)| json!({"id": format!("o{i}"), "poly": p})).collect();
        SceneBounds::from_scene_json(&json!({"dim": 2, "params": params, "obstacles": obstacles})).unwrap()
    }

    /// The paper's disk w² − x1² − x2², w ~ U[0.3, 0.4], at (0.45, 0): P = w² − 0.2025 < 0
    /// on the whole support, and the Cantelli bound is exactly 2944/48069 (by hand:
    /// E[w²] = 37/300, E[w⁴] = 781/50000, μ = −19/240, σ² = 23/56250).
    #[test]
    fn uniform_disk() {
        let s = scene(json!({"w": {"dist": "uniform", "low": 0.3, "high": 0.4}}), &["w^2 - x1^2 - x2^2"]);
        let o = &s.obstacles[0];
        assert_eq!((o.max_order, o.n_nodes(), o.params[0].degree), (8, 9, 2));
        assert_eq!(o.support_box(), Some(vec![(0.3, 0.4)]));
        let grid_max = o.max_on_support_grid(&[0.45, 0.0], 0.0, 11).unwrap();
        assert!(close(grid_max, 0.16 - 0.2025, 1e-14), "{grid_max}");
        let m = o.moments_at(&[0.45, 0.0], 0.0);
        assert!(close(m.mu, -19.0 / 240.0, 1e-14));
        assert!(close(m.variance(), 23.0 / 56250.0, 1e-12));
        assert!(close(m.cantelli(), 2944.0 / 48069.0, 1e-12), "{}", m.cantelli());
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        assert_eq!(o.mc_hits(&[0.45, 0.0], 0.0, 10_000, &mut rng), Some(0));
        // inside: μ > 0, every bound is 1; at the centre the support maximum is positive
        let m = o.moments_at(&[0.0, 0.0], 0.0);
        assert_eq!((m.cantelli(), m.shifted(4, 0.0), m.best_shifted(8)), (1.0, 1.0, (0.0, 1.0)));
        assert!(o.max_on_support_grid(&[0.0, 0.0], 0.0, 2).unwrap() > 0.0);
        // on the fringe 0.3 < |x| < 0.4: a fraction of the draws hit, and the MC lower
        // limit lies below every bound
        let x = [0.37, 0.0];
        let m = o.moments_at(&x, 0.0);
        let hits = o.mc_hits(&x, 0.0, 20_000, &mut rng).unwrap();
        let exact = (0.4 - 0.37) / 0.1;
        assert!(binomial_lower_limit(hits as u64, 20_000, 1e-6) <= exact);
        assert!(binomial_upper_limit(hits as u64, 20_000, 1e-6) >= exact);
        for order in [4, 6, 8] {
            assert!(m.best_shifted(order).1 >= exact - 1e-12);
        }
        assert!(m.cantelli() >= exact);
    }

    /// κ_r of U² for U ~ N(a, σ²): σ^{2r}·2^{r−1}(r−1)!·(1 + r·a²/σ²) (noncentral χ² with
    /// one degree of freedom, scaled by σ²).
    fn kappa_sq(r: u32, a: f64, s: f64) -> f64 {
        let fact: f64 = (1..r).map(f64::from).product();
        s.powi(2 * r as i32) * 2f64.powi(r as i32 - 1) * fact * (1.0 + f64::from(r) * a * a / (s * s))
    }

    /// The Gaussian-centre disk 0.09 − (x1 − u)² − (x2 − v)², u, v ~ N(0, 0.05²): with
    /// U = x1 − u ~ N(x1, σ²), V ~ N(x2, σ²), P = 0.09 − U² − V², so
    /// μ = 0.09 − x1² − x2² − 2σ², and the cumulants of P are sums of those of −U², −V²:
    /// c₂ = κ₂ = 4σ²(x1² + x2²) + 4σ⁴, c₃ = −κ₃(U²) − κ₃(V²), c₄ = κ₄ + 3κ₂².
    #[test]
    fn gaussian_centre_disk_closed_forms_and_monte_carlo() {
        let sd = 0.05;
        let s = scene(
            json!({"u": {"dist": "normal", "mean": 0, "std": "1/20"}, "v": {"dist": "normal", "mean": 0, "std": 0.05}}),
            &["0.09 - (x1 - u)^2 - (x2 - v)^2"],
        );
        let o = &s.obstacles[0];
        assert_eq!((o.max_order, o.n_nodes()), (8, 81));
        assert_eq!(o.support_box(), None);
        assert_eq!(o.max_on_support_grid(&[0.0, 0.0], 0.0, 5), None);
        for (a, b) in [(0.5, 0.0), (0.2, 0.3), (0.0, 0.0), (-0.31, 0.05)] {
            let m = o.moments_at(&[a, b], 0.0);
            let mu = 0.09 - a * a - b * b - 2.0 * sd * sd;
            let k2 = kappa_sq(2, a, sd) + kappa_sq(2, b, sd);
            let c2_by_hand = 4.0 * sd * sd * (a * a + b * b) + 4.0 * sd.powi(4);
            assert!(close(k2, c2_by_hand, 1e-14));
            let k3 = -(kappa_sq(3, a, sd) + kappa_sq(3, b, sd));
            let k4 = kappa_sq(4, a, sd) + kappa_sq(4, b, sd);
            assert!(close(m.mu, mu, 1e-13), "μ at ({a}, {b}): {} vs {mu}", m.mu);
            assert!(close(m.c[2], c2_by_hand, 1e-12), "c₂ at ({a}, {b}): {} vs {c2_by_hand}", m.c[2]);
            assert!(close(m.c[3], k3, 1e-10), "c₃ at ({a}, {b}): {} vs {k3}", m.c[3]);
            assert!(close(m.c[4], k4 + 3.0 * k2 * k2, 1e-10), "c₄ at ({a}, {b})");
            assert!(close(m.c[0], 1.0, 1e-14) && m.c[1].abs() <= 1e-15 * m.c[2].sqrt().max(m.mu.abs()));
        }
        // against a seeded Monte Carlo estimate of the central moments (10⁶ draws; the
        // tolerances are ~10 standard errors)
        let x = [0.2, 0.3];
        let m = o.moments_at(&x, 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(42);
        let n = 1_000_000;
        let draws: Vec<f64> = (0..n)
            .map(|_| {
                let w: Vec<f64> = o.params.iter().map(|p| p.dist.sample(&mut rng)).collect();
                o.eval(&x, 0.0, &w)
            })
            .collect();
        let mean = draws.iter().sum::<f64>() / n as f64;
        let central = |j: i32| draws.iter().map(|p| (p - mean).powi(j)).sum::<f64>() / n as f64;
        let sigma = m.c[2].sqrt();
        assert!((mean - m.mu).abs() <= 0.01 * sigma, "mean {mean} vs {}", m.mu);
        assert!(close(central(2), m.c[2], 0.015), "c₂ {} vs {}", central(2), m.c[2]);
        assert!((central(3) - m.c[3]).abs() <= 0.05 * sigma.powi(3), "c₃ {} vs {}", central(3), m.c[3]);
        assert!(close(central(4), m.c[4], 0.05), "c₄ {} vs {}", central(4), m.c[4]);
    }

    /// shifted(order, 0) is Markov's bound c_order/μ^order; the optimised shift is never
    /// worse than b = 0 nor than any grid b; Cantelli equals the order-2 optimum
    /// (min over a of E[(P + a)²]/a² = σ²/(σ² + μ²), at a = σ²/(−μ) + (−μ)).
    #[test]
    fn shifted_bounds() {
        let s = scene(
            json!({"u": {"dist": "normal", "mean": 0, "std": 0.05}, "v": {"dist": "laplace", "mean": 0, "scale": 0.03},
                   "r": {"dist": "beta", "alpha": 2, "beta": 5, "low": 0.25, "high": 0.35}}),
            &["r^2 - (x1 - u)^2 - (x2 - v)^2"],
        );
        let o = &s.obstacles[0];
        assert_eq!(o.max_order, 8);
        for x in [[0.5, 0.0], [0.42, 0.1], [1.0, -1.0]] {
            let m = o.moments_at(&x, 0.0);
            assert!(m.mu < 0.0);
            for order in [2u32, 4, 6, 8] {
                let markov = m.c[order as usize] / m.mu.powi(order as i32);
                let v = m.shifted(order, 0.0);
                assert!(close(v, markov.min(1.0), 1e-11), "order {order} at {x:?}: {v} vs {markov}");
                let (b, best) = m.best_shifted(order);
                assert!((SHIFT_B_MIN..=SHIFT_B_MAX).contains(&b));
                assert!(best <= v * (1.0 + 1e-12), "order {order}: best {best} > b=0 {v}");
                for i in 0..=49 {
                    let bi = SHIFT_B_MIN + (SHIFT_B_MAX - SHIFT_B_MIN) * f64::from(i) / 49.0;
                    assert!(best <= m.shifted(order, bi) * (1.0 + 1e-12));
                }
                assert_eq!(m.shifted(order, 1.0), 1.0);
                assert_eq!(m.shifted(order, f64::NAN), 1.0);
            }
            // order 2: the optimum over b is Cantelli (reached at b = −σ²/μ², inside the
            // searched range for these points)
            let (b2, best2) = m.best_shifted(2);
            assert!(close(best2, m.cantelli(), 1e-9), "{best2} vs {}", m.cantelli());
            assert!(close(b2, -m.c[2] / (m.mu * m.mu), 1e-4) || m.cantelli() == 1.0);
            assert!(m.shifted(3, 0.0).is_nan() && m.shifted(10, 0.0).is_nan() && m.shifted(0, 0.0).is_nan());
            assert!(m.best_shifted(5).1.is_nan());
        }
    }

    /// A moments list (U[0.3, 0.4] written as raw moments) gives the same bounds as the
    /// uniform itself, up to the order its length allows.
    #[test]
    fn moments_lists() {
        let raw = |k: usize| -> Vec<Value> {
            (1..=k as i32)
                .map(|j| json!((0.4f64.powi(j + 1) - 0.3f64.powi(j + 1)) / (f64::from(j + 1) * 0.1)))
                .collect()
        };
        // moments of U[−0.05, 0.05]: E[w^j] = 0.05^j/(j + 1) for even j, 0 for odd j
        let centred = |k: usize| -> Vec<Value> {
            (1..=k as i32).map(|j| json!(if j % 2 == 0 { 0.05f64.powi(j) / f64::from(j + 1) } else { 0.0 })).collect()
        };
        let x = [0.45, 0.0];
        let uni = scene(json!({"w": {"dist": "uniform", "low": 0.3, "high": 0.4}}), &["w^2 - x1^2 - x2^2"]);
        let mu = uni.obstacles[0].moments_at(&x, 0.0);
        // exactly 2·degree moments (the format's minimum): order 2 only, still exact
        let s = scene(
            json!({"w": {"dist": "moments", "raw": ["7/20", "37/300", "0.04375", "781/50000"]}}),
            &["w^2 - x1^2 - x2^2"],
        );
        let o = &s.obstacles[0];
        assert_eq!((o.max_order, o.n_nodes()), (2, 3));
        let m = o.moments_at(&x, 0.0);
        assert!(close(m.cantelli(), mu.cantelli(), 1e-12));
        assert!(m.c[4].is_nan() && m.shifted(4, 0.0).is_nan());
        assert_eq!(o.support_box(), None);
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        assert_eq!(o.mc_hits(&x, 0.0, 10, &mut rng), None);
        // 12 or 16 moments of a variable centred on 0: orders 6 and 8, as the uniform
        for (k, order) in [(12, 6), (16, 8)] {
            let s = scene(json!({"w": {"dist": "moments", "raw": centred(k)}}), &["(0.35 + w)^2 - x1^2 - x2^2"]);
            let o = &s.obstacles[0];
            assert_eq!(o.max_order, order);
            let m = o.moments_at(&x, 0.0);
            for j in 2..=order as usize {
                assert!(close(m.c[j], mu.c[j], 1e-9), "k = {k}, c_{j}: {} vs {}", m.c[j], mu.c[j]);
            }
            assert!(close(m.best_shifted(order).1, mu.best_shifted(order).1, 1e-8));
        }
        // the raw moments of U[0.3, 0.4] itself (mean/sd ≈ 12): standardising in f64
        // cancels ~j·log10(12) digits of the j-th moment, so the high orders are refused
        // and the order drops to what the moments still determine — never a wrong rule
        for k in [8, 12, 16] {
            let s = scene(json!({"w": {"dist": "moments", "raw": raw(k)}}), &["w^2 - x1^2 - x2^2"]);
            let o = &s.obstacles[0];
            let m = o.moments_at(&x, 0.0);
            eprintln!("raw moments of U[0.3, 0.4], {k} listed: order {}", o.max_order);
            for j in 2..=o.max_order as usize {
                assert!(close(m.c[j], mu.c[j], 1e-6), "k = {k}, c_{j}: {} vs {}", m.c[j], mu.c[j]);
            }
        }
        // too few moments even for E[P²]
        let e = SceneBounds::from_scene_json(
            &json!({"dim": 2, "params": {"w": {"dist": "moments", "raw": [0.35, 0.1233]}},
            "obstacles": [{"id": "d", "poly": "w^2 - x1^2"}]}),
        );
        assert!(e.is_err());
    }

    #[test]
    fn orders_drop_with_degree_and_tensor_size() {
        let normal = json!({"dist": "normal", "mean": 0, "std": 0.1});
        // degree 4 in w: P⁸ needs 17 nodes > 16; P⁶ needs 13
        let s = scene(json!({"w": normal}), &["w^4 - x1^2"]);
        assert_eq!((s.obstacles[0].max_order, s.obstacles[0].n_nodes()), (6, 13));
        // degree 15: only E[P²] (16 nodes); degree 16: refused
        assert_eq!(scene(json!({"w": normal}), &["w^15 - x1"]).obstacles[0].max_order, 2);
        let e = SceneBounds::from_scene_json(
            &json!({"dim": 1, "params": {"w": normal}, "obstacles": [{"id": "a", "poly": "w^16 - x1"}]}),
        );
        assert!(matches!(e, Err(BoundsError::Scene { .. })), "{e:?}");
        // eight degree-2 parameters: 9⁸ and 7⁸ nodes are too many, 5⁸ = 390625 fit
        let params: serde_json::Map<String, Value> = (1..=8).map(|i| (format!("w{i}"), normal.clone())).collect();
        let poly: String = (1..=8).map(|i| format!(" - (x1 - w{i})^2")).collect();
        let s = scene(Value::Object(params), &[&format!("1{poly}")]);
        assert_eq!((s.obstacles[0].max_order, s.obstacles[0].n_nodes()), (4, 390_625));
        // discrete atoms are exact whatever the degree; a constant normal is one node
        let s = scene(
            json!({"k": {"dist": "discrete", "values": [0, 1, 2], "weights": [0.2, 0.3, 0.5]},
                   "c": {"dist": "normal", "mean": 1, "std": 0}}),
            &["k^9*c^3 - x1"],
        );
        let o = &s.obstacles[0];
        assert_eq!((o.max_order, o.n_nodes()), (8, 3));
        let m = o.moments_at(&[100.0, 0.0], 0.0);
        assert!(close(m.mu, 0.3 + 0.5 * 512.0 - 100.0, 1e-14));
        assert_eq!(o.support_box(), Some(vec![(0.0, 2.0), (1.0, 1.0)]));
        assert_eq!(o.max_on_support_grid(&[100.0, 0.0], 0.0, 7), Some(412.0));
    }

    #[test]
    fn scene_errors_name_the_field() {
        let check = |v: Value, want: &str| {
            let e = SceneBounds::from_scene_json(&v).unwrap_err().to_string();
            assert!(e.starts_with(want), "{e} (wanted {want})");
        };
        let u = json!({"dist": "uniform", "low": 0, "high": 1});
        check(json!({"dim": 2, "obstacles": [{"id": "a", "poly": "x3 - 1"}]}), "obstacles[0].poly: unknown identifier");
        check(json!({"dim": 2, "obstacles": [{"id": "a", "poly": "q - 1"}]}), "obstacles[0].poly: unknown identifier");
        check(json!({"dim": 2, "params": {"w": u}, "obstacles": [{"id": "a", "poly": "x1/w"}]}), "obstacles[0].poly.w");
        check(json!({"dim": 2, "obstacles": [{"id": "a", "poly": "x1 +"}]}), "obstacles[0].poly: column 5");
        check(
            json!({"dim": 2, "params": {"w": {"dist": "normal", "mean": 0, "std": -1}}, "obstacles": []}),
            "params.w.std",
        );
        check(json!({"dim": 2, "params": {"x1": u}, "obstacles": []}), "params.x1");
        check(json!({"dim": 2, "params": {"t": u}, "obstacles": []}), "params.t");
        check(json!({"dim": 9, "obstacles": []}), "dim");
        check(json!({"dim": 2}), "obstacles");
        check(json!({"dim": 2, "obstacles": [{"id": "a"}]}), "obstacles[0].poly");
        check(json!({"dim": 2, "obstacles": [{"id": "a", "poly": "1", "colour": 3}]}), "obstacles[0].colour");
        check(json!([]), ": a scene");
        // a declared but unused parameter is fine; so is a parameter-free obstacle
        let s = SceneBounds::from_scene_json(
            &json!({"dim": 2, "params": {"w": u}, "obstacles": [{"id": "a", "poly": "1 - x1^2"}]}),
        )
        .unwrap();
        let o = s.obstacle("a").unwrap();
        assert!(o.params.is_empty() && o.n_nodes() == 1);
        assert_eq!(o.support_box(), Some(vec![]));
        assert_eq!(o.max_on_support_grid(&[2.0, 0.0], 0.0, 3), Some(-3.0));
        let m = o.moments_at(&[2.0, 0.0], 0.0);
        assert_eq!((m.mu, m.c[2], m.cantelli(), m.shifted(8, 0.0)), (-3.0, 0.0, 0.0, 0.0));
        // a short x: NaN values, no panic
        assert!(o.moments_at(&[], 0.0).mu.is_nan());
        assert!(o.eval(&[1.0, 0.0], 0.0, &[]) == 0.0);
    }

    /// Every reference and extreme scene of the repository reads, and its bounds at a few
    /// points are finite numbers in [0, 1].
    #[test]
    fn repository_scenes_read() {
        let scenes = [
            include_str!("../../../scenes/example-a1-2d.json"),
            include_str!("../../../scenes/example-a2-3d.json"),
            include_str!("../../../scenes/example-b-lane-change.json"),
            include_str!("../../../scenes/example-c-delivery.json"),
            include_str!("../../../scenes/example-d1-cluttered-2d.json"),
            include_str!("../../../scenes/example-d2-cluttered-3d.json"),
            include_str!("../../../scenes/illustrative-1.json"),
            include_str!("../../../scenes/illustrative-2.json"),
            include_str!("../../../scenes/illustrative-3.json"),
            include_str!("../../../scenes/illustrative-4.json"),
            include_str!("../../../tests/scenes/extreme/far-time.json"),
            include_str!("../../../tests/scenes/extreme/keep-in-superellipse-at-1e41.json"),
            include_str!("../../../tests/scenes/extreme/subnormal-coefficient.json"),
            include_str!("../../../tests/scenes/extreme/superellipse-at-1e20-grazing.json"),
            include_str!("../../../tests/scenes/extreme/superellipse-at-1e21.json"),
            include_str!("../../../tests/scenes/extreme/tiny-horizon.json"),
        ];
        for text in scenes {
            let v: Value = serde_json::from_str(text).unwrap();
            let name = v["name"].as_str().unwrap_or("?").to_string();
            let s = SceneBounds::from_scene_json(&v).unwrap_or_else(|e| panic!("{name}: {e}"));
            let nums = |v: &Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| number(x).unwrap()).collect() };
            let (lower, upper) = (nums(&v["workspace"]["lower"]), nums(&v["workspace"]["upper"]));
            let t0 = number(&v["horizon"][0]).unwrap();
            for o in &s.obstacles {
                for f in [0.1, 0.5, 0.9] {
                    let x: Vec<f64> = lower.iter().zip(&upper).map(|(l, u)| l + f * (u - l)).collect();
                    let m = o.moments_at(&x, t0);
                    let c = m.cantelli();
                    assert!((0.0..=1.0).contains(&c), "{name}/{}: cantelli {c} at {x:?}", o.id);
                    let (_, b) = m.best_shifted(m.max_order());
                    assert!((0.0..=1.0).contains(&b), "{name}/{}: shifted {b}", o.id);
                }
            }
        }
    }

    /// The Chernoff–KL limits: k = 0 gives the exact Clopper–Pearson 1 − α^{1/n}; they are
    /// at least as wide as Clopper–Pearson (computed here from the binomial tail); and a
    /// seeded simulation covers p at least 1 − α of the time.
    #[test]
    fn binomial_limits() {
        for (n, alpha) in [(10u64, 0.05), (1000, 0.01), (1_000_000, 1e-6)] {
            let u = binomial_upper_limit(0, n, alpha);
            let cp = -(alpha.ln() / n as f64).exp_m1();
            assert!(close(u, cp, 1e-12), "k = 0, n = {n}: {u} vs {cp}");
            assert!(u >= cp * (1.0 - 1e-13)); // the conservative side, up to rounding of the two
            assert!(u <= (1.0 / alpha).ln() / n as f64 * 1.01);
            assert_eq!(binomial_lower_limit(0, n, alpha), 0.0);
            assert_eq!(binomial_upper_limit(n, n, alpha), 1.0);
            let l = binomial_lower_limit(n, n, alpha);
            assert!(close(l, alpha.powf(1.0 / n as f64), 1e-12), "k = n: {l}");
        }
        // Clopper–Pearson from the exact tail Prob_p(X ≥ k) (log-space pmf)
        let tail_ge = |k: u64, n: u64, p: f64| -> f64 {
            let ln_choose = |j: u64| -> f64 { (1..=j).map(|i| ((n - j + i) as f64 / i as f64).ln()).sum() };
            (k..=n).map(|j| (ln_choose(j) + j as f64 * p.ln() + (n - j) as f64 * (-p).ln_1p()).exp()).sum()
        };
        for (k, n, alpha) in [(5u64, 100u64, 0.05), (50, 1000, 0.05), (3, 20, 0.1), (200, 400, 0.01)] {
            let (mut lo, mut hi) = (0.0, k as f64 / n as f64);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if tail_ge(k, n, mid) < alpha {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let cp_lower = lo;
            let kl_lower = binomial_lower_limit(k, n, alpha);
            assert!(kl_lower <= cp_lower, "({k}, {n}): KL {kl_lower} > CP {cp_lower}");
            assert!(kl_lower >= 0.4 * cp_lower, "({k}, {n}): KL {kl_lower} much wider than CP {cp_lower}");
            assert!(kl_lower < k as f64 / n as f64 && binomial_upper_limit(k, n, alpha) > k as f64 / n as f64);
        }
        // coverage by simulation (seeded)
        let mut rng = ChaCha8Rng::seed_from_u64(2024);
        for (p, n, alpha) in [(0.03, 500u64, 0.05), (0.5, 50, 0.1), (0.002, 5000, 0.05)] {
            let binom = rand_distr::Binomial::new(n, p).unwrap();
            let reps = 4000;
            let (mut low_ok, mut up_ok) = (0, 0);
            for _ in 0..reps {
                let k: u64 = rand_distr::Distribution::sample(&binom, &mut rng);
                low_ok += usize::from(binomial_lower_limit(k, n, alpha) <= p);
                up_ok += usize::from(binomial_upper_limit(k, n, alpha) >= p);
            }
            let need = ((1.0 - alpha) * reps as f64) as usize;
            assert!(low_ok >= need && up_ok >= need, "p = {p}: coverage {low_ok}, {up_ok} of {reps}");
        }
        assert!(binomial_lower_limit(5, 4, 0.05).is_nan() && binomial_upper_limit(1, 2, f64::NAN).is_nan());
        assert_eq!((binomial_lower_limit(1, 2, 1.0), binomial_upper_limit(1, 2, 0.0)), (0.5, 1.0));
    }
}
