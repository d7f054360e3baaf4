//! The serde shape of scene format v1 (`docs/formats.md`). Unknown
//! fields are errors: they are probably typos.

use super::num::Num;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The only scene format this version reads.
pub const SCENE_FORMAT: &str = "riskplan-scene/1";

/// A scene, scene format v1 (docs/formats.md); unknown fields are errors. Limits: dim ≤ 8,
/// degree ≤ 8 in (x, t) and per parameter, ≤ 500 terms per obstacle, ≤ 512 obstacles, and
/// the expansion and contour-work limits of docs/formats.md §1.7.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// `riskplan-scene/1`.
    #[schemars(extend("const" = SCENE_FORMAT))]
    pub format: String,
    /// Scene name.
    pub name: String,
    /// One line of description.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Spatial dimension (1 to 8).
    #[schemars(range(min = 1, max = crate::MAX_DIM))]
    pub dim: usize,
    /// The workspace box.
    pub workspace: WorkspaceFile,
    /// `[t0, tf]`.
    #[schemars(length(equal = 2))]
    pub horizon: Vec<Num>,
    /// Δ in (0, 1): the bound on the probability of collision with each obstacle at every
    /// instant.
    pub risk: Num,
    /// Δ levels of a contour figure.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub risk_levels: Option<Vec<Num>>,
    /// Uncertain parameters by name (every identifier of a polynomial other than x1..x{dim}
    /// and t).
    #[serde(default)]
    #[schemars(extend("propertyNames" = { "pattern": PARAM_NAME_PATTERN }))]
    pub params: BTreeMap<String, ParamFile>,
    /// Obstacles (at most 512).
    #[schemars(length(max = crate::MAX_OBSTACLES))]
    pub obstacles: Vec<ObstacleFile>,
    /// x(t0); absent in contour-only scenes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1, max = crate::MAX_DIM))]
    pub start: Option<Vec<Num>>,
    /// x(tf); absent in contour-only scenes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1, max = crate::MAX_DIM))]
    pub goal: Option<Vec<Num>>,
    /// The robot's body: the radius of the disk/ball around its reference point (≥ 0, below
    /// half the workspace's smallest side; default 0, a point robot). Every obstacle is
    /// grown by it (docs/design.md §3.12).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_radius: Option<Num>,
    /// Planner options and the paper's planner parameters (§1.6); strict.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planner: Option<PlannerBlock>,
    /// Free-form: what the paper reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expected: Option<serde_json::Value>,
    /// Paper-versus-code notes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<Vec<String>>,
}

/// The workspace box: `{"lower": [...], "upper": [...]}`.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceFile {
    /// Lower corner.
    #[schemars(length(min = 1, max = crate::MAX_DIM))]
    pub lower: Vec<Num>,
    /// Upper corner.
    #[schemars(length(min = 1, max = crate::MAX_DIM))]
    pub upper: Vec<Num>,
}

/// The names of a scene's parameters: identifiers.
pub const PARAM_NAME_PATTERN: &str = "^[A-Za-z_][A-Za-z0-9_]*$";

/// One obstacle: `{x : poly >= 0}`, or a pedestrian template (exactly one of the two).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(extend("oneOf" = [{ "required": ["poly"] }, { "required": ["pedestrian"] }]))]
pub struct ObstacleFile {
    /// An obstacle id, unique in its scene (it is also a key-expression chunk in
    /// `riskplan/scenes/<scene>/obstacles/<id>`, so it should avoid / * $ ? #).
    #[schemars(length(min = 1))]
    pub id: String,
    /// Polynomial text: numbers (0.3, 1e-3, 37/300), identifiers (x1..x{dim}, t,
    /// parameters), + - * ^, parentheses, unary minus; ^ takes a non-negative integer
    /// literal; / divides by a numeric constant only. The obstacle is the set where
    /// poly >= 0. Empty (absent) for a pedestrian.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub poly: String,
    /// A pedestrian (docs/formats.md §1.5.1) instead of a polynomial.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pedestrian: Option<PedestrianFile>,
}

fn zero() -> Num {
    Num(num_traits::Zero::zero())
}
fn one() -> Num {
    Num(num_traits::One::one())
}

/// A parameter distribution, tagged by `dist`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(tag = "dist", rename_all = "lowercase", deny_unknown_fields)]
pub enum ParamFile {
    /// `uniform`: `low`, `high`.
    Uniform {
        /// Lower end.
        low: Num,
        /// Upper end.
        high: Num,
    },
    /// `normal`: `mean`, `std`.
    Normal {
        /// Mean.
        mean: Num,
        /// Standard deviation.
        std: Num,
    },
    /// `beta`: `alpha`, `beta`, optional `low` (0) and `high` (1).
    Beta {
        /// α.
        alpha: Num,
        /// β.
        beta: Num,
        /// Lower end of the support.
        #[serde(default = "zero")]
        low: Num,
        /// Upper end of the support.
        #[serde(default = "one")]
        high: Num,
    },
    /// `gamma`: `shape`, `scale`.
    Gamma {
        /// κ.
        shape: Num,
        /// θ.
        scale: Num,
    },
    /// `exponential`: `rate`.
    Exponential {
        /// λ.
        rate: Num,
    },
    /// `laplace`: `mean`, `scale`.
    Laplace {
        /// μ.
        mean: Num,
        /// b.
        scale: Num,
    },
    /// `discrete`: `values`, `weights`.
    Discrete {
        /// Support points.
        values: Vec<Num>,
        /// Probabilities.
        weights: Vec<Num>,
    },
    /// `moments`: `raw` = E\[w\], E\[w²\], ...
    Moments {
        /// Raw moments from order 1.
        raw: Vec<Num>,
    },
}

impl ParamFile {
    /// The exact distribution (not yet validated).
    pub fn to_distribution(&self) -> riskplan_math::moments::Distribution {
        use riskplan_math::moments::Distribution as D;
        let r = |n: &Num| n.0.clone();
        let rs = |v: &[Num]| v.iter().map(r).collect();
        match self {
            ParamFile::Uniform { low, high } => D::Uniform { low: r(low), high: r(high) },
            ParamFile::Normal { mean, std } => D::Normal { mean: r(mean), std: r(std) },
            ParamFile::Beta { alpha, beta, low, high } => {
                D::Beta { alpha: r(alpha), beta: r(beta), low: r(low), high: r(high) }
            }
            ParamFile::Gamma { shape, scale } => D::Gamma { shape: r(shape), scale: r(scale) },
            ParamFile::Exponential { rate } => D::Exponential { rate: r(rate) },
            ParamFile::Laplace { mean, scale } => D::Laplace { mean: r(mean), scale: r(scale) },
            ParamFile::Discrete { values, weights } => D::Discrete { values: rs(values), weights: rs(weights) },
            ParamFile::Moments { raw } => D::Moments { raw: rs(raw) },
        }
    }
}

/// The scene's `planner` block (docs/formats.md §1.6): options every planner honours
/// (`max_speed`, `max_accel`) and the parameters of each of the paper's planners, as
/// the reference scenes record them. Strict: a misspelt key is an error.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlannerBlock {
    /// Speed limit (workspace units per time unit), > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_speed: Option<f64>,
    /// Acceleration limit used when smoothing corners, > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_accel: Option<f64>,
    /// Which risk bounds may prove safety when a request does not say: `auto` (the
    /// tightest sound one, the default) or `cantelli` (the paper's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bound: Option<riskplan_math::contour::BoundChoice>,
    /// The paper's RRT-SOS parameters (read by `rrt-sos-paper`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rrt_sos: Option<RrtSosBlock>,
    /// The paper's time-varying SOS parameters (recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_varying_sos: Option<TimeVaryingSosBlock>,
    /// The paper's standard SOS (moment) parameters (recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub standard_sos: Option<StandardSosBlock>,
    /// The paper's Monte Carlo RRT baseline parameters (recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub monte_carlo_rrt: Option<MonteCarloRrtBlock>,
}

/// `planner.rrt_sos.width`: stripe half-widths, as a MATLAB range or a list.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WidthBlock {
    /// First half-width.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
    /// Increment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step: Option<f64>,
    /// Last half-width (inclusive).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop: Option<f64>,
    /// The half-widths as a list (wins over the range).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub values: Option<Vec<f64>>,
    /// How many entries of the range the authors' code reaches.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub used_entries: Option<usize>,
}

/// A box `{lower, upper}` as the authors' scripts give it (recorded).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BoxBlock {
    /// Lower corner.
    pub lower: Vec<f64>,
    /// Upper corner.
    pub upper: Vec<f64>,
}

/// `planner.rrt_sos`.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RrtSosBlock {
    /// Where the values come from (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// `static` or `dynamic (layered)` (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub variant: Option<String>,
    /// A remark (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    /// Steering step `rlim` (> 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rlim: Option<f64>,
    /// Pieces of the layered planner (≥ 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pieces: Option<usize>,
    /// Stripe half-widths.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<WidthBlock>,
    /// Accepted vertices per stripe.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples_per_stripe: Option<usize>,
    /// Iterations per stripe (layered).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iter_per_stripe: Option<usize>,
    /// Vertices at which a layer stops (layered).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_vertices_per_layer: Option<usize>,
    /// Iterations per layer (layered).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations_per_layer: Option<usize>,
    /// The authors' improve flag (0 or 1; recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub improve_rrt: Option<u8>,
    /// Degree of the authors' SOS multipliers (recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sos_multiplier_degree_d: Option<u32>,
    /// The authors' seed (recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub random_seed: Option<u64>,
    /// The authors' sampling box (recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bd: Option<BoxBlock>,
    /// How edges are timed (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge_time: Option<String>,
    /// Obstacles the authors' script constrains (recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obstacles_constrained: Option<Vec<String>>,
}

/// `planner.time_varying_sos` (recorded from the authors' Julia code).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeVaryingSosBlock {
    /// Where the values come from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Pieces.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pieces: Option<usize>,
    /// Convex–concave iterations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// Relaxation degree.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub relaxation_degree: Option<u32>,
    /// The authors' seed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub random_seed: Option<u64>,
    /// Weight of the length term.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_weight: Option<f64>,
    /// Initial scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale_init: Option<f64>,
    /// Regularisation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reg: Option<f64>,
    /// Order of the risk contours in the authors' parameter file.
    #[serde(default, rename = "order_of_risk_contours_in_Parameters_txt", skip_serializing_if = "Option::is_none")]
    pub order_of_risk_contours_in_parameters_txt: Option<u32>,
    /// The authors' `edge_size`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge_size: Option<f64>,
    /// Box constraints (polynomial texts).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub box_constraints: Option<Vec<String>>,
    /// The heuristic (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heuristic: Option<String>,
    /// The authors' solver (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<String>,
    /// Obstacles the authors' script constrains.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obstacles_constrained: Option<Vec<String>>,
}

/// `planner.standard_sos` (recorded from the authors' MATLAB code).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StandardSosBlock {
    /// Where the values come from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Degree of the polynomial trajectory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polynomial_trajectory_degree: Option<u32>,
    /// Pieces of the piecewise-linear variant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub piecewise_linear_pieces: Option<usize>,
    /// GloptiPoly relaxation order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gloptipoly_order_d: Option<u32>,
    /// The risk formulation (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub risk: Option<String>,
    /// The objective (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objective: Option<String>,
    /// Time intervals of the piecewise-linear variant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub piecewise_linear_time_intervals: Option<Vec<serde_json::Value>>,
    /// Solutions the authors extracted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extracted_solutions: Option<u32>,
}

/// `planner.monte_carlo_rrt` (recorded).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MonteCarloRrtBlock {
    /// Scenarios per edge.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty_samples: Option<u64>,
    /// Waypoints per edge.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub waypoints_per_edge: Option<usize>,
    /// The authors' code (free text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub code: Option<String>,
}

/// A pedestrian (docs/formats.md §1.5.1): a moving disk/ball predicted at `time` with
/// isotropic Gaussian errors of position and velocity and a radius with a bounded support;
/// certified by its Gaussian tail bound (docs/design.md §3.11).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PedestrianFile {
    /// Predicted (nominal) centre at `time`.
    #[schemars(length(min = 1, max = crate::MAX_DIM))]
    pub position: Vec<Num>,
    /// Predicted (nominal) velocity.
    #[schemars(length(min = 1, max = crate::MAX_DIM))]
    pub velocity: Vec<Num>,
    /// The time of the prediction (`t_ref`).
    pub time: Num,
    /// The radius: a number, or a distribution with a bounded support (`uniform`,
    /// `beta`, `discrete`).
    pub radius: RadiusFile,
    /// Standard deviation of each coordinate of the position error at `time` (≥ 0;
    /// default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_std: Option<Num>,
    /// Standard deviation of each coordinate of the velocity error (≥ 0; default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_std: Option<Num>,
}

/// A pedestrian's radius: fixed, or a distribution with a bounded support.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq, JsonSchema)]
#[serde(untagged)]
pub enum RadiusFile {
    /// A fixed radius.
    Fixed(Num),
    /// A random radius.
    Random(ParamFile),
}
