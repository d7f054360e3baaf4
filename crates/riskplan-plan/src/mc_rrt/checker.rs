//! The Monte Carlo motion checker of the paper's baseline (Section V-A.3,
//! Illustrative Example 3; docs/design.md §7.3): `K` fresh uncertainty scenarios per
//! edge, `W` evenly spaced waypoints `τ_k = k/(W−1)`; an edge is accepted iff at
//! every waypoint, for every obstacle, the fraction of scenarios in collision is
//! at most Δ. **Not sound**: an accepted edge carries no guarantee, and planners
//! using this checker mark their output `certified: false`.

use crate::{Motion, MotionChecker};
use riskplan_math::mc::McModel;
use riskplan_scene::Piece;
use std::hash::{Hash, Hasher};
use std::sync::atomic::{AtomicU64, Ordering};

/// Parameters of the Monte Carlo checker (defaults: the paper's K = 10, W = 20).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct McCheckerParams {
    /// Scenarios per edge check.
    pub scenarios: u64,
    /// Waypoints per edge.
    pub waypoints: usize,
}

impl Default for McCheckerParams {
    fn default() -> Self {
        McCheckerParams { scenarios: 10, waypoints: 20 }
    }
}

/// Judges edges by sampling. Each check draws fresh scenarios from a seeded stream.
#[derive(Debug)]
pub struct McChecker {
    model: McModel,
    delta: f64,
    params: McCheckerParams,
    seed: u64,
    calls: AtomicU64,
}

impl McChecker {
    /// A checker at risk level `delta`, seeded.
    pub fn new(model: McModel, delta: f64, params: McCheckerParams, seed: u64) -> Self {
        McChecker { model, delta, params, seed, calls: AtomicU64::new(0) }
    }

    /// Scenarios are drawn from a stream keyed by the checker's seed and the points
    /// judged, so the same edge gets the same judgement (plans are reproducible), and
    /// different edges get independent scenarios.
    fn judge(&self, points: &[Vec<f64>]) -> Motion {
        self.calls.fetch_add(1, Ordering::Relaxed);
        let mut h = std::collections::hash_map::DefaultHasher::new();
        self.seed.hash(&mut h);
        for p in points {
            for v in p {
                v.to_bits().hash(&mut h);
            }
        }
        let seed = h.finish();
        let k = self.params.scenarios.max(1);
        let hits = self.model.hits(points, k, seed);
        let limit = self.delta * k as f64;
        if hits.iter().all(|per_obstacle| per_obstacle.iter().all(|&h| h as f64 <= limit)) {
            Motion::Accepted
        } else {
            Motion::Rejected
        }
    }
}

impl MotionChecker for McChecker {
    fn name(&self) -> &str {
        "monte-carlo"
    }

    fn sound(&self) -> bool {
        false
    }

    fn check(&self, piece: &Piece) -> Motion {
        let w = self.params.waypoints.max(2);
        let points: Vec<Vec<f64>> = (0..w)
            .map(|k| {
                let t = piece.t0 + (piece.t1 - piece.t0) * k as f64 / (w - 1) as f64;
                let mut x = piece.at(t);
                x.push(t);
                x
            })
            .collect();
        self.judge(&points)
    }

    fn check_point(&self, x: &[f64], t: f64) -> Motion {
        let mut xt = x.to_vec();
        xt.push(t);
        self.judge(&[xt])
    }
}
