//! Trajectory format v1 (`docs/formats.md`): pieces `x_d(t) = Σ_k
//! coeffs[d][k]·t^k` on `[t0, t1]` in absolute time, contiguous in time.
//!
//! Trajectory numbers are `f64` and are taken *as they are*: the certified
//! trajectory is exactly the one a robot would execute from these floats (every
//! float is a dyadic rational, so certification composes them exactly).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The only trajectory format this version reads.
pub const TRAJECTORY_FORMAT: &str = "riskplan-trajectory/1";

/// Largest degree of a trajectory piece in t.
pub const MAX_PIECE_DEGREE: usize = 8;

/// Largest number of pieces.
pub const MAX_PIECES: usize = 10_000;

/// Largest gap between neighbouring pieces at their shared time, relative to the
/// workspace diagonal. Polynomial pieces evaluated in floating point at the same
/// instant can differ by rounding; a larger jump is a discontinuous (teleporting)
/// trajectory and is rejected.
pub const CONTINUITY_TOLERANCE: f64 = 1e-9;

/// One polynomial piece x_d(t) = Σ_k coeffs\[d\]\[k\]·t^k on `[t0, t1]`, in absolute time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Piece {
    /// Start time.
    pub t0: f64,
    /// End time.
    pub t1: f64,
    /// One row per dimension: `coeffs[d][k]` multiplies `t^k` in coordinate `d` (absolute
    /// time), degree ≤ 8.
    #[schemars(length(min = 1), inner(length(min = 1, max = 9)))]
    pub coeffs: Vec<Vec<f64>>,
}

impl Piece {
    /// The straight segment from `a` at `t0` to `b` at `t1`, in absolute time:
    /// `x(t) = a + (b − a)(t − t0)/(t1 − t0)`. The coefficients are rounded floats;
    /// certification uses the rounded coefficients, so what is certified is exactly
    /// what is returned.
    pub fn segment(a: &[f64], b: &[f64], t0: f64, t1: f64) -> Piece {
        let h = t1 - t0;
        let coeffs = a
            .iter()
            .zip(b)
            .map(|(&a, &b)| {
                let slope = (b - a) / h;
                vec![a - slope * t0, slope]
            })
            .collect();
        Piece { t0, t1, coeffs }
    }

    /// Position at absolute time `t` (floating point).
    pub fn at(&self, t: f64) -> Vec<f64> {
        self.coeffs.iter().map(|c| c.iter().rev().fold(0.0, |acc, &k| acc * t + k)).collect()
    }

    /// Velocity at absolute time `t` (floating point; Horner on `Σ k·c_k·t^(k−1)`).
    pub fn velocity(&self, t: f64) -> Vec<f64> {
        self.coeffs
            .iter()
            .map(|c| c.iter().enumerate().skip(1).rev().fold(0.0, |acc, (k, &ck)| acc * t + k as f64 * ck))
            .collect()
    }

    /// Degree in t (the largest over coordinates).
    pub fn degree(&self) -> usize {
        self.coeffs.iter().map(|c| c.len().saturating_sub(1)).max().unwrap_or(0)
    }
}

/// A trajectory, format v1: contiguous pieces in time order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Trajectory {
    /// `riskplan-trajectory/1`.
    #[schemars(extend("const" = TRAJECTORY_FORMAT))]
    pub format: String,
    /// The pieces, in time order.
    #[schemars(length(min = 1))]
    pub pieces: Vec<Piece>,
}

/// A trajectory file, which may be the output of `riskplan plan` (extra fields are kept).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryFile {
    /// Must be [`TRAJECTORY_FORMAT`].
    pub format: String,
    /// The pieces.
    pub pieces: Vec<Piece>,
    /// Planner that produced it (plan output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planner: Option<String>,
    /// Whether every piece was certified (plan output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certified: Option<bool>,
    /// Planner statistics (plan output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stats: Option<serde_json::Value>,
    /// Scene revision used (service output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub revision: Option<u64>,
    /// Scene name (plan output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
    /// Risk level used (plan output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub risk: Option<f64>,
}

impl TrajectoryFile {
    /// Parses trajectory JSON (format v1, or `riskplan plan` output) with what a plan adds
    /// (planner, scene, Δ, stats). A file of another riskplan format (a scene) is named
    /// as such instead of by its first field a trajectory does not have.
    pub fn from_json(text: &str) -> Result<TrajectoryFile, TrajectoryError> {
        // the plain parse first (several times faster on large trajectories); only a
        // failure is parsed again to name the field at fault
        let f: TrajectoryFile = match serde_json::from_str(text) {
            Ok(f) => f,
            Err(_) => {
                #[derive(Deserialize)]
                struct Format {
                    format: Option<String>,
                }
                if let Ok(Format { format: Some(other) }) = serde_json::from_str::<Format>(text) {
                    if other != TRAJECTORY_FORMAT {
                        return Err(wrong_format(&other));
                    }
                }
                let de = &mut serde_json::Deserializer::from_str(text);
                serde_path_to_error::deserialize::<_, TrajectoryFile>(de).map_err(|e| {
                    let p = e.path().to_string();
                    terr(if p == "." { "trajectory".to_string() } else { p }, e.into_inner().to_string())
                })?
            }
        };
        if f.format != TRAJECTORY_FORMAT {
            return Err(wrong_format(&f.format));
        }
        Ok(f)
    }
}

/// The error of a file whose `format` is not [`TRAJECTORY_FORMAT`].
fn wrong_format(format: &str) -> TrajectoryError {
    if format == crate::SCENE_FORMAT {
        return terr(
            "format",
            format!(
                "this is a scene file (\"{format}\"), not a trajectory: give it as --scene; a trajectory \
                 (\"{TRAJECTORY_FORMAT}\") is what `riskplan plan --out` writes"
            ),
        );
    }
    terr("format", format!("must be \"{TRAJECTORY_FORMAT}\", got \"{format}\""))
}

/// What is wrong with a trajectory.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{path}: {message}")]
pub struct TrajectoryError {
    /// Path of the offending field (`pieces[1].t0`).
    pub path: String,
    /// What is wrong.
    pub message: String,
}

fn terr(path: impl Into<String>, message: impl Into<String>) -> TrajectoryError {
    TrajectoryError { path: path.into(), message: message.into() }
}

impl Trajectory {
    /// Parses trajectory JSON (format v1, or `riskplan plan` output).
    pub fn from_json(text: &str) -> Result<Trajectory, TrajectoryError> {
        let f = TrajectoryFile::from_json(text)?;
        Ok(Trajectory { format: f.format, pieces: f.pieces })
    }

    /// From pieces.
    pub fn new(pieces: Vec<Piece>) -> Trajectory {
        Trajectory { format: TRAJECTORY_FORMAT.to_string(), pieces }
    }

    /// Checks the trajectory against a scene's dimension, horizon and workspace size:
    /// finite numbers, `t0 < t1`, contiguous pieces inside the horizon, one
    /// coefficient row per dimension, degree ≤ `MAX_PIECE_DEGREE`, continuity.
    pub fn validate(&self, dim: usize, horizon: (f64, f64), workspace_diagonal: f64) -> Result<(), TrajectoryError> {
        self.validate_up_to(dim, horizon, workspace_diagonal, MAX_PIECES)
    }

    /// [`Trajectory::validate`] with at most `max_pieces` pieces instead of
    /// [`MAX_PIECES`] (`verify` takes larger trajectories than a plan returns).
    pub fn validate_up_to(
        &self,
        dim: usize,
        horizon: (f64, f64),
        workspace_diagonal: f64,
        max_pieces: usize,
    ) -> Result<(), TrajectoryError> {
        if self.pieces.is_empty() {
            return Err(terr("pieces", "must hold at least one piece"));
        }
        if self.pieces.len() > max_pieces {
            return Err(terr("pieces", format!("at most {max_pieces} pieces, got {}", self.pieces.len())));
        }
        for (i, p) in self.pieces.iter().enumerate() {
            let at = |f: &str| format!("pieces[{i}].{f}");
            if !p.t0.is_finite() || !p.t1.is_finite() || p.t0 >= p.t1 {
                return Err(terr(at("t1"), format!("needs finite t0 < t1, got [{}, {}]", p.t0, p.t1)));
            }
            if p.t0 < horizon.0 || p.t1 > horizon.1 {
                return Err(terr(
                    at("t0"),
                    format!("[{}, {}] is outside the scene horizon [{}, {}]", p.t0, p.t1, horizon.0, horizon.1),
                ));
            }
            if p.coeffs.len() != dim {
                return Err(terr(
                    at("coeffs"),
                    format!("needs {dim} rows (one per dimension), got {}", p.coeffs.len()),
                ));
            }
            for (d, row) in p.coeffs.iter().enumerate() {
                if row.is_empty() || row.len() > MAX_PIECE_DEGREE + 1 {
                    return Err(terr(
                        format!("pieces[{i}].coeffs[{d}]"),
                        format!("needs 1 to {} coefficients, got {}", MAX_PIECE_DEGREE + 1, row.len()),
                    ));
                }
                if row.iter().any(|c| !c.is_finite()) {
                    return Err(terr(format!("pieces[{i}].coeffs[{d}]"), "coefficients must be finite"));
                }
            }
            if i > 0 {
                let prev = &self.pieces[i - 1];
                if prev.t1 != p.t0 {
                    return Err(terr(
                        at("t0"),
                        format!(
                            "pieces must be contiguous: previous piece ends at {}, this one starts at {}",
                            prev.t1, p.t0
                        ),
                    ));
                }
                let (a, b) = (prev.at(p.t0), p.at(p.t0));
                let gap = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
                if gap > CONTINUITY_TOLERANCE * workspace_diagonal.max(1.0) {
                    return Err(terr(
                        at("coeffs"),
                        format!("the trajectory jumps by {gap:e} at t = {} (pieces must meet)", p.t0),
                    ));
                }
            }
        }
        Ok(())
    }
}
