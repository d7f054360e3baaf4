//! The independent feasibility oracle: judges a [`GeneratedScene`] feasible (with a
//! path), infeasible (with a typed reason) or ambiguous, using none of riskplan's
//! moment, polynomial, contour, certification or verification code.
//!
//! **Point safety.** At a point (x, t), E\[P\] and E\[P²\] of each obstacle are computed by
//! Gauss quadrature ([`super::quadrature`], 3 nodes per parameter, tensor product over
//! an obstacle's independent parameters, exact since P has degree ≤ 2 in each
//! parameter) of P evaluated from the generator's structure ([`ObstacleSpec::eval`]);
//! a pedestrian's Gaussian position and velocity errors through its centre error, one
//! Gaussian per axis at each time ([`ObstacleMoments`]).
//! The point is safe at level Δ when, for every obstacle, it lies in the paper's
//! Cantelli contour: E\[P\] < 0 and E\[P\]² − (1−Δ)·E\[P²\] > 0 ([`cantelli_safe`]), and it
//! lies in the workspace box.
//!
//! **Static scenes** (no obstacle moves): a grid of cells over the workspace, with the
//! cell size set by the smallest obstacle feature ([`CELLS_PER_FEATURE`] cells across
//! it) within [`STATIC_CELLS_2D`] / [`STATIC_CELLS_3D`] cells on the longest side; an
//! A* search over the 8-/26-connected graph. *Feasible* needs clearance: every cell of
//! the path and all its neighbours safe at the tightened level Δ·[`TIGHT_FACTOR`],
//! every edge safe at that level at [`EDGE_SUBSTEPS`] − 1 interior points, and the
//! straight connections from start and goal to cells up to [`CONNECTION_REACH`] cells
//! away safe at level Δ (the endpoints themselves need only Δ) at ≥
//! [`CONNECTION_SAMPLES`] points. *Infeasible* when start or goal is unsafe at Δ
//! ([`InfeasibleReason::EndpointUnsafe`]), or when no path exists even in the graph of
//! cells safe at the relaxed level min(Δ·[`RELAX_FACTOR`], [`RELAX_CAP`]) with no
//! clearance and no edge checks ([`InfeasibleReason::Disconnected`]). Otherwise
//! *ambiguous*. With a speed limit, a static path must also be no longer than
//! max_speed·(t_f − t₀) (it is timed at constant speed).
//!
//! **Moving obstacles**: a time-expanded grid: [`MOVING_CELLS_2D`] / [`MOVING_CELLS_3D`]
//! cells on the longest side and [`LAYERS`] time layers over the horizon (enough that
//! no obstacle moves more than a cell per layer and, without a speed limit, that the
//! strict reach covers [`LAYER_SLACK`] times the start–goal distance, within the range). A move goes
//! from a cell at layer k to a cell at layer k+1 (staying included) whose centre is
//! within max_speed·dt (scenes with a speed limit) — without a limit within half the
//! workspace diagonal per layer, the "generous reach" — and, for the strict search, at
//! most [`REACH_CAP_2D`] / [`REACH_CAP_3D`] cells per axis (a restriction of the graph,
//! which keeps the search cheap and cannot make a *feasible* judgement wrong). Every
//! move is checked at the tightened level at interior points on a lattice of
//! max([`EDGE_SUBSTEPS`], 2·reach) sub-steps per layer, in space and time. The relaxed
//! reachability check uses the full reach plus one cell. Out-of-reach scenes
//! (|goal − start| > max_speed·(t_f − t₀)) are [`InfeasibleReason::OutOfReach`].
//!
//! These are approximations with margins (Δ/2 against 1.5·Δ), not proofs: the oracle
//! is evidence against which the planners and certifiers are compared.

use super::generate::{Dist, GeneratedScene, ObstacleSpec, Shape, Unc};
use super::quadrature::{rule, QuadratureError, Rule};
use serde::Serialize;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap, VecDeque};
use thiserror::Error;

// the clearance search's tightened level Δ·TIGHT_FACTOR: documented where the generator
// defines it (it sizes pedestrians' bounds by it)
pub use super::generate::TIGHT_FACTOR;
/// The relaxed level of the disconnection check is min(Δ·RELAX_FACTOR, [`RELAX_CAP`]).
pub const RELAX_FACTOR: f64 = 1.5;
/// The relaxed level stays below 1 (at Δ = 1 every point with E\[P\] < 0 is "safe").
pub const RELAX_CAP: f64 = 0.99;
/// Cells on the longest workspace side, static 2-D scenes (min, max).
pub const STATIC_CELLS_2D: (usize, usize) = (64, 128);
/// Cells on the longest workspace side, static 3-D scenes (min, max).
pub const STATIC_CELLS_3D: (usize, usize) = (24, 40);
/// Cells on the longest workspace side, moving 2-D scenes (min, max).
pub const MOVING_CELLS_2D: (usize, usize) = (32, 64);
/// Cells on the longest workspace side, moving 3-D scenes (min, max).
pub const MOVING_CELLS_3D: (usize, usize) = (12, 20);
/// Time layers over the horizon, moving scenes (min, max); within the range, enough
/// that no obstacle's reference point moves more than a cell per layer.
pub const LAYERS: (usize, usize) = (16, 40);
/// Cells across the smallest obstacle feature (smallest semi-axis or lobe radius), as
/// far as the cell ranges allow.
pub const CELLS_PER_FEATURE: f64 = 3.0;
/// Sub-steps of an edge: interior check points at 1/EDGE_SUBSTEPS, 2/EDGE_SUBSTEPS, …
pub const EDGE_SUBSTEPS: usize = 4;
/// Largest strict-search move per layer in cells per axis, 2-D.
pub const REACH_CAP_2D: i64 = 3;
/// Largest strict-search move per layer in cells per axis, 3-D.
pub const REACH_CAP_3D: i64 = 2;
/// Static scenes: start and goal connect to allowed cells up to this many cells (per
/// axis) from their own cell.
pub const CONNECTION_REACH: i64 = 2;
/// Without a speed limit, enough layers that the strict search's reach (the cap per
/// layer) covers this multiple of the start–goal distance in cells (detours).
pub const LAYER_SLACK: f64 = 1.6;
/// Smallest number of check points on a straight connection from start or goal.
pub const CONNECTION_SAMPLES: usize = 16;
/// Default budget of fresh point classifications of one strict search; beyond it the
/// strict search gives up (the judgement is then decided by the relaxed check or is
/// ambiguous). Bounds the oracle's time on hard scenes.
pub const DEFAULT_MAX_EVALUATIONS: usize = 400_000;

/// Oracle options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleOptions {
    /// Budget of fresh point classifications of the strict search.
    pub max_evaluations: usize,
}

impl Default for OracleOptions {
    fn default() -> Self {
        OracleOptions { max_evaluations: DEFAULT_MAX_EVALUATIONS }
    }
}

/// A waypoint of an oracle path.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Waypoint {
    /// Position.
    pub x: Vec<f64>,
    /// Time.
    pub t: f64,
}

/// Why the oracle calls a scene infeasible.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum InfeasibleReason {
    /// Start (at t₀) or goal (at t_f) is not safe at level Δ.
    EndpointUnsafe {
        /// `start` or `goal`.
        endpoint: String,
        /// The first obstacle whose contour excludes it (or `workspace`).
        obstacle: String,
        /// The time.
        time: f64,
    },
    /// No path even through cells safe at the relaxed level.
    Disconnected,
    /// |goal − start| > max_speed·(t_f − t₀).
    OutOfReach {
        /// |goal − start|.
        distance: f64,
        /// max_speed·(t_f − t₀).
        reach: f64,
    },
}

/// The oracle's verdict.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "judgement", rename_all = "snake_case")]
pub enum Judgement {
    /// A path with clearance exists.
    Feasible {
        /// Waypoints from start at t₀ to goal at t_f.
        path: Vec<Waypoint>,
    },
    /// No path exists.
    Infeasible {
        /// Why.
        reason: InfeasibleReason,
    },
    /// Neither could be shown at the oracle's resolution.
    Ambiguous {
        /// What was inconclusive.
        note: String,
    },
}

impl Judgement {
    /// `feasible`, `infeasible` or `ambiguous`.
    pub fn label(&self) -> &'static str {
        match self {
            Judgement::Feasible { .. } => "feasible",
            Judgement::Infeasible { .. } => "infeasible",
            Judgement::Ambiguous { .. } => "ambiguous",
        }
    }
}

/// The grid the oracle used.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridInfo {
    /// Cells per axis.
    pub cells: Vec<usize>,
    /// Time layers (0 for static scenes).
    pub layers: usize,
    /// Strict-search move bound in cells per axis (moving scenes).
    pub reach_cells: i64,
    /// Sub-steps per edge.
    pub substeps: usize,
    /// Levels: Δ, tightened, relaxed.
    pub levels: [f64; 3],
}

/// The oracle's report on one scene.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OracleReport {
    /// The verdict.
    pub judgement: Judgement,
    /// The grid.
    pub grid: GridInfo,
    /// Point classifications made (each: E\[P\], E\[P²\] of every obstacle).
    pub evaluations: usize,
}

/// Input the oracle cannot judge.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum OracleError {
    /// A parameter whose quadrature rule cannot be built.
    #[error("parameter {param}: {source}")]
    Quadrature {
        /// Parameter name.
        param: String,
        /// Why.
        source: QuadratureError,
    },
    /// An inconsistent scene description.
    #[error("bad scene: {0}")]
    BadScene(String),
}

/// The Cantelli contour condition of one obstacle at level `delta` (paper, eqs. 10–12):
/// E\[P\] < 0 and E\[P\]² − (1−Δ)·E\[P²\] > 0.
pub fn cantelli_safe(ep: f64, ep2: f64, delta: f64) -> bool {
    ep < 0.0 && ep * ep - (1.0 - delta) * ep2 > 0.0
}

/// E\[P\] and E\[P²\] of one obstacle at points, by tensor-product quadrature.
///
/// A pedestrian ([`Shape::Pedestrian`]) whose position and velocity errors are each
/// `base + scale·ω` of its own normal parameter ω is integrated through its centre error
/// instead: per axis z_d(t) = p_d + v_d·(t − t_ref) is normal (a sum of independent
/// normals) with mean m_p + m_v·(t − t_ref) and variance s_p² + s_v²·(t − t_ref)², and the
/// axes are independent, so a 3-node Gauss–Hermite rule per axis (exact to degree 5; P
/// has degree 2 in z) gives E\[P\] and E\[P²\] exactly with 3^dim nodes instead of the
/// 3^(2·dim) of the tensor product over the 2·dim errors. The other parameters (an
/// uncertain radius) keep their tensor-product rule. [`ObstacleMoments::tensor`] builds
/// the plain tensor product for every obstacle (the cross-check of the shortcut).
#[derive(Clone, Debug)]
pub struct ObstacleMoments {
    spec: ObstacleSpec,
    /// (weight, parameter values) of the tensor-product rule (with a Gaussian centre
    /// error: over the other parameters only, the errors' entries 0 and unused).
    nodes: Vec<(f64, Vec<f64>)>,
    /// A pedestrian's Gaussian centre error, integrated per axis.
    centre_error: Option<GaussianCentreError>,
}

/// A pedestrian's centre error z(t) = p + v·(t − t_ref), normal and independent per axis.
#[derive(Clone, Debug)]
struct GaussianCentreError {
    t_ref: f64,
    /// Per axis: mean and variance of the position error, of the velocity error.
    pos: Vec<(f64, f64)>,
    vel: Vec<(f64, f64)>,
    /// The product over the axes of the standard normal's 3-node rule: (weight, ξ per
    /// axis); z_d = mean_d(t) + ξ_d·sd_d(t).
    combos: Vec<(f64, Vec<f64>)>,
}

impl GaussianCentreError {
    /// The pedestrian's errors if each is constant or `base + scale·ω` of a normal ω of
    /// its own (no parameter shared with another quantity), with the indices of those
    /// parameters; `None` otherwise (the tensor product then integrates them).
    fn of(spec: &ObstacleSpec) -> Result<Option<(Self, Vec<usize>)>, OracleError> {
        let Shape::Pedestrian { radius, pos, vel, t_ref } = &spec.shape else { return Ok(None) };
        let mut used: Vec<usize> = radius.param.into_iter().collect();
        let mut own = vec![];
        let mut normal = |u: &Unc| -> Option<(f64, f64)> {
            match u.param {
                None => Some((u.base, 0.0)),
                Some(i) => {
                    if used.contains(&i) {
                        return None;
                    }
                    used.push(i);
                    own.push(i);
                    match spec.params.get(i).map(|p| &p.dist) {
                        Some(Dist::Normal { mean, std }) => Some((u.base + u.scale * mean, (u.scale * std).powi(2))),
                        _ => None,
                    }
                }
            }
        };
        let p: Option<Vec<(f64, f64)>> = pos.iter().map(&mut normal).collect();
        let v: Option<Vec<(f64, f64)>> = vel.iter().map(&mut normal).collect();
        let (Some(p), Some(v)) = (p, v) else { return Ok(None) };
        let std_normal = Dist::Normal { mean: 0.0, std: 1.0 };
        let r = rule(&std_normal).map_err(|source| OracleError::Quadrature { param: "N(0, 1)".into(), source })?;
        let mut combos = vec![(1.0, vec![])];
        for _ in 0..p.len() {
            combos = combos
                .into_iter()
                .flat_map(|(w, xi): (f64, Vec<f64>)| {
                    r.nodes.iter().zip(&r.weights).map(move |(&x, &rw)| {
                        let mut xi2 = xi.clone();
                        xi2.push(x);
                        (w * rw, xi2)
                    })
                })
                .collect();
        }
        Ok(Some((GaussianCentreError { t_ref: *t_ref, pos: p, vel: v, combos }, own)))
    }
}

impl ObstacleMoments {
    /// Builds the rule of the obstacle's parameters (a pedestrian's Gaussian errors
    /// through its centre error, see the type's documentation).
    pub fn new(spec: &ObstacleSpec) -> Result<Self, OracleError> {
        match GaussianCentreError::of(spec)? {
            Some((ce, own)) => {
                Ok(ObstacleMoments { spec: spec.clone(), nodes: tensor_rule(spec, &own)?, centre_error: Some(ce) })
            }
            None => Self::tensor(spec),
        }
    }

    /// The plain tensor-product rule over every parameter, whatever the obstacle
    /// (3^k nodes for k parameters: slow for pedestrians; the cross-check of
    /// [`ObstacleMoments::new`]).
    pub fn tensor(spec: &ObstacleSpec) -> Result<Self, OracleError> {
        Ok(ObstacleMoments { spec: spec.clone(), nodes: tensor_rule(spec, &[])?, centre_error: None })
    }

    /// Quadrature nodes per evaluation (the cost of [`ObstacleMoments::at`]).
    pub fn node_count(&self) -> usize {
        self.nodes.len() * self.centre_error.as_ref().map_or(1, |c| c.combos.len())
    }

    /// (E\[P\], E\[P²\]) at (x, t).
    pub fn at(&self, x: &[f64], t: f64) -> (f64, f64) {
        let (mut m1, mut m2) = (0.0, 0.0);
        match &self.centre_error {
            None => {
                for (w, v) in &self.nodes {
                    let p = self.spec.eval(x, t, v);
                    m1 += w * p;
                    m2 += w * p * p;
                }
            }
            Some(ce) => {
                let dt = t - ce.t_ref;
                let (mean, sd): (Vec<f64>, Vec<f64>) = ce
                    .pos
                    .iter()
                    .zip(&ce.vel)
                    .map(|((mp, vp), (mv, vv))| (mp + mv * dt, (vp + vv * dt * dt).sqrt()))
                    .unzip();
                let mut z = vec![0.0; mean.len()];
                for (w, v) in &self.nodes {
                    for (cw, xi) in &ce.combos {
                        for (d, zd) in z.iter_mut().enumerate() {
                            *zd = mean[d] + xi[d] * sd[d];
                        }
                        let p = self.spec.eval_with_centre_error(x, t, v, &z);
                        m1 += w * cw * p;
                        m2 += w * cw * p * p;
                    }
                }
            }
        }
        (m1, m2)
    }
}

/// The tensor product of the rules of the obstacle's parameters, but for those in
/// `skip` (value 0, weight 1).
fn tensor_rule(spec: &ObstacleSpec, skip: &[usize]) -> Result<Vec<(f64, Vec<f64>)>, OracleError> {
    let mut nodes = vec![(1.0, vec![])];
    for (i, p) in spec.params.iter().enumerate() {
        let r = if skip.contains(&i) {
            Rule { nodes: vec![0.0], weights: vec![1.0] }
        } else {
            rule(&p.dist).map_err(|source| OracleError::Quadrature { param: p.name.clone(), source })?
        };
        nodes = nodes
            .into_iter()
            .flat_map(|(w, v)| {
                r.nodes.iter().zip(&r.weights).map(move |(&x, &rw)| {
                    let mut v2 = v.clone();
                    v2.push(x);
                    (w * rw, v2)
                })
            })
            .collect();
    }
    Ok(nodes)
}

/// Point classification against the three levels.
struct Model<'a> {
    g: &'a GeneratedScene,
    obs: Vec<ObstacleMoments>,
    /// Δ, tightened, relaxed.
    levels: [f64; 3],
    evaluations: usize,
}

const SAFE_DELTA: u8 = 1;
const SAFE_TIGHT: u8 = 2;
const SAFE_RELAXED: u8 = 4;

impl<'a> Model<'a> {
    fn new(g: &'a GeneratedScene) -> Result<Self, OracleError> {
        if !(g.delta > 0.0 && g.delta < 1.0) {
            return Err(OracleError::BadScene(format!("Δ = {} is not in (0, 1)", g.delta)));
        }
        if g.lower.len() != g.dim || g.upper.len() != g.dim || g.start.len() != g.dim || g.goal.len() != g.dim {
            return Err(OracleError::BadScene("coordinates of the wrong dimension".into()));
        }
        if g.horizon.0.partial_cmp(&g.horizon.1) != Some(std::cmp::Ordering::Less) {
            return Err(OracleError::BadScene("empty horizon".into()));
        }
        validate(g).map_err(OracleError::BadScene)?;
        let obs = g.obstacles.iter().map(ObstacleMoments::new).collect::<Result<Vec<_>, _>>()?;
        let levels = [g.delta, g.delta * TIGHT_FACTOR, (g.delta * RELAX_FACTOR).min(RELAX_CAP).max(g.delta)];
        Ok(Model { g, obs, levels, evaluations: 0 })
    }

    fn inside(&self, x: &[f64]) -> bool {
        x.iter().zip(self.g.lower.iter().zip(&self.g.upper)).all(|(v, (l, u))| l <= v && v <= u)
    }

    /// Bit mask of the levels at which (x, t) is safe.
    fn mask(&mut self, x: &[f64], t: f64) -> u8 {
        self.evaluations += 1;
        if !self.inside(x) {
            return 0;
        }
        let mut m = SAFE_DELTA | SAFE_TIGHT | SAFE_RELAXED;
        for o in &self.obs {
            let (ep, ep2) = o.at(x, t);
            for (bit, level) in [SAFE_DELTA, SAFE_TIGHT, SAFE_RELAXED].into_iter().zip(self.levels) {
                if m & bit != 0 && !cantelli_safe(ep, ep2, level) {
                    m &= !bit;
                }
            }
            if m == 0 {
                break;
            }
        }
        m
    }

    /// The first obstacle (or the workspace) that makes (x, t) unsafe at Δ.
    fn blocker(&self, x: &[f64], t: f64) -> Option<String> {
        if !self.inside(x) {
            return Some("workspace".into());
        }
        self.obs
            .iter()
            .find(|o| {
                let (ep, ep2) = o.at(x, t);
                !cantelli_safe(ep, ep2, self.levels[0])
            })
            .map(|o| o.spec.id.clone())
    }

    /// Whether the straight motion from an endpoint (a, ta) to a cell centre (b, tb) is
    /// safe at level Δ at `n` + 1 evenly spaced points, ends included. Level Δ, not the
    /// tightened one: the endpoint itself need only be safe at Δ, and the cell it
    /// connects to is checked with clearance at the tightened level.
    fn connection_safe(&mut self, a: &[f64], ta: f64, b: &[f64], tb: f64, n: usize) -> bool {
        (0..=n).all(|j| {
            let s = j as f64 / n as f64;
            let x: Vec<f64> = a.iter().zip(b).map(|(a, b)| a + s * (b - a)).collect();
            self.mask(&x, ta + s * (tb - ta)) & SAFE_DELTA != 0
        })
    }
}

/// What the grids and the point evaluation rely on besides Δ, the coordinate lengths
/// and the horizon (checked first, in [`Model::new`]): a hand-made scene that breaks it is
/// refused with a message, never judged with a panic or an unbounded grid.
fn validate(g: &GeneratedScene) -> Result<(), String> {
    // the grid's memo key holds three space coordinates and time (4 × KEY_BITS bits)
    if !(2..=3).contains(&g.dim) {
        return Err(format!("dimension {} (the oracle judges 2-D and 3-D scenes)", g.dim));
    }
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if !finite(&g.start) || !finite(&g.goal) || !(g.horizon.1 - g.horizon.0).is_finite() {
        return Err("start, goal and horizon must be finite".into());
    }
    if !g.lower.iter().zip(&g.upper).all(|(l, u)| l < u && (u - l).is_finite()) {
        return Err("every workspace side must be finite and longer than zero".into());
    }
    if g.max_speed.is_some_and(|v| !(v > 0.0 && v.is_finite())) {
        return Err("max_speed must be finite and > 0".into());
    }
    for o in &g.obstacles {
        let m = &o.motion;
        if [&m.c0, &m.v, &m.a].iter().any(|v| v.len() != g.dim || !finite(v)) {
            return Err(format!("obstacle {}: motion of the wrong dimension or not finite", o.id));
        }
        let (per_axis, uncs): (Vec<usize>, Vec<&Unc>) = match &o.shape {
            Shape::Ball { radius, offset } => (vec![offset.len()], [radius].into_iter().chain(offset).collect()),
            Shape::Ellipsoid { size, inv_sq, offset, .. } => {
                (vec![inv_sq.len(), offset.len()], [size].into_iter().chain(offset).collect())
            }
            Shape::Peanut { shift, lobe, r1sq, k, .. } => (vec![lobe.len()], vec![shift, r1sq, k]),
            Shape::Superellipse { r4 } => (vec![], vec![r4]),
            Shape::Pedestrian { radius, pos, vel, t_ref } => {
                if !t_ref.is_finite() {
                    return Err(format!("obstacle {}: t_ref is not finite", o.id));
                }
                (vec![pos.len(), vel.len()], [radius].into_iter().chain(pos).chain(vel).collect())
            }
        };
        if per_axis.iter().any(|&n| n != g.dim) {
            return Err(format!("obstacle {}: shape of the wrong dimension", o.id));
        }
        if uncs.iter().any(|u| u.param.is_some_and(|i| i >= o.params.len())) {
            return Err(format!("obstacle {}: a quantity refers to a parameter it does not have", o.id));
        }
    }
    Ok(())
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt()
}

/// A grid of cells with a fine lattice of `sub` points per cell per axis (and per layer
/// in time), memoising point classifications.
struct Grid {
    dim: usize,
    n: Vec<i64>,
    h: Vec<f64>,
    lower: Vec<f64>,
    sub: i64,
    t0: f64,
    dt: f64,
    memo: HashMap<u64, u8>,
    fresh: usize,
}

/// Bits per lattice coordinate in a memo key (4 × 16 = 64).
const KEY_BITS: u32 = 16;

impl Grid {
    fn new(g: &GeneratedScene, cells_longest: usize, sub: i64, layers: usize) -> Grid {
        let width = g.width();
        let h0 = width / cells_longest as f64;
        let n: Vec<i64> = (0..g.dim).map(|d| (((g.upper[d] - g.lower[d]) / h0).ceil() as i64).max(2)).collect();
        let h: Vec<f64> = (0..g.dim).map(|d| (g.upper[d] - g.lower[d]) / n[d] as f64).collect();
        let dt = if layers == 0 { 0.0 } else { (g.horizon.1 - g.horizon.0) / layers as f64 };
        Grid { dim: g.dim, n, h, lower: g.lower.clone(), sub, t0: g.horizon.0, dt, memo: HashMap::new(), fresh: 0 }
    }

    fn cells(&self) -> usize {
        self.n.iter().product::<i64>() as usize
    }

    fn id(&self, i: &[i64]) -> usize {
        let mut id = 0;
        for d in (0..self.dim).rev() {
            id = id * self.n[d] as usize + i[d] as usize;
        }
        id
    }

    fn coords(&self, mut id: usize) -> Vec<i64> {
        (0..self.dim)
            .map(|d| {
                let c = (id % self.n[d] as usize) as i64;
                id /= self.n[d] as usize;
                c
            })
            .collect()
    }

    fn in_bounds(&self, i: &[i64]) -> bool {
        i.iter().zip(&self.n).all(|(&c, &n)| c >= 0 && c < n)
    }

    fn centre(&self, i: &[i64]) -> Vec<f64> {
        (0..self.dim).map(|d| self.lower[d] + self.h[d] * (i[d] as f64 + 0.5)).collect()
    }

    fn cell_of(&self, x: &[f64]) -> Vec<i64> {
        (0..self.dim).map(|d| (((x[d] - self.lower[d]) / self.h[d]).floor() as i64).clamp(0, self.n[d] - 1)).collect()
    }

    /// Classification of the fine lattice point `f` (space, in 1/sub cells from the
    /// first centre) at fine time index `g` (in 1/sub layers from t₀).
    fn fine(&mut self, m: &mut Model<'_>, f: &[i64], g: i64) -> u8 {
        let mut key = g as u64;
        for &c in f {
            key = (key << KEY_BITS) | (c as u64 & ((1 << KEY_BITS) - 1));
        }
        if let Some(&v) = self.memo.get(&key) {
            return v;
        }
        let x: Vec<f64> =
            (0..self.dim).map(|d| self.lower[d] + self.h[d] * (0.5 + f[d] as f64 / self.sub as f64)).collect();
        let t = self.t0 + self.dt * g as f64 / self.sub as f64;
        let v = m.mask(&x, t);
        self.fresh += 1;
        self.memo.insert(key, v);
        v
    }

    /// Classification of a cell centre at layer k.
    fn node(&mut self, m: &mut Model<'_>, i: &[i64], k: i64) -> u8 {
        let f: Vec<i64> = i.iter().map(|c| c * self.sub).collect();
        self.fine(m, &f, k * self.sub)
    }

    /// Cell and every in-bounds neighbour safe at the tightened level, at layer k.
    fn allowed(&mut self, m: &mut Model<'_>, i: &[i64], k: i64, around: &[Vec<i64>]) -> bool {
        if self.node(m, i, k) & SAFE_TIGHT == 0 {
            return false;
        }
        for off in around {
            let j: Vec<i64> = i.iter().zip(off).map(|(a, b)| a + b).collect();
            if self.in_bounds(&j) && self.node(m, &j, k) & SAFE_TIGHT == 0 {
                return false;
            }
        }
        true
    }

    /// Interior lattice points of the move i → i + off from layer k (k+1 when `timed`)
    /// safe at the tightened level.
    fn edge(&mut self, m: &mut Model<'_>, i: &[i64], off: &[i64], k: i64, timed: bool) -> bool {
        (1..self.sub).all(|j| {
            let f: Vec<i64> = i.iter().zip(off).map(|(c, o)| c * self.sub + j * o).collect();
            let g = k * self.sub + if timed { j } else { 0 };
            self.fine(m, &f, g) & SAFE_TIGHT != 0
        })
    }
}

/// All offsets in [−r, r]^dim except 0 (with `include_zero`, also 0).
fn offsets(dim: usize, r: i64, include_zero: bool) -> Vec<Vec<i64>> {
    let mut out = vec![vec![]];
    for _ in 0..dim {
        out = out.into_iter().flat_map(|v| (-r..=r).map(move |c| [v.clone(), vec![c]].concat())).collect();
    }
    out.retain(|v| include_zero || v.iter().any(|&c| c != 0));
    out
}

fn cheb(a: &[i64], b: &[i64]) -> i64 {
    a.iter().zip(b).map(|(a, b)| (a - b).abs()).max().unwrap_or(0)
}

/// Outcome of a strict search.
enum Search {
    Found(Vec<Waypoint>),
    NotFound,
    Budget,
}

/// Judges a generated scene.
pub fn judge(g: &GeneratedScene, opts: &OracleOptions) -> Result<OracleReport, OracleError> {
    let mut m = Model::new(g)?;
    let levels = m.levels;
    let (t0, tf) = g.horizon;
    let moving = g.moving();
    let (cells, layers) = resolution(g);
    let mut info = GridInfo { cells: vec![], layers, reach_cells: 0, substeps: EDGE_SUBSTEPS, levels };
    let report =
        |judgement, info: GridInfo, m: &Model<'_>| OracleReport { judgement, grid: info, evaluations: m.evaluations };

    for (name, p, t) in [("start", &g.start, t0), ("goal", &g.goal, tf)] {
        if let Some(ob) = m.blocker(p, t) {
            let reason = InfeasibleReason::EndpointUnsafe { endpoint: name.into(), obstacle: ob, time: t };
            return Ok(report(Judgement::Infeasible { reason }, info, &m));
        }
    }
    let straight = dist(&g.start, &g.goal);
    if let Some(v) = g.max_speed {
        let reach = v * (tf - t0);
        if straight > reach {
            let reason = InfeasibleReason::OutOfReach { distance: straight, reach };
            return Ok(report(Judgement::Infeasible { reason }, info, &m));
        }
    }
    let judgement = if moving {
        judge_moving(g, &mut m, &mut info, cells, layers, opts)
    } else {
        judge_static(g, &mut m, &mut info, cells, opts)
    };
    Ok(report(judgement, info, &m))
}

/// Cells on the longest side and time layers for a scene.
fn resolution(g: &GeneratedScene) -> (usize, usize) {
    let width = g.width();
    let feature = g.obstacles.iter().map(|o| o.feature).fold(f64::INFINITY, f64::min);
    let want = (width / feature * CELLS_PER_FEATURE).ceil();
    let moving = g.moving();
    let (lo, hi) = match (g.dim, moving) {
        (2, false) => STATIC_CELLS_2D,
        (_, false) => STATIC_CELLS_3D,
        (2, true) => MOVING_CELLS_2D,
        (_, true) => MOVING_CELLS_3D,
    };
    let cells = if want.is_finite() { (want as usize).clamp(lo, hi) } else { lo };
    if !moving {
        return (cells, 0);
    }
    // layers: obstacle travel per layer ≲ one cell
    let (t0, tf) = g.horizon;
    let h = width / cells as f64;
    let travel = g
        .obstacles
        .iter()
        .map(|o| {
            (0..32)
                .map(|k| {
                    let ta = t0 + (tf - t0) * k as f64 / 32.0;
                    let tb = t0 + (tf - t0) * (k + 1) as f64 / 32.0;
                    dist(&o.motion.centre(ta), &o.motion.centre(tb))
                })
                .sum::<f64>()
        })
        .fold(0.0, f64::max);
    let mut layers = (travel / h).ceil();
    if g.max_speed.is_none() {
        let cap = if g.dim == 2 { REACH_CAP_2D } else { REACH_CAP_3D } as f64;
        let cheb = g.start.iter().zip(&g.goal).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max) / h;
        layers = layers.max((LAYER_SLACK * cheb / cap).ceil());
    }
    (cells, (layers as usize).clamp(LAYERS.0, LAYERS.1))
}

fn judge_static(
    g: &GeneratedScene,
    m: &mut Model<'_>,
    info: &mut GridInfo,
    cells: usize,
    opts: &OracleOptions,
) -> Judgement {
    let sub = EDGE_SUBSTEPS as i64;
    let mut grid = Grid::new(g, cells, sub, 0);
    info.cells = grid.n.iter().map(|&n| n as usize).collect();
    let around = offsets(g.dim, 1, false);
    let (t0, tf) = g.horizon;
    let hmax = grid.h.iter().cloned().fold(0.0, f64::max);
    let conn = |len: f64| CONNECTION_SAMPLES.max((len / hmax * EDGE_SUBSTEPS as f64).ceil() as usize);

    // endpoint connections: cells around the endpoint's cell, allowed, straight segment safe
    let connect = |grid: &mut Grid, m: &mut Model<'_>, p: &[f64]| -> Vec<(usize, f64)> {
        let c = grid.cell_of(p);
        let mut out = vec![];
        for off in offsets(g.dim, CONNECTION_REACH, true) {
            let j: Vec<i64> = c.iter().zip(&off).map(|(a, b)| a + b).collect();
            if !grid.in_bounds(&j) || !grid.allowed(m, &j, 0, &around) {
                continue;
            }
            let x = grid.centre(&j);
            let len = dist(p, &x);
            if m.connection_safe(p, t0, &x, t0, conn(len)) {
                out.push((grid.id(&j), len));
            }
        }
        out
    };
    let starts = connect(&mut grid, m, &g.start);
    let goals: HashMap<usize, f64> = connect(&mut grid, m, &g.goal).into_iter().collect();
    let budget = opts.max_evaluations;
    let mut result = Search::NotFound;
    if !starts.is_empty() && !goals.is_empty() {
        // A* over allowed cells, Euclidean costs and heuristic
        let mut best: HashMap<usize, f64> = HashMap::new();
        let mut parent: HashMap<usize, usize> = HashMap::new();
        let mut heap = BinaryHeap::new();
        let hgoal = |grid: &Grid, id: usize| dist(&grid.centre(&grid.coords(id)), &g.goal);
        for &(id, len) in &starts {
            best.insert(id, len);
            heap.push(Reverse(((len + hgoal(&grid, id)).to_bits(), id)));
        }
        let moves = offsets(g.dim, 1, false);
        while let Some(Reverse((_, id))) = heap.pop() {
            if grid.fresh > budget {
                result = Search::Budget;
                break;
            }
            if goals.contains_key(&id) {
                let mut ids = vec![id];
                while let Some(&p) = parent.get(ids.last().unwrap_or(&id)) {
                    ids.push(p);
                }
                ids.reverse();
                let mut pts = vec![g.start.clone()];
                pts.extend(ids.iter().map(|&i| grid.centre(&grid.coords(i))));
                pts.push(g.goal.clone());
                result = Search::Found(time_at_constant_speed(pts, t0, tf));
                break;
            }
            let gi = best[&id];
            let i = grid.coords(id);
            for off in &moves {
                let j: Vec<i64> = i.iter().zip(off).map(|(a, b)| a + b).collect();
                if !grid.in_bounds(&j) {
                    continue;
                }
                let jd = grid.id(&j);
                let step = dist(&grid.centre(&i), &grid.centre(&j));
                if best.get(&jd).is_some_and(|&b| b <= gi + step) {
                    continue;
                }
                if !grid.allowed(m, &j, 0, &around) || !grid.edge(m, &i, off, 0, false) {
                    continue;
                }
                best.insert(jd, gi + step);
                parent.insert(jd, id);
                heap.push(Reverse(((gi + step + hgoal(&grid, jd)).to_bits(), jd)));
            }
        }
    }
    match result {
        Search::Found(path) => {
            let len: f64 = path.windows(2).map(|w| dist(&w[0].x, &w[1].x)).sum();
            match g.max_speed {
                Some(v) if len > v * (tf - t0) => Judgement::Ambiguous {
                    note: format!("clearance path of length {len:.4} exceeds max_speed·T = {:.4}", v * (tf - t0)),
                },
                _ => Judgement::Feasible { path },
            }
        }
        other => {
            if static_disconnected(g, m, &mut grid) {
                Judgement::Infeasible { reason: InfeasibleReason::Disconnected }
            } else {
                Judgement::Ambiguous {
                    note: match other {
                        Search::Budget => "strict search over its evaluation budget; relaxed graph connected".into(),
                        _ => "no clearance path at Δ/2; relaxed graph connected".into(),
                    },
                }
            }
        }
    }
}

/// Waypoints timed at constant speed over [t0, tf].
fn time_at_constant_speed(pts: Vec<Vec<f64>>, t0: f64, tf: f64) -> Vec<Waypoint> {
    let total: f64 = pts.windows(2).map(|w| dist(&w[0], &w[1])).sum();
    let mut acc = 0.0;
    let n = pts.len();
    let mut out = Vec::with_capacity(n);
    for (k, p) in pts.iter().enumerate() {
        if k > 0 {
            acc += dist(&pts[k - 1], p);
        }
        let t = if k + 1 == n {
            tf
        } else if total > 0.0 {
            t0 + (tf - t0) * acc / total
        } else {
            t0
        };
        out.push(Waypoint { x: p.clone(), t });
    }
    out
}

/// Breadth-first search over cells safe at the relaxed level (no clearance, no edge
/// checks), 8-/26-connected, from the cells around the start to those around the goal.
fn static_disconnected(g: &GeneratedScene, m: &mut Model<'_>, grid: &mut Grid) -> bool {
    let around = offsets(g.dim, 1, true);
    let moves = offsets(g.dim, 1, false);
    let mut seen = vec![false; grid.cells()];
    let mut queue = VecDeque::new();
    let sc = grid.cell_of(&g.start);
    let gc = grid.cell_of(&g.goal);
    for off in &around {
        let j: Vec<i64> = sc.iter().zip(off).map(|(a, b)| a + b).collect();
        if grid.in_bounds(&j) && grid.node(m, &j, 0) & SAFE_RELAXED != 0 {
            let id = grid.id(&j);
            if !seen[id] {
                seen[id] = true;
                queue.push_back(j);
            }
        }
    }
    while let Some(i) = queue.pop_front() {
        if cheb(&i, &gc) <= 1 {
            return false;
        }
        for off in &moves {
            let j: Vec<i64> = i.iter().zip(off).map(|(a, b)| a + b).collect();
            if !grid.in_bounds(&j) {
                continue;
            }
            let id = grid.id(&j);
            if !seen[id] && grid.node(m, &j, 0) & SAFE_RELAXED != 0 {
                seen[id] = true;
                queue.push_back(j);
            }
        }
    }
    true
}

fn judge_moving(
    g: &GeneratedScene,
    m: &mut Model<'_>,
    info: &mut GridInfo,
    cells: usize,
    layers: usize,
    opts: &OracleOptions,
) -> Judgement {
    let (t0, tf) = g.horizon;
    let width = g.width();
    let h0 = width / cells as f64;
    let dt = (tf - t0) / layers as f64;
    let diag = g.lower.iter().zip(&g.upper).map(|(l, u)| (u - l).powi(2)).sum::<f64>().sqrt();
    // reach per layer: the speed limit, else half the workspace diagonal ("generous")
    let reach = g.max_speed.map(|v| v * dt).unwrap_or(0.5 * diag);
    let cap = if g.dim == 2 { REACH_CAP_2D } else { REACH_CAP_3D };
    let r = ((reach / h0).floor() as i64).min(cap);
    let sub = (EDGE_SUBSTEPS as i64).max(2 * r);
    let mut grid = Grid::new(g, cells, sub, layers);
    info.cells = grid.n.iter().map(|&n| n as usize).collect();
    info.reach_cells = r;
    info.substeps = sub as usize;
    let hmin = grid.h.iter().cloned().fold(f64::INFINITY, f64::min);
    let k_last = layers as i64; // goal layer
    let around = offsets(g.dim, 1, false);
    let mut result = Search::NotFound;
    if r >= 1 {
        result = moving_search(g, m, &mut grid, r, reach, k_last, &around, opts.max_evaluations);
    }
    match result {
        Search::Found(path) => Judgement::Feasible { path },
        other => {
            let r_rel = ((reach / hmin).ceil() as i64).saturating_add(1).min(grid.n.iter().cloned().max().unwrap_or(1));
            if moving_disconnected(g, m, &mut grid, r_rel, k_last) {
                Judgement::Infeasible { reason: InfeasibleReason::Disconnected }
            } else {
                Judgement::Ambiguous {
                    note: match other {
                        Search::Budget => "time-expanded strict search over its evaluation budget".into(),
                        _ if r < 1 => "speed limit below one cell per layer".into(),
                        _ => "no clearance path at Δ/2 in the time-expanded grid; relaxed graph connected".into(),
                    },
                }
            }
        }
    }
}

/// A* in the time-expanded graph: states (cell, layer) for layers 1..K−1; start at
/// layer 0 and goal at layer K are the exact endpoints.
#[allow(clippy::too_many_arguments)]
fn moving_search(
    g: &GeneratedScene,
    m: &mut Model<'_>,
    grid: &mut Grid,
    r: i64,
    reach: f64,
    k_last: i64,
    around: &[Vec<i64>],
    budget: usize,
) -> Search {
    let (t0, tf) = g.horizon;
    let dt = grid.dt;
    let limit = g.max_speed.is_some();
    let ncells = grid.cells();
    let gcell = grid.cell_of(&g.goal);
    let scell = grid.cell_of(&g.start);
    let hmax = grid.h.iter().cloned().fold(0.0, f64::max);
    let conn = |len: f64| CONNECTION_SAMPLES.max((len / hmax * EDGE_SUBSTEPS as f64).ceil() as usize);
    let moves = offsets(g.dim, r, true);
    let state = |id: usize, k: i64| k as usize * ncells + id;
    let mut best: HashMap<usize, f64> = HashMap::new();
    let mut parent: HashMap<usize, usize> = HashMap::new();
    let mut heap = BinaryHeap::new();
    let reachable = |grid: &Grid, i: &[i64], k: i64| {
        let left = k_last - k;
        cheb(i, &gcell) <= r * left && (!limit || dist(&grid.centre(i), &g.goal) <= reach * left as f64 + hmax)
    };
    // first moves: start (t0) → cell at layer 1
    for off in &moves {
        let j: Vec<i64> = scell.iter().zip(off).map(|(a, b)| a + b).collect();
        if !grid.in_bounds(&j) || !reachable(grid, &j, 1) {
            continue;
        }
        let x = grid.centre(&j);
        let len = dist(&g.start, &x);
        if (limit && len > reach)
            || !grid.allowed(m, &j, 1, around)
            || !m.connection_safe(&g.start, t0, &x, t0 + dt, conn(len))
        {
            continue;
        }
        let s = state(grid.id(&j), 1);
        best.insert(s, len);
        heap.push(Reverse(((len + dist(&x, &g.goal)).to_bits(), s)));
    }
    while let Some(Reverse((_, s))) = heap.pop() {
        if grid.fresh > budget {
            return Search::Budget;
        }
        let (k, id) = ((s / ncells) as i64, s % ncells);
        let i = grid.coords(id);
        let gi = best[&s];
        let x = grid.centre(&i);
        if k == k_last - 1 {
            // last move: cell → goal at tf
            let len = dist(&x, &g.goal);
            if (!limit || len <= reach)
                && cheb(&i, &gcell) <= r
                && m.connection_safe(&x, tf - dt, &g.goal, tf, conn(len))
            {
                let mut states = vec![s];
                while let Some(&p) = parent.get(states.last().unwrap_or(&s)) {
                    states.push(p);
                }
                states.reverse();
                let mut path = vec![Waypoint { x: g.start.clone(), t: t0 }];
                for st in states {
                    let kk = (st / ncells) as f64;
                    path.push(Waypoint { x: grid.centre(&grid.coords(st % ncells)), t: t0 + dt * kk });
                }
                path.push(Waypoint { x: g.goal.clone(), t: tf });
                return Search::Found(path);
            }
            continue;
        }
        for off in &moves {
            let j: Vec<i64> = i.iter().zip(off).map(|(a, b)| a + b).collect();
            if !grid.in_bounds(&j) || !reachable(grid, &j, k + 1) {
                continue;
            }
            let y = grid.centre(&j);
            let step = dist(&x, &y);
            if limit && step > reach {
                continue;
            }
            let s2 = state(grid.id(&j), k + 1);
            if best.get(&s2).is_some_and(|&b| b <= gi + step) {
                continue;
            }
            if !grid.allowed(m, &j, k + 1, around) || !grid.edge(m, &i, off, k, true) {
                continue;
            }
            best.insert(s2, gi + step);
            parent.insert(s2, s);
            heap.push(Reverse(((gi + step + dist(&y, &g.goal)).to_bits(), s2)));
        }
    }
    Search::NotFound
}

/// Layer-by-layer reachability through cells safe at the relaxed level, moves of up to
/// `r` cells per axis per layer (no clearance, no edge checks).
fn moving_disconnected(g: &GeneratedScene, m: &mut Model<'_>, grid: &mut Grid, r: i64, k_last: i64) -> bool {
    let n = grid.cells();
    let scell = grid.cell_of(&g.start);
    let gcell = grid.cell_of(&g.goal);
    let mut cur = vec![false; n];
    cur[grid.id(&scell)] = true;
    for k in 1..k_last {
        let dil = dilate(grid, &cur, r);
        let mut next = vec![false; n];
        let mut any = false;
        for id in 0..n {
            if dil[id] {
                let i = grid.coords(id);
                if grid.node(m, &i, k) & SAFE_RELAXED != 0 {
                    next[id] = true;
                    any = true;
                }
            }
        }
        if !any {
            return true;
        }
        cur = next;
    }
    !cur.iter().enumerate().any(|(id, &c)| c && cheb(&grid.coords(id), &gcell) <= r)
}

/// Chebyshev dilation by `r` cells, axis by axis.
fn dilate(grid: &Grid, set: &[bool], r: i64) -> Vec<bool> {
    let mut cur = set.to_vec();
    for d in 0..grid.dim {
        let mut next = vec![false; cur.len()];
        for (id, &on) in cur.iter().enumerate() {
            if !on {
                continue;
            }
            let mut i = grid.coords(id);
            let c = i[d];
            for v in (c - r).max(0)..=(c + r).min(grid.n[d] - 1) {
                i[d] = v;
                next[grid.id(&i)] = true;
            }
        }
        cur = next;
    }
    cur
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{Dist, Intent, Motion, MotionKind, ParamSpec};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha12Rng;

    fn ball(id: &str, c: Vec<f64>, radius: Unc, params: Vec<ParamSpec>) -> ObstacleSpec {
        let dim = c.len();
        ObstacleSpec {
            id: id.into(),
            shape: Shape::Ball { radius, offset: vec![Unc::fixed(0.0); dim] },
            motion: Motion { kind: MotionKind::Static, c0: c, v: vec![0.0; dim], a: vec![0.0; dim] },
            params,
            bound: 1.0,
            feature: 0.1,
        }
    }

    fn scene(obstacles: Vec<ObstacleSpec>, delta: f64) -> GeneratedScene {
        GeneratedScene {
            seed: 0,
            index: 0,
            name: "hand".into(),
            dim: 2,
            lower: vec![100.0, -50.0],
            upper: vec![101.0, -49.0],
            horizon: (3.0, 4.0),
            delta,
            start: vec![100.1, -49.5],
            goal: vec![100.9, -49.5],
            max_speed: None,
            obstacles,
            intent: Intent::Feasible,
        }
    }

    /// The Cantelli level of a disk with uniform radius matches the closed form: at a
    /// point at distance ρ, E[P] = E[r²] − ρ², E[P²] = E[r⁴] − 2ρ²E[r²] + ρ⁴, and the
    /// point is safe exactly when Δ > 1 − E[P]²/E[P²].
    #[test]
    fn point_safety_matches_the_closed_form_cantelli_level() {
        let (a, b) = (0.1, 0.2);
        let p = ParamSpec { name: "r".into(), dist: Dist::Uniform { low: a, high: b } };
        let o = ball("d", vec![100.5, -49.5], Unc { base: 0.0, scale: 1.0, param: Some(0) }, vec![p]);
        let er2 = (b * b * b - a * a * a) / (3.0 * (b - a));
        let er4 = (b.powi(5) - a.powi(5)) / (5.0 * (b - a));
        for rho in [0.25, 0.3, 0.4] {
            let ep = er2 - rho * rho;
            let ep2 = er4 - 2.0 * rho * rho * er2 + rho.powi(4);
            let level = 1.0 - ep * ep / ep2;
            for (delta, safe) in [(level * 1.02, true), (level * 0.98, false)] {
                let g = scene(vec![o.clone()], delta.min(0.99));
                let mut m = Model::new(&g).unwrap();
                let x = [100.5 + rho, -49.5];
                assert_eq!(m.mask(&x, 3.5) & SAFE_DELTA != 0, safe, "ρ = {rho}, Δ = {delta}, level {level}");
            }
        }
    }

    /// E[P] by quadrature against a high-sample Monte Carlo mean, for every family.
    #[test]
    fn expected_p_agrees_with_monte_carlo() {
        let mut rng = ChaCha12Rng::seed_from_u64(11);
        let dists = [
            Dist::Uniform { low: -0.5, high: 1.0 },
            Dist::Normal { mean: 0.2, std: 0.5 },
            Dist::Beta { alpha: 2.0, beta: 3.5, low: -1.0, high: 1.0 },
            Dist::Gamma { shape: 2.5, scale: 0.4 },
            Dist::Exponential { rate: 2.0 },
            Dist::Laplace { mean: -0.1, scale: 0.3 },
            Dist::Discrete { values: vec![-1.0, 0.0, 0.5], weights: vec![0.25, 0.35, 0.4] },
            Dist::moments_of_uniform(-7, 9, 20),
        ];
        for d in dists {
            // P = (0.3 + 0.05 w)² − (x1 − 0.1 w − 100.5)² − (x2 + 49.5)²: degree 2 in w
            let params = vec![ParamSpec { name: "w".into(), dist: d.clone() }];
            let o = ObstacleSpec {
                shape: Shape::Ball {
                    radius: Unc { base: 0.3, scale: 0.05, param: Some(0) },
                    offset: vec![Unc { base: 0.0, scale: 0.1, param: Some(0) }, Unc::fixed(0.0)],
                },
                ..ball("d", vec![100.5, -49.5], Unc::fixed(0.0), params)
            };
            let om = ObstacleMoments::new(&o).unwrap();
            for x in [[100.5, -49.5], [100.7, -49.4], [100.1, -49.9]] {
                let (ep, ep2) = om.at(&x, 3.5);
                let n = 200_000;
                let (mut s1, mut s2) = (0.0, 0.0);
                for _ in 0..n {
                    let p = o.eval(&x, 3.5, &[d.sample(&mut rng)]);
                    s1 += p;
                    s2 += p * p;
                }
                let mean = s1 / n as f64;
                let sd = (s2 / n as f64 - mean * mean).max(0.0).sqrt();
                let se = sd / (n as f64).sqrt();
                assert!((ep - mean).abs() <= 5.0 * se + 1e-12, "{}: E[P] {ep} vs MC {mean} ± {se}", d.family());
                assert!((ep2 - s2 / n as f64).abs() <= 0.02 * ep2 + 1e-12, "{}: E[P²]", d.family());
            }
        }
    }

    /// A pedestrian's moments through its Gaussian centre error (3^dim nodes per radius
    /// node) equal the plain tensor product over all its parameters (3^(2·dim + 1)), and
    /// E[P] has the closed form E[r²] − |x − c(t) − m(t)|² − Σ_d s_d(t)²; every
    /// pedestrian of a generated suite takes the shortcut.
    #[test]
    fn pedestrian_moments_through_the_centre_error() {
        let mut rng = ChaCha12Rng::seed_from_u64(3);
        let mut checked = 0;
        for i in 0..120 {
            let g = crate::generate::generate(1, i);
            for o in g.obstacles.iter().filter(|o| matches!(o.shape, Shape::Pedestrian { .. })) {
                let fast = ObstacleMoments::new(o).unwrap();
                let full = ObstacleMoments::tensor(o).unwrap();
                // 3^dim times fewer nodes than the tensor product over 2·dim errors
                assert_eq!(fast.node_count() * 3usize.pow(g.dim as u32), full.node_count(), "scene {i} {}", o.id);
                if checked >= 12 {
                    continue; // the full tensor product is slow in 3-D: a dozen suffice
                }
                checked += 1;
                for _ in 0..5 {
                    let t = g.horizon.0 + (g.horizon.1 - g.horizon.0) * rng.random::<f64>();
                    let c = o.motion.centre(t);
                    let x: Vec<f64> = c.iter().map(|c| c + o.bound * (2.0 * rng.random::<f64>() - 1.0)).collect();
                    let (a1, a2) = fast.at(&x, t);
                    let (b1, b2) = full.at(&x, t);
                    let scale = 1.0 + o.bound.powi(2) + c.iter().fold(0.0f64, |m, v| m.max(v.abs())).powi(2);
                    assert!((a1 - b1).abs() <= 1e-9 * scale, "scene {i} {}: E[P] {a1} vs {b1}", o.id);
                    assert!((a2 - b2).abs() <= 1e-9 * scale * scale, "scene {i} {}: E[P²] {a2} vs {b2}", o.id);
                }
            }
        }
        assert!(checked >= 5, "{checked} pedestrians");
        // closed form, hand-made 2-D pedestrian with a fixed radius and nonzero means
        let n = |name: &str, mean: f64, std: f64| ParamSpec { name: name.into(), dist: Dist::Normal { mean, std } };
        let u = |i: usize, scale: f64| Unc { base: 0.01, scale, param: Some(i) };
        let o = ObstacleSpec {
            id: "p".into(),
            shape: Shape::Pedestrian {
                radius: Unc::fixed(0.2),
                pos: vec![u(0, 1.0), u(1, 2.0)],
                vel: vec![u(2, 1.0), Unc::fixed(0.0)],
                t_ref: 3.0,
            },
            motion: Motion { kind: MotionKind::Linear, c0: vec![100.0, -49.5], v: vec![0.1, 0.0], a: vec![0.0; 2] },
            params: vec![n("a", 0.02, 0.03), n("b", 0.0, 0.01), n("c", -0.01, 0.05)],
            bound: 1.0,
            feature: 0.2,
        };
        let om = ObstacleMoments::new(&o).unwrap();
        assert_eq!(om.node_count(), 9);
        let (x, t): ([f64; 2], f64) = ([100.6, -49.4], 3.5);
        let dt = t - 3.0;
        let m = [0.01 + 0.02 + (0.01 - 0.01) * dt, 0.01];
        let var = [0.03f64.powi(2) + (0.05 * dt).powi(2), 0.02f64.powi(2)];
        let c = o.motion.centre(t);
        let ep = 0.04 - (x[0] - c[0] - m[0]).powi(2) - (x[1] - c[1] - m[1]).powi(2) - var[0] - var[1];
        let (e1, _) = om.at(&x, t);
        assert!((e1 - ep).abs() < 1e-12, "{e1} vs {ep}");
        let (f1, f2) = ObstacleMoments::tensor(&o).unwrap().at(&x, t);
        assert!((f1 - e1).abs() < 1e-12 && (f2 - om.at(&x, t).1).abs() < 1e-12);
        // a shared or non-normal error parameter takes the plain tensor product
        let mut shared = o.clone();
        if let Shape::Pedestrian { vel, .. } = &mut shared.shape {
            vel[1] = u(0, 1.0);
        }
        assert_eq!(ObstacleMoments::new(&shared).unwrap().node_count(), 27);
        let mut uniform = o.clone();
        uniform.params[1].dist = Dist::Uniform { low: -0.01, high: 0.01 };
        assert_eq!(ObstacleMoments::new(&uniform).unwrap().node_count(), 27);
        let (g1, _) = ObstacleMoments::new(&uniform).unwrap().at(&x, t);
        assert!(g1.is_finite());
    }

    /// An open scene with two small disks is feasible, with a path from start to goal.
    #[test]
    fn open_scene_is_feasible() {
        let p = |n: &str| ParamSpec { name: n.into(), dist: Dist::Normal { mean: 0.0, std: 1.0 } };
        let g = scene(
            vec![
                ball("a", vec![100.5, -49.3], Unc { base: 0.1, scale: 0.01, param: Some(0) }, vec![p("a")]),
                ball("b", vec![100.3, -49.8], Unc { base: 0.08, scale: 0.01, param: Some(0) }, vec![p("b")]),
            ],
            0.05,
        );
        let r = judge(&g, &OracleOptions::default()).unwrap();
        let Judgement::Feasible { path } = r.judgement else { panic!("{:?}", r.judgement) };
        assert_eq!(path.first().map(|w| &w.x), Some(&g.start));
        assert_eq!(path.last().map(|w| &w.x), Some(&g.goal));
        // moving version: a disk sweeping across the middle
        let mut gm = g.clone();
        gm.obstacles[0].motion =
            Motion { kind: MotionKind::Linear, c0: vec![100.5, -49.5 - 3.5 * 0.6], v: vec![0.0, 0.6], a: vec![0.0; 2] };
        gm.obstacles[0].motion.c0[1] -= 0.3;
        let r = judge(&gm, &OracleOptions::default()).unwrap();
        assert!(matches!(r.judgement, Judgement::Feasible { .. }), "{:?}", r.judgement);
    }

    /// A wall whose gaps are closed only by the radius uncertainty (E[P] < 0 in the
    /// gaps, but the Cantelli level there is far above Δ) is infeasible: this test
    /// depends on the (1 − Δ) factor of the contour, not only on the sign of E[P].
    #[test]
    fn uncertain_wall_is_infeasible() {
        let mut obstacles = vec![];
        for k in 0..6 {
            let y = -50.0 + 0.2 * k as f64;
            let name = format!("w{k}");
            obstacles.push(ball(
                &name,
                vec![100.5, y],
                Unc { base: 0.09, scale: 0.03, param: Some(0) },
                vec![ParamSpec { name: name.clone(), dist: Dist::Uniform { low: -1.0, high: 1.0 } }],
            ));
        }
        let g = scene(obstacles, 0.05);
        // in a gap E[P] < 0: the mean wall does not touch
        let gap = [100.5, -49.9];
        let om = ObstacleMoments::new(&g.obstacles[0]).unwrap();
        assert!(om.at(&gap, 3.5).0 < 0.0);
        let r = judge(&g, &OracleOptions::default()).unwrap();
        assert_eq!(r.judgement, Judgement::Infeasible { reason: InfeasibleReason::Disconnected });
        // start inside a disk: endpoint reason
        let mut g2 = g.clone();
        g2.start = vec![100.5, -49.6];
        let r = judge(&g2, &OracleOptions::default()).unwrap();
        assert!(matches!(r.judgement, Judgement::Infeasible { reason: InfeasibleReason::EndpointUnsafe { .. } }));
        // out of reach
        let mut g3 = scene(vec![], 0.05);
        g3.max_speed = Some(0.5);
        let r = judge(&g3, &OracleOptions::default()).unwrap();
        assert!(matches!(r.judgement, Judgement::Infeasible { reason: InfeasibleReason::OutOfReach { .. } }));
    }

    /// Hand-made scenes the oracle cannot judge are refused with a message (no panic,
    /// no unbounded grid), and a quantity's missing parameter evaluates to NaN.
    #[test]
    fn malformed_scenes_are_refused() {
        let p = || vec![ParamSpec { name: "r".into(), dist: Dist::Uniform { low: 0.1, high: 0.2 } }];
        let good = ball("d", vec![100.5, -49.5], Unc { base: 0.0, scale: 1.0, param: Some(0) }, p());
        let mut cases: Vec<GeneratedScene> = vec![];
        let mut g = scene(vec![good.clone()], 0.05);
        g.dim = 4;
        g.lower.extend([0.0, 0.0]);
        g.upper.extend([1.0, 1.0]);
        g.start.extend([0.5, 0.5]);
        g.goal.extend([0.5, 0.5]);
        cases.push(g);
        let mut g = scene(vec![good.clone()], 0.05);
        g.upper[0] = f64::INFINITY;
        cases.push(g);
        let mut g = scene(vec![good.clone()], 0.05);
        g.max_speed = Some(-1.0);
        cases.push(g);
        let mut o = good.clone();
        o.motion.v = vec![0.0];
        cases.push(scene(vec![o], 0.05));
        let mut o = good.clone();
        o.params.clear();
        cases.push(scene(vec![o], 0.05));
        let mut o = good.clone();
        o.shape = Shape::Ellipsoid { size: Unc::fixed(1.0), inv_sq: vec![1.0], rot: (1.0, 0.0), offset: vec![] };
        cases.push(scene(vec![o], 0.05));
        for g in cases {
            assert!(matches!(judge(&g, &OracleOptions::default()), Err(OracleError::BadScene(_))), "{g:?}");
        }
        assert!(good.eval(&[100.5, -49.5], 3.5, &[]).is_nan());
        // zero denominators are not the moments of a distribution
        let o = ball(
            "m",
            vec![100.5, -49.5],
            Unc { base: 0.1, scale: 0.01, param: Some(0) },
            vec![ParamSpec { name: "m".into(), dist: Dist::moments_of_uniform(3, 3, 20) }],
        );
        assert!(matches!(ObstacleMoments::new(&o), Err(OracleError::Quadrature { .. })));
    }
}
