//! Scenes: format v1 parsing, validation, and the per-obstacle contour cache (L2).
//!
//! [`Scene::from_json`] reads scene text (callers do the file I/O), checks every
//! field, and builds each obstacle's [`RiskContour`] once. A bad scene yields one
//! [`SceneError`] naming the field (`params.w.std`, `obstacles[2].poly`) and what is
//! wrong; nothing panics on any input.
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan-certify`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan_certify::checker::SceneKernel;
//! ```

mod closed_set;
mod file;
pub mod motion;
mod num;
mod pedestrian;
mod trajectory;

pub use closed_set::WireName;
pub use file::{
    BoxBlock, MonteCarloRrtBlock, ObstacleFile, ParamFile, PedestrianFile, PlannerBlock, RadiusFile, RrtSosBlock,
    SceneFile, StandardSosBlock, TimeVaryingSosBlock, WidthBlock, WorkspaceFile, PARAM_NAME_PATTERN, SCENE_FORMAT,
};
pub use num::{parse_num_text, Num, NUM_TEXT_PATTERN};
pub use pedestrian::{Pedestrian, MAX_PEDESTRIAN_MAGNITUDE};
pub use trajectory::{
    Piece, Trajectory, TrajectoryError, TrajectoryFile, CONTINUITY_TOLERANCE, MAX_PIECES, MAX_PIECE_DEGREE,
    TRAJECTORY_FORMAT,
};

/// What [`closed_set!`] expands to names (not an API).
#[doc(hidden)]
pub mod __private {
    pub use schemars;
    pub use serde;
}

use num_rational::BigRational;
use num_traits::{Signed, Zero};
use riskplan_math::contour::{ContourError, Layout, RiskContour, RiskLevel, RiskLevelError};
use riskplan_math::mc::McModel;
use riskplan_math::moments::{Distribution, MomentError};
use riskplan_math::poly::{parse_with_budget, rational_to_f64, QPoly, Var, VarTable};
use std::collections::BTreeMap;
use std::sync::Arc;
use thiserror::Error;

/// Largest spatial dimension accepted.
pub const MAX_DIM: usize = 8;
/// Largest total degree of an obstacle polynomial in (x, t). E\[P²\] has twice this
/// degree; 8 keeps every certification polynomial at degree ≤ 16 for segments.
pub const MAX_OBSTACLE_DEGREE: u32 = 8;
/// Largest degree of an obstacle polynomial in one parameter (moments to twice this).
pub const MAX_PARAM_DEGREE: u32 = 8;
/// Largest number of terms of an obstacle polynomial after expansion. Building E\[P²\]
/// costs one exact product per pair of terms (`terms²`): 462 terms took 0.4 s; the
/// 1287 terms of `(x1+x2+x3+t+w+1)^8` took 2.3 s.
pub const MAX_TERMS: usize = 500;
/// Budget of the whole scene's contour construction, Σ over obstacles of `terms²`
/// (the products that E\[P²\] needs): measured at about 2 µs a product, so at most about
/// half a second of exact arithmetic, and a scene cannot hold a server's worker for
/// long (fuzzing counts an input that takes over a second as a hang). The paper's
/// largest scene needs under 2 000.
pub const MAX_CONTOUR_WORK: usize = 250_000;
/// Budget of term products for expanding all of a scene's obstacle texts together
/// (`poly::parse_with_budget`); with [`MAX_CONTOUR_WORK`] it bounds the exact
/// arithmetic a scene can ask for, however many obstacles it lists.
pub const MAX_SCENE_PARSE_WORK: usize = 100_000;
/// Largest number of obstacles in a scene.
pub const MAX_OBSTACLES: usize = 512;

/// What is wrong with a scene.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SceneErrorKind {
    /// Not valid JSON, a wrong type, a missing or an unknown field.
    #[error("{0}")]
    Syntax(String),
    /// A value outside its domain.
    #[error("{0}")]
    Invalid(String),
    /// Polynomial text that does not parse.
    #[error("{0}")]
    Poly(#[from] riskplan_math::poly::PolyError),
    /// A distribution whose moments cannot be computed.
    #[error("{0}")]
    Moment(#[from] MomentError),
    /// A contour that cannot be built.
    #[error("{0}")]
    Contour(#[from] ContourError),
}

/// A scene error: the field path and what is wrong with it.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{}{kind}", if path.is_empty() { String::new() } else { format!("{path}: ") })]
pub struct SceneError {
    /// Path of the offending field, e.g. `params.w.std` (empty for the whole file).
    pub path: String,
    /// What is wrong.
    pub kind: SceneErrorKind,
}

fn err(path: impl Into<String>, msg: impl Into<String>) -> SceneError {
    SceneError { path: path.into(), kind: SceneErrorKind::Invalid(msg.into()) }
}

/// The workspace box, exact and in floats.
#[derive(Clone, Debug, PartialEq)]
pub struct Workspace {
    /// Lower corner.
    pub lower: Vec<f64>,
    /// Upper corner.
    pub upper: Vec<f64>,
}

impl Workspace {
    /// Whether `x` lies in the closed box.
    pub fn contains(&self, x: &[f64]) -> bool {
        x.len() == self.lower.len()
            && x.iter().zip(self.lower.iter().zip(&self.upper)).all(|(v, (l, u))| l <= v && v <= u)
    }
}

/// An uncertain parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct Param {
    /// Name in the polynomials.
    pub name: String,
    /// Its variable.
    pub var: Var,
    /// Its distribution (validated).
    pub dist: Distribution,
}

/// An obstacle `{x : P(x, ω, t) ≥ 0}` with its cached contour.
#[derive(Clone, Debug)]
pub struct Obstacle {
    /// Unique id.
    pub id: String,
    /// The polynomial text as given (empty for a pedestrian).
    pub text: String,
    /// P(x, ω, t), exact: in the scene's variables, or for a pedestrian in its own
    /// (`x1..xn, t`, then [`Obstacle::own_params`]; built on first use).
    pub poly: ObstaclePoly,
    /// E\[P\], E\[P²\], built once (eqs. 10/12): at once for a polynomial obstacle, on
    /// first use for a pedestrian.
    pub contour: ContourCell,
    /// The pedestrian template this obstacle was made from, if any (docs/design.md §3.11).
    pub pedestrian: Option<Arc<Pedestrian>>,
    /// With a robot body (docs/design.md §3.12): the polynomial before it was grown (in
    /// the same variables as `poly`, which is then the grown one), for the Monte Carlo
    /// audit of body contact; `None` without a body (and for a pedestrian, which keeps
    /// its own: [`Obstacle::contact_poly`]).
    pub original: Option<Arc<QPoly>>,
}

/// An obstacle's polynomial: as parsed, or a pedestrian's, built on first use.
/// Dereferences to the [`QPoly`].
#[derive(Clone, Debug)]
pub enum ObstaclePoly {
    /// Parsed (and grown).
    Ready(Arc<QPoly>),
    /// A pedestrian's.
    Pedestrian(Arc<Pedestrian>),
}

impl std::ops::Deref for ObstaclePoly {
    type Target = QPoly;
    fn deref(&self) -> &QPoly {
        match self {
            ObstaclePoly::Ready(p) => p,
            ObstaclePoly::Pedestrian(p) => p.poly(),
        }
    }
}

impl Obstacle {
    /// The obstacle itself, not grown by the body: what contact means (the Monte Carlo
    /// audit samples the body against it).
    pub fn contact_poly(&self) -> &QPoly {
        match (&self.pedestrian, &self.original) {
            (Some(p), _) => p.original_poly(),
            (None, Some(o)) => o,
            (None, None) => &self.poly,
        }
    }

    /// The parameters that are this obstacle's own (a pedestrian's), with variables of
    /// its polynomial; empty for a polynomial obstacle (its parameters are the scene's).
    pub fn own_params(&self) -> &[Param] {
        self.pedestrian.as_ref().map_or(&[], |p| &p.params)
    }

    /// Whether the obstacle moves.
    pub fn is_dynamic(&self) -> bool {
        match &self.pedestrian {
            Some(p) => p.disk.sigma_v > 0.0 || p.disk.velocity.iter().any(|v| v.lo != 0.0 || v.hi != 0.0),
            None => self.contour.is_dynamic(),
        }
    }
}

/// An obstacle's contour: built, or built on first use (a pedestrian's: most plans never
/// need it). Dereferences to the [`RiskContour`]; clones share it.
#[derive(Clone)]
pub struct ContourCell(Arc<CellInner>);

enum CellInner {
    Ready(Arc<RiskContour>),
    Lazy { cell: std::sync::OnceLock<Arc<RiskContour>>, pedestrian: Arc<Pedestrian>, dim: usize },
}

impl ContourCell {
    /// A contour already built.
    pub fn ready(c: Arc<RiskContour>) -> ContourCell {
        ContourCell(Arc::new(CellInner::Ready(c)))
    }

    /// A pedestrian's contour, built on first use.
    pub fn pedestrian(pedestrian: Arc<Pedestrian>, dim: usize) -> ContourCell {
        ContourCell(Arc::new(CellInner::Lazy { cell: std::sync::OnceLock::new(), pedestrian, dim }))
    }

    /// The contour (built now if it was not).
    pub fn get(&self) -> &Arc<RiskContour> {
        match &*self.0 {
            CellInner::Ready(c) => c,
            CellInner::Lazy { cell, pedestrian, dim } => cell.get_or_init(|| Arc::new(pedestrian.contour(*dim))),
        }
    }

    /// An identity of this contour: equal for clones (a contour taken unchanged into the
    /// next revision of a scene), different for contours built apart.
    pub fn key(&self) -> usize {
        match &*self.0 {
            CellInner::Ready(c) => Arc::as_ptr(c) as usize,
            CellInner::Lazy { .. } => Arc::as_ptr(&self.0) as *const () as usize,
        }
    }

    /// Whether it has been built.
    pub fn is_built(&self) -> bool {
        match &*self.0 {
            CellInner::Ready(_) => true,
            CellInner::Lazy { cell, .. } => cell.get().is_some(),
        }
    }

    /// The contour if built (never builds).
    pub fn peek(&self) -> Option<&Arc<RiskContour>> {
        match &*self.0 {
            CellInner::Ready(c) => Some(c),
            CellInner::Lazy { cell, .. } => cell.get(),
        }
    }
}

impl std::ops::Deref for ContourCell {
    type Target = RiskContour;
    fn deref(&self) -> &RiskContour {
        self.get()
    }
}

impl std::fmt::Debug for ContourCell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.peek() {
            Some(c) => c.fmt(f),
            None => f.write_str("ContourCell(not built)"),
        }
    }
}

/// A validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Name.
    pub name: String,
    /// Spatial dimension.
    pub dim: usize,
    /// Workspace box.
    pub workspace: Workspace,
    /// `[t0, tf]`.
    pub horizon: (f64, f64),
    /// Δ, exact.
    pub risk: RiskLevel,
    /// Levels for contour figures (`risk_levels`, else `[risk]`).
    pub risk_levels: Vec<RiskLevel>,
    /// Parameters, in variable order.
    pub params: Vec<Param>,
    /// Obstacles, in file order.
    pub obstacles: Vec<Obstacle>,
    /// x(t0), if given.
    pub start: Option<Vec<f64>>,
    /// x(tf), if given.
    pub goal: Option<Vec<f64>>,
    /// Variable names: `x1..xn, t, params...`.
    pub vars: VarTable,
    /// The file as read (for re-serialising and for free-form blocks).
    pub file: SceneFile,
    /// The robot's body radius (`robot_radius`, 0 for a point robot), exact; every
    /// obstacle is grown by it (docs/design.md §3.12).
    pub body: BigRational,
}

impl Scene {
    /// Parses and validates scene JSON text.
    pub fn from_json(text: &str) -> Result<Scene, SceneError> {
        Scene::from_json_cached(text, &ContourCache::default())
    }

    /// [`Scene::from_json`] with contours shared through `cache` (see [`Scene::from_file_cached`]).
    pub fn from_json_cached(text: &str, cache: &ContourCache) -> Result<Scene, SceneError> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let file: SceneFile = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            SceneError {
                path: if path == "." { String::new() } else { path },
                kind: SceneErrorKind::Syntax(e.into_inner().to_string()),
            }
        })?;
        Scene::from_file_cached(file, cache)
    }

    /// Validates a parsed scene file.
    pub fn from_file(file: SceneFile) -> Result<Scene, SceneError> {
        Scene::from_file_cached(file, &ContourCache::default())
    }

    /// Validates a parsed scene file, taking each obstacle's contour from `cache` when
    /// the same polynomial with the same parameter distributions was built before
    /// (and adding the ones built now). A scene update that moves one obstacle thus
    /// rebuilds only that obstacle's E\[P\] and E\[P²\].
    pub fn from_file_cached(file: SceneFile, cache: &ContourCache) -> Result<Scene, SceneError> {
        Scene::from_file_reusing(file, cache, None)
    }

    /// [`Scene::from_file_cached`], taking every pedestrian whose template is unchanged
    /// (same id, same fields) from `previous` as it is — with its contour if one was built
    /// — so that an update of some pedestrians costs only theirs (docs/design.md §3.11).
    pub fn from_file_reusing(
        file: SceneFile,
        cache: &ContourCache,
        previous: Option<&Scene>,
    ) -> Result<Scene, SceneError> {
        if file.format != SCENE_FORMAT {
            return Err(err("format", format!("must be \"{SCENE_FORMAT}\", got \"{}\"", file.format)));
        }
        let dim = file.dim;
        if dim == 0 || dim > MAX_DIM {
            return Err(err("dim", format!("must be between 1 and {MAX_DIM}, got {dim}")));
        }
        let workspace = validate_workspace(&file.workspace, dim)?;
        let horizon = validate_horizon(&file.horizon)?;
        let risk = validate_risk("risk", &file.risk)?;
        let risk_levels = match &file.risk_levels {
            Some(levels) => levels
                .iter()
                .enumerate()
                .map(|(i, d)| validate_risk(&format!("risk_levels[{i}]"), d))
                .collect::<Result<_, _>>()?,
            None => vec![risk.clone()],
        };
        let (vars, params) = validate_params(&file, dim)?;
        let layout = Layout { dim };
        let body = validate_body(&file, &workspace)?;
        let previous = previous.filter(|p| p.body == body);
        let parsed = parse_obstacles(&file, &vars, dim, previous)?;
        // grown by the body (docs/design.md §3.12): (grown, original)
        let parsed = grow_obstacles(parsed, &body, &vars, &params, &workspace, horizon)?;
        // each variable's largest degree over the obstacles' polynomials (formed once: the
        // moments of a parameter serve every obstacle it occurs in)
        let mut degrees: BTreeMap<Var, u32> = BTreeMap::new();
        for p in &parsed {
            if let Parsed::Poly(q, _) = p {
                q.max_exponents_into(&mut degrees);
            }
        }
        // the moments are computed only when a contour is not in the cache, and only for
        // its parameters: a scene revision whose obstacles are all cached (an update of
        // one deterministic obstacle, a replica installing its primary's commit) needs
        // none — exact moments are costly, and a scene of 512 uncertain disks has 1024
        // parameters of which an update of one obstacle needs two
        let mut moments: BTreeMap<Var, Vec<BigRational>> = BTreeMap::new();
        let supports: Vec<(Var, BigRational, BigRational)> =
            params.iter().filter_map(|p| p.dist.support().map(|(lo, hi)| (p.var, lo, hi))).collect();
        let laws: Vec<(Var, &riskplan_math::moments::Distribution)> = params.iter().map(|p| (p.var, &p.dist)).collect();
        let name = |v: Var| vars.name(v);
        let mut obstacles = Vec::with_capacity(parsed.len());
        for (i, (o, parsed)) in file.obstacles.iter().zip(parsed).enumerate() {
            let (poly, original) = match parsed {
                Parsed::Poly(q, original) => (q, original),
                Parsed::Reused(old) => {
                    obstacles.push(old);
                    continue;
                }
                Parsed::Pedestrian(p, original) => {
                    obstacles.push(Obstacle {
                        id: o.id.clone(),
                        text: String::new(),
                        poly: ObstaclePoly::Pedestrian(p.clone()),
                        contour: ContourCell::pedestrian(p.clone(), dim),
                        pedestrian: Some(p),
                        original,
                    });
                    continue;
                }
            };
            let mut key = ContourCache::key(dim, &o.poly, &poly, &file.params, &vars);
            if !body.is_zero() {
                key = format!("{key}|body={body}");
            }
            let contour = match cache.get(&key) {
                Some(c) => c,
                None => {
                    for v in poly.vars().into_iter().filter(|&v| layout.is_param(v)) {
                        if let (false, Some(p)) = (moments.contains_key(&v), params.iter().find(|p| p.var == v)) {
                            moments.insert(v, needed_moments(degrees.get(&v).copied().unwrap_or(0), p)?);
                        }
                    }
                    let moments = &moments;
                    let lookup = |v: Var, k: u32| moments.get(&v).and_then(|m| m.get(k as usize)).cloned();
                    let c = RiskContour::new(layout, &poly, &lookup, &name)
                        .map_err(|e| SceneError { path: format!("obstacles[{i}].poly"), kind: e.into() })?
                        .with_support(&supports)
                        .with_laws(&laws);
                    cache.insert(key, Arc::new(c))
                }
            };
            obstacles.push(Obstacle {
                id: o.id.clone(),
                text: o.poly.clone(),
                poly: ObstaclePoly::Ready(Arc::new(poly)),
                contour: ContourCell::ready(contour),
                pedestrian: None,
                original,
            });
        }
        if let Some(b) = &file.planner {
            validate_planner_block(b)?;
        }
        let start = validate_point("start", &file.start, &workspace)?;
        let goal = validate_point("goal", &file.goal, &workspace)?;
        if start.is_some() != goal.is_some() {
            return Err(err(if start.is_some() { "goal" } else { "start" }, "start and goal must be given together"));
        }
        Ok(Scene {
            name: file.name.clone(),
            dim,
            workspace,
            horizon,
            risk,
            risk_levels,
            params,
            obstacles,
            start,
            goal,
            vars,
            file,
            body,
        })
    }

    /// The same scene for a robot whose body has radius `rho` (a request's
    /// `robot_radius`, replacing the scene's): every obstacle grown by it
    /// (docs/design.md §3.12), contours shared through `cache`.
    pub fn with_body(&self, rho: f64, cache: &ContourCache) -> Result<Scene, SceneError> {
        let Some(r) = BigRational::from_float(rho) else {
            return Err(err("robot_radius", format!("must be a finite number ≥ 0, got {rho}")));
        };
        if r == self.body {
            return Ok(self.clone());
        }
        let mut file = self.file.clone();
        file.robot_radius = Some(Num(r));
        Scene::from_file_reusing(file, cache, Some(self))
    }

    /// The variable layout of this scene's polynomials.
    pub fn layout(&self) -> Layout {
        Layout { dim: self.dim }
    }

    /// Δ as `f64`.
    pub fn risk_f64(&self) -> f64 {
        self.risk.to_f64()
    }

    /// The obstacle with this id.
    pub fn obstacle(&self, id: &str) -> Option<&Obstacle> {
        self.obstacles.iter().find(|o| o.id == id)
    }

    /// The centre of the scene's space-time box: the workspace centre and the middle of
    /// the horizon (the origin of the compiled and Monte Carlo variables, docs/design.md §5.10).
    pub fn center(&self) -> Vec<f64> {
        let ws = &self.workspace;
        let mut c: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(l, u)| 0.5 * l + 0.5 * u).collect();
        c.push(0.5 * self.horizon.0 + 0.5 * self.horizon.1);
        c
    }

    /// A Monte Carlo model of the scene: parameters sampled jointly per scenario, so
    /// a parameter named by two obstacles is one random variable (docs/design.md §7.1).
    pub fn mc_model(&self) -> Result<McModel, SceneError> {
        let mut samplers = Vec::new();
        for p in &self.params {
            let s = p.dist.sampler().map_err(|e| SceneError { path: format!("params.{}", p.name), kind: e.into() })?;
            samplers.push((p.var, s));
        }
        let center = self.center();
        // a pedestrian's own parameters become variables after the scene's
        let mut nvars = self.vars.len();
        let mut polys = Vec::with_capacity(self.obstacles.len());
        for o in &self.obstacles {
            let own = o.own_params();
            // with a body: the obstacle itself, not grown (the model samples the body)
            let source = o.contact_poly();
            let poly = if own.is_empty() {
                source.clone()
            } else {
                let base = nvars;
                nvars += own.len();
                let map: Vec<(Var, Var)> = own.iter().enumerate().map(|(k, p)| (p.var, (base + k) as Var)).collect();
                for (k, p) in own.iter().enumerate() {
                    let s = p
                        .dist
                        .sampler()
                        .map_err(|e| SceneError { path: format!("obstacles.{}.pedestrian", o.id), kind: e.into() })?;
                    samplers.push(((base + k) as Var, s));
                }
                source.subst(&|v| map.iter().find(|m| m.0 == v).map(|m| riskplan_math::poly::Poly::var(m.1)))
            };
            polys.push(riskplan_math::poly::shift(&poly, &center).map_coeffs(rational_to_f64));
        }
        Ok(McModel::new(self.layout(), nvars, polys, samplers, center).with_body(rational_to_f64(&self.body)))
    }
}

/// The planner block's numbers: limits positive and finite, `rlim` and widths positive,
/// `pieces` between 1 and 1000 (docs/formats.md §1.6).
fn validate_planner_block(b: &PlannerBlock) -> Result<(), SceneError> {
    let positive = |path: &str, v: Option<f64>| match v {
        Some(x) if !(x > 0.0 && x.is_finite()) => Err(err(path, format!("must be a positive number, got {x}"))),
        _ => Ok(()),
    };
    positive("planner.max_speed", b.max_speed)?;
    positive("planner.max_accel", b.max_accel)?;
    if let Some(r) = &b.rrt_sos {
        positive("planner.rrt_sos.rlim", r.rlim)?;
        if let Some(p) = r.pieces {
            if !(1..=1000).contains(&p) {
                return Err(err("planner.rrt_sos.pieces", format!("must be between 1 and 1000, got {p}")));
            }
        }
        if let Some(w) = &r.width {
            for (k, v) in [("start", w.start), ("step", w.step), ("stop", w.stop)] {
                positive(&format!("planner.rrt_sos.width.{k}"), v)?;
            }
            for (i, v) in w.values.iter().flatten().enumerate() {
                positive(&format!("planner.rrt_sos.width.values[{i}]"), Some(*v))?;
            }
        }
        for (k, v) in [
            ("samples_per_stripe", r.samples_per_stripe),
            ("iter_per_stripe", r.iter_per_stripe),
            ("max_vertices_per_layer", r.max_vertices_per_layer),
            ("max_iterations_per_layer", r.max_iterations_per_layer),
        ] {
            if v == Some(0) {
                return Err(err(format!("planner.rrt_sos.{k}"), "must be ≥ 1"));
            }
        }
    }
    Ok(())
}

/// Contours by (dimension, polynomial text, distributions of its parameters), shared
/// between scene revisions. Counts hits and misses for the service's status.
#[derive(Debug, Default)]
pub struct ContourCache {
    map: std::sync::Mutex<std::collections::HashMap<String, Arc<RiskContour>>>,
    hits: std::sync::atomic::AtomicU64,
    misses: std::sync::atomic::AtomicU64,
}

impl ContourCache {
    fn key(dim: usize, text: &str, poly: &QPoly, params: &BTreeMap<String, ParamFile>, vars: &VarTable) -> String {
        let layout = Layout { dim };
        let used: Vec<String> = poly
            .vars()
            .into_iter()
            .filter(|&v| layout.is_param(v))
            .map(|v| {
                let n = vars.name(v);
                format!(
                    "{n}={}",
                    params.get(&n).map(|p| serde_json::to_string(p).unwrap_or_default()).unwrap_or_default()
                )
            })
            .collect();
        // the contour holds the moment bounds' central moments up to this order: a change of
        // the order is a different contour
        format!("{dim}|{text}|orders<={}|{}", riskplan_math::contour::bounds::MAX_MOMENT_ORDER, used.join(";"))
    }

    fn get(&self, key: &str) -> Option<Arc<RiskContour>> {
        let hit = self.map.lock().ok()?.get(key).cloned();
        let counter = if hit.is_some() { &self.hits } else { &self.misses };
        counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        hit
    }

    fn insert(&self, key: String, c: Arc<RiskContour>) -> Arc<RiskContour> {
        if let Ok(mut m) = self.map.lock() {
            m.insert(key, c.clone());
        }
        c
    }

    /// Keeps only the contours used by `scenes` (called after updates).
    pub fn retain_used<'a>(&self, scenes: impl IntoIterator<Item = &'a Scene>) {
        let live: Vec<*const RiskContour> = scenes
            .into_iter()
            .flat_map(|s| s.obstacles.iter().filter_map(|o| o.contour.peek().map(Arc::as_ptr)))
            .collect();
        if let Ok(mut m) = self.map.lock() {
            m.retain(|_, c| live.contains(&Arc::as_ptr(c)));
        }
    }

    /// (entries, hits, misses).
    pub fn stats(&self) -> (usize, u64, u64) {
        let entries = self.map.lock().map(|m| m.len()).unwrap_or(0);
        use std::sync::atomic::Ordering::Relaxed;
        (entries, self.hits.load(Relaxed), self.misses.load(Relaxed))
    }
}

fn validate_workspace(w: &WorkspaceFile, dim: usize) -> Result<Workspace, SceneError> {
    for (name, v) in [("lower", &w.lower), ("upper", &w.upper)] {
        if v.len() != dim {
            return Err(err(format!("workspace.{name}"), format!("must have {dim} entries (dim), got {}", v.len())));
        }
    }
    for i in 0..dim {
        if w.lower[i] >= w.upper[i] {
            return Err(err(
                format!("workspace.upper[{i}]"),
                format!("must be greater than workspace.lower[{i}] ({} ≥ {})", w.lower[i].f64(), w.upper[i].f64()),
            ));
        }
    }
    let (lower, upper): (Vec<f64>, Vec<f64>) =
        (w.lower.iter().map(Num::f64).collect(), w.upper.iter().map(Num::f64).collect());
    // every bound a finite float, every side of positive finite length in floats, and a
    // finite diagonal: tolerances are relative to the diagonal, and an infinite or
    // collapsed box would make them meaningless
    for i in 0..dim {
        let side = upper[i] - lower[i];
        if !(lower[i].is_finite() && upper[i].is_finite() && side > 0.0 && side.is_finite()) {
            return Err(err(
                format!("workspace.upper[{i}]"),
                format!(
                    "the bounds must be finite floats a positive, finite distance apart (got {} and {})",
                    lower[i], upper[i]
                ),
            ));
        }
    }
    if !lower.iter().zip(&upper).map(|(l, u)| (u - l) * (u - l)).sum::<f64>().sqrt().is_finite() {
        return Err(err("workspace", "the diagonal of the box must be a finite float"));
    }
    Ok(Workspace { lower, upper })
}

fn validate_horizon(h: &[Num]) -> Result<(f64, f64), SceneError> {
    if h.len() != 2 {
        return Err(err("horizon", format!("must be [t0, tf], got {} entries", h.len())));
    }
    if h[0] >= h[1] {
        return Err(err("horizon", format!("t0 must be less than tf, got [{}, {}]", h[0].f64(), h[1].f64())));
    }
    let (t0, t1) = (h[0].f64(), h[1].f64());
    if !(t0.is_finite() && t1.is_finite() && t0 < t1 && (t1 - t0).is_finite()) {
        return Err(err(
            "horizon",
            format!("t0 and tf must be finite floats with t0 < tf and a finite duration, got [{t0}, {t1}]"),
        ));
    }
    Ok((t0, t1))
}

/// Δ must lie in the open interval (0, 1).
pub fn validate_risk(path: &str, d: &Num) -> Result<RiskLevel, SceneError> {
    RiskLevel::new(d.0.clone()).map_err(|_| err(path, RiskLevelError(d.f64().to_string()).to_string()))
}

fn is_identifier(s: &str) -> bool {
    let mut c = s.chars();
    matches!(c.next(), Some(f) if f.is_alphabetic() || f == '_') && c.all(|ch| ch.is_alphanumeric() || ch == '_')
}

fn is_space_name(s: &str) -> bool {
    s.strip_prefix('x').is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
}

fn validate_params(file: &SceneFile, dim: usize) -> Result<(VarTable, Vec<Param>), SceneError> {
    let mut names: Vec<String> = (1..=dim).map(|i| format!("x{i}")).collect();
    names.push("t".into());
    let mut params = Vec::new();
    for (name, pf) in &file.params {
        let path = format!("params.{name}");
        if !is_identifier(name) {
            return Err(err(path, "a parameter name must be an identifier (letters, digits, '_')"));
        }
        if name == "t" || is_space_name(name) {
            return Err(err(path, format!("'{name}' is reserved for time or space variables")));
        }
        let dist = pf.to_distribution().validated().map_err(|e| moment_err(&path, e))?;
        names.push(name.clone());
        params.push(Param { name: name.clone(), var: (names.len() - 1) as Var, dist });
    }
    Ok((VarTable::new(names), params))
}

fn moment_err(path: &str, e: MomentError) -> SceneError {
    match e {
        MomentError::InvalidParameter { field, message } => err(format!("{path}.{field}"), message),
        other => SceneError { path: path.to_string(), kind: other.into() },
    }
}

/// One obstacle as parsed: a polynomial in the scene's variables, or a pedestrian (with
/// its contour cell when taken unchanged from the previous scene).
enum Parsed {
    /// A polynomial (grown by the body, with the original when there is one).
    Poly(QPoly, Option<Arc<QPoly>>),
    /// A new pedestrian (grown, with its original polynomial when there is a body).
    Pedestrian(Arc<Pedestrian>, Option<Arc<QPoly>>),
    /// An obstacle taken unchanged from the previous revision.
    Reused(Obstacle),
}

fn parse_obstacles(
    file: &SceneFile,
    vars: &VarTable,
    dim: usize,
    previous: Option<&Scene>,
) -> Result<Vec<Parsed>, SceneError> {
    if file.obstacles.len() > MAX_OBSTACLES {
        return Err(err("obstacles", format!("at most {MAX_OBSTACLES} obstacles, got {}", file.obstacles.len())));
    }
    let layout = Layout { dim };
    let mut seen = BTreeMap::new();
    let mut work = 0usize;
    let mut parse_budget = MAX_SCENE_PARSE_WORK;
    let mut out = Vec::new();
    for (i, o) in file.obstacles.iter().enumerate() {
        if o.id.trim().is_empty() {
            return Err(err(format!("obstacles[{i}].id"), "must not be empty"));
        }
        if let Some(j) = seen.insert(o.id.clone(), i) {
            return Err(err(format!("obstacles[{i}].id"), format!("'{}' is already the id of obstacles[{j}]", o.id)));
        }
        match (&o.pedestrian, o.poly.is_empty()) {
            (Some(pf), true) => {
                let reused = previous
                    .and_then(|s| s.obstacle(&o.id))
                    .filter(|old| old.pedestrian.as_ref().is_some_and(|p| p.file == *pf) && s_dim(previous) == dim);
                out.push(match reused {
                    Some(old) => Parsed::Reused(old.clone()),
                    None => Parsed::Pedestrian(
                        Arc::new(Pedestrian::new(pf, dim, &format!("obstacles[{i}].pedestrian"))?),
                        None,
                    ),
                });
                continue;
            }
            (Some(_), false) => {
                return Err(err(format!("obstacles[{i}]"), "give either 'poly' or 'pedestrian', not both"));
            }
            (None, true) => {
                return Err(err(format!("obstacles[{i}].poly"), "an obstacle needs 'poly' (or 'pedestrian')"))
            }
            (None, false) => {}
        }
        let path = format!("obstacles[{i}].poly");
        let mut resolve = |n: &str| -> Result<Var, String> {
            vars.get(n).ok_or_else(|| {
                if is_space_name(n) {
                    format!("'{n}' is not a space variable of this {dim}-D scene (x1..x{dim}) nor a declared parameter")
                } else {
                    format!("unknown identifier '{n}': declare it in params, or use x1..x{dim} or t")
                }
            })
        };
        let poly = parse_with_budget(&o.poly, &mut resolve, &mut parse_budget)
            .map_err(|e| SceneError { path: path.clone(), kind: e.into() })?;
        let deg_xt = poly.degree_in_vars(|v| !layout.is_param(v));
        if deg_xt > MAX_OBSTACLE_DEGREE {
            return Err(err(path, format!("degree {deg_xt} in (x, t) exceeds the limit {MAX_OBSTACLE_DEGREE}")));
        }
        if poly.len() > MAX_TERMS {
            return Err(err(path, format!("{} terms after expansion exceed the limit {MAX_TERMS}", poly.len())));
        }
        work += poly.len() * poly.len();
        if work > MAX_CONTOUR_WORK {
            return Err(err(
                path,
                format!(
                    "the contours of the obstacles up to this one need {work} exact term products (Σ terms²), over the limit {MAX_CONTOUR_WORK}"
                ),
            ));
        }
        for v in poly.vars().into_iter().filter(|&v| layout.is_param(v)) {
            let d = poly.degree_in(v);
            if d > MAX_PARAM_DEGREE {
                return Err(err(
                    path,
                    format!("degree {d} in '{}' exceeds the limit {MAX_PARAM_DEGREE}", vars.name(v)),
                ));
            }
        }
        out.push(Parsed::Poly(poly, None));
    }
    Ok(out)
}

/// `robot_radius`: a finite number ≥ 0 whose body fits the workspace (its diameter below
/// the smallest side).
fn validate_body(file: &SceneFile, ws: &Workspace) -> Result<BigRational, SceneError> {
    let Some(r) = &file.robot_radius else { return Ok(BigRational::zero()) };
    if r.0.is_negative() {
        return Err(err("robot_radius", format!("must be ≥ 0, got {}", r.f64())));
    }
    let side = ws.lower.iter().zip(&ws.upper).map(|(l, u)| u - l).fold(f64::INFINITY, f64::min);
    if 2.0 * r.f64() >= side || r.f64().is_nan() {
        return Err(err(
            "robot_radius",
            format!("a body of radius {} does not fit the workspace (smallest side {side})", r.f64()),
        ));
    }
    Ok(r.0.clone())
}

/// Points at which the body envelope takes the typical sizes of its terms: a grid over
/// the workspace at three times, the parameters at their means (docs/design.md §3.12).
fn envelope_samples(vars: &VarTable, params: &[Param], ws: &Workspace, horizon: (f64, f64)) -> Vec<Vec<f64>> {
    let dim = ws.lower.len();
    let per: usize = if dim <= 2 { 12 } else { 5 };
    let total = per.pow(dim as u32);
    let mut out = Vec::with_capacity(total * 3);
    let means: Vec<(Var, f64)> =
        params.iter().filter_map(|p| p.dist.mean().ok().map(|m| (p.var, rational_to_f64(&m)))).collect();
    for ti in 0..3 {
        let t = horizon.0 + (horizon.1 - horizon.0) * ti as f64 / 2.0;
        for k in 0..total {
            let mut v = vec![0.0; vars.len().max(dim + 1)];
            let mut r = k;
            for (d, slot) in v.iter_mut().enumerate().take(dim) {
                let i = r % per;
                r /= per;
                *slot = ws.lower[d] + (ws.upper[d] - ws.lower[d]) * (i as f64 + 0.5) / per as f64;
            }
            v[dim] = t;
            for &(var, m) in &means {
                if let Some(slot) = v.get_mut(var as usize) {
                    *slot = m;
                }
            }
            out.push(v);
        }
    }
    out
}

/// Grows every new obstacle by the body (nothing to do without one; docs/design.md §3.12).
fn grow_obstacles(
    parsed: Vec<Parsed>,
    body: &BigRational,
    vars: &VarTable,
    params: &[Param],
    ws: &Workspace,
    horizon: (f64, f64),
) -> Result<Vec<Parsed>, SceneError> {
    if body.is_zero() {
        return Ok(parsed);
    }
    let layout = Layout { dim: ws.lower.len() };
    let ranges: Vec<riskplan_math::poly::Interval> = (0..vars.len())
        .map(|v| {
            params.iter().find(|p| p.var as usize == v).and_then(|p| p.dist.support()).map_or(
                riskplan_math::poly::Interval::ENTIRE,
                |(lo, hi)| {
                    riskplan_math::poly::Interval::new(
                        riskplan_math::poly::Interval::enclose_rational(&lo).lo,
                        riskplan_math::poly::Interval::enclose_rational(&hi).hi,
                    )
                },
            )
        })
        .collect();
    let range = |v: Var| ranges.get(v as usize).copied().unwrap_or(riskplan_math::poly::Interval::ENTIRE);
    let samples = std::cell::OnceCell::new();
    // the limits of parsing hold for the grown polynomials too (their contours are built)
    let mut work = 0usize;
    parsed
        .into_iter()
        .enumerate()
        .map(|(i, p)| match p {
            Parsed::Poly(q, _) => {
                let samples = samples.get_or_init(|| envelope_samples(vars, params, ws, horizon));
                let path = format!("obstacles[{i}]");
                let g = riskplan_math::contour::grow::grow(&q, layout, body, &range, samples, (MAX_OBSTACLE_DEGREE, MAX_TERMS))
                    .map_err(|e| err(&path, format!("robot_radius: {e}")))?;
                work += g.poly.len() * g.poly.len();
                if work > MAX_CONTOUR_WORK {
                    return Err(err(
                        &path,
                        format!("robot_radius: the grown obstacles need {work} exact term products, over the limit {MAX_CONTOUR_WORK}"),
                    ));
                }
                for v in g.poly.vars().into_iter().filter(|&v| layout.is_param(v)) {
                    let d = g.poly.degree_in(v);
                    if d > MAX_PARAM_DEGREE {
                        return Err(err(
                            &path,
                            format!("robot_radius: grown, its degree {d} in '{}' exceeds the limit {MAX_PARAM_DEGREE}", vars.name(v)),
                        ));
                    }
                }
                Ok(Parsed::Poly(g.poly, Some(Arc::new(q))))
            }
            Parsed::Pedestrian(p, _) => Ok(Parsed::Pedestrian(Arc::new(p.grown(body)), None)),
            reused @ Parsed::Reused(_) => Ok(reused),
        })
        .collect::<Result<Vec<_>, _>>()
}

fn s_dim(s: Option<&Scene>) -> usize {
    s.map_or(0, |s| s.dim)
}

/// Raw moments of parameter `p` up to `2·max deg` over the obstacles (§2.1: E\[P²\]), and
/// beyond, as far as known, up to the moment bounds' highest order.
/// The raw moments of parameter `p` that the contours need, `deg` its largest degree in
/// the scene's obstacles.
fn needed_moments(deg: u32, p: &Param) -> Result<Vec<BigRational>, SceneError> {
    let k = 2 * deg;
    let mut m = p.dist.raw_moments(k).map_err(|e| moment_err(&format!("params.{}", p.name), e))?;
    if m.iter().skip(2).step_by(2).any(|x| x.is_negative()) {
        return Err(err(format!("params.{}", p.name), "even moments must be ≥ 0"));
    }
    // the higher orders of the moment bounds (docs/design.md §3.8), as far as they are
    // known: a moment list supports the orders it lists, and only if they are still a
    // moment sequence (Hankel check); the Cantelli contour needs only the first 2·deg
    let top = riskplan_math::contour::bounds::MAX_MOMENT_ORDER * deg;
    let known = match &p.dist {
        riskplan_math::moments::Distribution::Moments { raw } => (raw.len() as u32).min(top),
        _ => top,
    };
    if known > k {
        if let Ok(more) = p.dist.raw_moments(known) {
            if !more.iter().skip(2).step_by(2).any(|x| x.is_negative()) {
                m = more;
            }
        }
    }
    Ok(m)
}

fn validate_point(path: &str, p: &Option<Vec<Num>>, ws: &Workspace) -> Result<Option<Vec<f64>>, SceneError> {
    let Some(p) = p else { return Ok(None) };
    if p.len() != ws.lower.len() {
        return Err(err(path, format!("must have {} entries (dim), got {}", ws.lower.len(), p.len())));
    }
    let x: Vec<f64> = p.iter().map(Num::f64).collect();
    if !ws.contains(&x) {
        return Err(err(path, format!("{x:?} is outside the workspace {:?}..{:?}", ws.lower, ws.upper)));
    }
    Ok(Some(x))
}

#[cfg(test)]
mod tests;
