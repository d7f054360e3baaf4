//! Time-layered RRT-SOS for moving obstacles (Section V-B; authors'
//! `RRT_SOS_Dynamic.m`, docs/design.md §6.4). With `s` pieces on equal time
//! intervals `t_i = t0 + i(tf − t0)/s`, layer `i` holds positions at time `t_i`; an
//! edge from layer `i−1` to layer `i` is the constant-velocity motion between them
//! and is certified **only on its own interval** `[t_{i−1}, t_i]`, against moving
//! and static obstacles. The last sampled layer must also connect to the goal.
//!
//! Gaps of the authors' code handled here: `s = 1` (certify start → goal
//! directly); an empty layer or a last layer that fails restarts the construction
//! (a new attempt with the RNG stream continuing) instead of crashing; the stripe
//! index also grows with failed iterations so a layer cannot stall.

use super::rrt::steer;
use super::sampling::{width_range, StripeSampler};
use super::{
    check_endpoints, dist, nearest, CheckCounter, Motion, MotionChecker, PlanError, PlanOutcome, PlanStats, PlanStatus,
    Planner, Problem, Termination,
};
use crate::scene::{Piece, Trajectory};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// Parameters of the layered planner (defaults: the authors' values).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LayeredParams {
    /// Number of pieces `s` (equal time intervals).
    pub pieces: usize,
    /// Steering step `rlim`; also caps speed at `rlim·s/(tf − t0)`.
    pub step: f64,
    /// Stripe half-widths (`0.1:0.1:5`, of which the authors use the first 21).
    pub widths: Vec<f64>,
    /// Vertices per stripe in intermediate layers.
    pub samples_per_stripe: usize,
    /// Iterations per stripe (last layer, and as a floor elsewhere).
    pub iter_per_stripe: usize,
    /// Vertices at which an intermediate layer stops (`nV_MAX`).
    pub max_vertices_per_layer: usize,
    /// Iterations per layer (`MAX_ITER`).
    pub max_iterations_per_layer: usize,
    /// Restarts of the whole construction before giving up.
    pub max_attempts: usize,
}

impl Default for LayeredParams {
    fn default() -> Self {
        let mut widths = width_range(0.1, 0.1, 5.0);
        widths.truncate(21);
        LayeredParams {
            pieces: 2,
            step: 1.0,
            widths,
            samples_per_stripe: 10,
            iter_per_stripe: 50,
            max_vertices_per_layer: 20,
            max_iterations_per_layer: 1000,
            max_attempts: 100,
        }
    }
}

impl LayeredParams {
    /// Reads the scene's `planner.rrt_sos` block where present (pieces, rlim, widths, limits).
    pub fn from_scene_block(block: Option<&serde_json::Value>) -> Self {
        let mut p = LayeredParams::default();
        let Some(b) = block else { return p };
        let u = |k: &str| b[k].as_u64().map(|v| v as usize);
        if let Some(v) = u("pieces") {
            p.pieces = v;
        }
        if let Some(r) = b["rlim"].as_f64() {
            p.step = r;
        }
        if let (Some(a), Some(s), Some(e)) =
            (b["width"]["start"].as_f64(), b["width"]["step"].as_f64(), b["width"]["stop"].as_f64())
        {
            p.widths = width_range(a, s, e);
            if let Some(n) = b["width"]["used_entries"].as_u64() {
                p.widths.truncate(n as usize);
            }
        }
        if let Some(v) = u("samples_per_stripe") {
            p.samples_per_stripe = v;
        }
        if let Some(v) = u("iter_per_stripe") {
            p.iter_per_stripe = v;
        }
        if let Some(v) = u("max_vertices_per_layer") {
            p.max_vertices_per_layer = v;
        }
        if let Some(v) = u("max_iterations_per_layer") {
            p.max_iterations_per_layer = v;
        }
        p
    }

    /// Checks ranges.
    pub fn validate(&self) -> Result<(), PlanError> {
        let bad = |o: &str, m: &str| Err(PlanError::InvalidOption { option: o.into(), message: m.into() });
        if self.pieces == 0 {
            return bad("pieces", "must be ≥ 1");
        }
        if self.pieces > 1000 {
            return bad("pieces", "must be ≤ 1000");
        }
        if !(self.step > 0.0 && self.step.is_finite()) {
            return bad("step", "must be a positive number");
        }
        if self.samples_per_stripe == 0 || self.iter_per_stripe == 0 || self.max_vertices_per_layer == 0 {
            return bad("samples_per_stripe", "stripe and layer sizes must be ≥ 1");
        }
        if self.max_iterations_per_layer == 0 || self.max_attempts == 0 {
            return bad("max_iterations_per_layer", "must be ≥ 1");
        }
        Ok(())
    }
}

/// The layered dynamic RRT-SOS planner.
#[derive(Clone, Debug, Default)]
pub struct LayeredRrt {
    /// Parameters.
    pub params: LayeredParams,
}

impl LayeredRrt {
    /// With parameters.
    pub fn new(params: LayeredParams) -> Self {
        LayeredRrt { params }
    }
}

struct Layer {
    verts: Vec<Vec<f64>>,
    parent: Vec<usize>,
    pieces: Vec<Option<Piece>>,
}

enum Attempt {
    Found(Vec<Piece>),
    Failed,
    Stopped,
}

impl LayeredRrt {
    #[allow(clippy::too_many_arguments)]
    fn attempt(
        &self,
        p: &Problem,
        times: &[f64],
        sampler: &StripeSampler,
        rng: &mut ChaCha8Rng,
        checker: &dyn MotionChecker,
        counter: &CheckCounter,
        term: &Termination,
        stats: &mut PlanStats,
        tree: &mut Vec<(Vec<f64>, Vec<f64>)>,
    ) -> Attempt {
        let s = self.params.pieces;
        let mut layers = vec![Layer { verts: vec![p.start.clone()], parent: vec![usize::MAX], pieces: vec![None] }];
        if s == 1 {
            let piece = Piece::segment(&p.start, &p.goal, times[0], times[1]);
            return if counter.check(checker, &piece) == Motion::Accepted {
                Attempt::Found(vec![piece])
            } else {
                Attempt::Failed
            };
        }
        for i in 1..s {
            let last = i == s - 1;
            let mut layer = Layer { verts: vec![], parent: vec![], pieces: vec![] };
            let mut goal_piece = None;
            for iter in 0..self.params.max_iterations_per_layer {
                if term.should_stop() {
                    return Attempt::Stopped;
                }
                stats.iterations += 1;
                let by_count = layer.verts.len() / self.params.samples_per_stripe;
                let by_iter = iter / self.params.iter_per_stripe;
                let stripe = 1 + if last { by_iter } else { by_count.max(by_iter) };
                let q = sampler.sample(rng, stripe);
                let prev = &layers[i - 1];
                let a = nearest(&prev.verts, &q);
                let q = steer(&prev.verts[a], &q, self.params.step);
                let piece = Piece::segment(&prev.verts[a], &q, times[i - 1], times[i]);
                if counter.check(checker, &piece) != Motion::Accepted {
                    continue;
                }
                tree.push((prev.verts[a].clone(), q.clone()));
                if last {
                    let to_goal = Piece::segment(&q, &p.goal, times[i], times[i + 1]);
                    if counter.check(checker, &to_goal) == Motion::Accepted {
                        tree.push((q.clone(), p.goal.clone()));
                        layer.verts.push(q);
                        layer.parent.push(a);
                        layer.pieces.push(Some(piece));
                        goal_piece = Some(to_goal);
                        break;
                    }
                } else {
                    layer.verts.push(q);
                    layer.parent.push(a);
                    layer.pieces.push(Some(piece));
                    if layer.verts.len() >= self.params.max_vertices_per_layer {
                        break;
                    }
                }
            }
            stats.vertices += layer.verts.len() as u64;
            if layer.verts.is_empty() || (last && goal_piece.is_none()) {
                return Attempt::Failed;
            }
            layers.push(layer);
            if let Some(gp) = goal_piece {
                // Follow parents back from the last vertex of the last layer.
                let mut pieces = vec![gp];
                let mut idx = layers[s - 1].verts.len() - 1;
                for l in (1..s).rev() {
                    if let Some(pc) = layers[l].pieces[idx].clone() {
                        pieces.push(pc);
                    }
                    idx = layers[l].parent[idx];
                }
                pieces.reverse();
                return Attempt::Found(pieces);
            }
        }
        Attempt::Failed
    }
}

impl Planner for LayeredRrt {
    fn name(&self) -> &'static str {
        "rrt-sos"
    }

    fn solve(
        &mut self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
    ) -> Result<PlanOutcome, PlanError> {
        let t_start = Instant::now();
        self.params.validate()?;
        check_endpoints(p, checker)?;
        checker.prepare(term);
        let s = self.params.pieces;
        let (t0, tf) = p.horizon;
        let times: Vec<f64> = (0..=s).map(|i| if i == s { tf } else { t0 + (tf - t0) * i as f64 / s as f64 }).collect();
        let ws = &p.scene.workspace;
        let sampler = StripeSampler::new(&ws.lower, &ws.upper, &p.start, &p.goal, self.params.widths.clone());
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let counter = CheckCounter::default();
        let mut stats = PlanStats { checker: checker.name().to_string(), seed: p.seed, ..Default::default() };
        let mut tree = Vec::new();
        let mut status = PlanStatus::Exhausted;
        let mut trajectory = None;
        for _ in 0..self.params.max_attempts {
            stats.attempts += 1;
            match self.attempt(p, &times, &sampler, &mut rng, checker, &counter, term, &mut stats, &mut tree) {
                Attempt::Found(pieces) => {
                    stats.time_to_feasible_s = Some(t_start.elapsed().as_secs_f64());
                    let len: f64 = pieces.iter().map(|pc| dist(&pc.at(pc.t0), &pc.at(pc.t1))).sum();
                    stats.path_length = Some(len);
                    stats.feasible_path_length = Some(len);
                    trajectory = Some(Trajectory::new(pieces));
                    status = PlanStatus::Exact;
                    break;
                }
                Attempt::Stopped => {
                    status = if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached };
                    break;
                }
                Attempt::Failed if s == 1 => break,
                Attempt::Failed => {}
            }
        }
        let (checked, accepted, secs) = counter.totals();
        stats.edges_checked = checked;
        stats.edges_accepted = accepted;
        stats.checker_time_s = secs;
        stats.vertices += 1;
        stats.planning_time_s = t_start.elapsed().as_secs_f64();
        let certified = trajectory.is_some() && checker.sound();
        Ok(PlanOutcome { status, trajectory, certified, stats, tree })
    }
}
