//! The serde shape of scene format v1 (`docs/formats.md`). Unknown
//! fields are errors: they are probably typos.

use super::num::Num;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The only scene format this version reads.
pub const SCENE_FORMAT: &str = "riskplan-scene/1";

/// A scene file as written.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Must be [`SCENE_FORMAT`].
    pub format: String,
    /// Scene name.
    pub name: String,
    /// One line of description.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Spatial dimension.
    pub dim: usize,
    /// The workspace box.
    pub workspace: WorkspaceFile,
    /// `[t0, tf]`.
    pub horizon: Vec<Num>,
    /// Δ.
    pub risk: Num,
    /// Δ levels of a contour figure.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub risk_levels: Option<Vec<Num>>,
    /// Uncertain parameters by name.
    #[serde(default)]
    pub params: BTreeMap<String, ParamFile>,
    /// Obstacles.
    pub obstacles: Vec<ObstacleFile>,
    /// x(t0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<Vec<Num>>,
    /// x(tf).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<Vec<Num>>,
    /// Free-form planner parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planner: Option<serde_json::Value>,
    /// Free-form: what the paper reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expected: Option<serde_json::Value>,
    /// Paper-versus-code notes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<Vec<String>>,
}

/// `{"lower": [...], "upper": [...]}`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceFile {
    /// Lower corner.
    pub lower: Vec<Num>,
    /// Upper corner.
    pub upper: Vec<Num>,
}

/// One obstacle: `{x : poly >= 0}`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ObstacleFile {
    /// Unique id.
    pub id: String,
    /// Polynomial text.
    pub poly: String,
}

fn zero() -> Num {
    Num(num_traits::Zero::zero())
}
fn one() -> Num {
    Num(num_traits::One::one())
}

/// A parameter distribution, tagged by `dist`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
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
    /// `moments`: `raw` = E[w], E[w²], ...
    Moments {
        /// Raw moments from order 1.
        raw: Vec<Num>,
    },
}

impl ParamFile {
    /// The exact distribution (not yet validated).
    pub fn to_distribution(&self) -> crate::moments::Distribution {
        use crate::moments::Distribution as D;
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
