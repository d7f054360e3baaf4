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

use super::paper_static::steer;
use super::sampling::{width_range, StripeSampler};
use super::scale::Scale;
use super::smooth::{blend, shortcut, Limits, SmoothStats, Waypoint, WorkBudget};
use crate::NoPlanReason;
use crate::{
    begin, dist, nearest, within_speed, Begin, CheckCounter, Kinematics, Motion, MotionChecker, PlanError, PlanOutcome,
    PlanStats, PlanStatus, Planner, Problem, Termination,
};
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use riskplan_scene::{Piece, RrtSosBlock, Trajectory};
use std::time::Instant;

/// The tree's edges are steered to at most `(1 − SPEED_CAP_MARGIN)·max_speed·Δt`: a
/// piece's chord, evaluated from its rounded coefficients, can exceed its end points'
/// distance by a few ulps of their coordinates, and every returned piece must pass
/// [`within_speed`] (docs/design.md §6.4, §6.8). 10⁻⁹ covers coordinates up to about 10⁶
/// times the edge's length; an edge that still fails the check is not added.
pub const SPEED_CAP_MARGIN: f64 = 1e-9;

/// The ladder of piece counts tried when none is given: each rung gets half the time
/// that remains (the last all of it) and [`LayeredParams::max_attempts`] attempts.
pub const LADDER: [usize; 6] = [1, 2, 4, 8, 16, 32];

/// Parameters of the layered planner (defaults: the authors' values).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LayeredParams {
    /// Number of pieces `s` (equal time intervals); `None`: the `LADDER`.
    pub pieces: Option<usize>,
    /// Steering step `rlim` (the paper's, which also caps speed at `rlim·s/(tf − t0)`);
    /// `None`: no cap but `max_speed`.
    pub step: Option<f64>,
    /// Stripe half-widths (`0.1:0.1:5`, of which the authors use the first 21), or the
    /// radii of local sampling.
    pub widths: Vec<f64>,
    /// Vertices per stripe in intermediate layers.
    pub samples_per_stripe: usize,
    /// Iterations per stripe (last layer, and as a floor elsewhere).
    pub iter_per_stripe: usize,
    /// Vertices at which an intermediate layer stops (`nV_MAX`).
    pub max_vertices_per_layer: usize,
    /// Iterations per layer (`MAX_ITER`).
    pub max_iterations_per_layer: usize,
    /// Restarts of the whole construction before giving up (per rung of the ladder).
    pub max_attempts: usize,
    /// Sample layer `i` around the point `i/s` of the way from start to goal (the
    /// default planner) instead of the paper's stripe along the whole line.
    pub local: bool,
    /// Speed limit, acceleration limit for smoothing, and whether to shortcut and
    /// blend the result.
    pub kinematics: Kinematics,
    /// The whole-path budget (`risk_mode: trajectory`, docs/design.md §5.14): each vertex
    /// keeps the sum of its path's piece bounds ([`MotionChecker::path_risk`]) within it.
    /// Set by the request, never by a scene file.
    #[serde(skip)]
    pub path_budget: Option<f64>,
}

impl Default for LayeredParams {
    fn default() -> Self {
        let mut widths = width_range(0.1, 0.1, 5.0);
        widths.truncate(21);
        LayeredParams {
            pieces: Some(2),
            step: Some(1.0),
            widths,
            samples_per_stripe: 10,
            iter_per_stripe: 50,
            max_vertices_per_layer: 20,
            max_iterations_per_layer: 1000,
            max_attempts: 100,
            local: false,
            kinematics: Kinematics::default(),
            path_budget: None,
        }
    }
}

impl LayeredParams {
    /// The paper's parameters: the scene's `planner.rrt_sos` block where present
    /// (pieces, rlim, widths, limits), else the paper's values in the problem's units;
    /// without `pieces` the ladder.
    pub fn paper(block: Option<&RrtSosBlock>, scale: &Scale) -> Self {
        let mut p = LayeredParams {
            pieces: None,
            step: Some(scale.paper_step()),
            widths: scale.paper_layered_widths(),
            ..Default::default()
        };
        let Some(b) = block else { return p };
        if b.pieces.is_some() {
            p.pieces = b.pieces;
        }
        if let Some(r) = b.rlim {
            p.step = Some(r);
        }
        if let Some(w) = &b.width {
            if let Some(v) = &w.values {
                p.widths = v.clone();
            } else if let (Some(a), Some(s), Some(e)) = (w.start, w.step, w.stop) {
                p.widths = width_range(a, s, e);
            }
            if let Some(n) = w.used_entries {
                p.widths.truncate(n);
            }
        }
        for (v, dst) in [
            (b.samples_per_stripe, &mut p.samples_per_stripe),
            (b.iter_per_stripe, &mut p.iter_per_stripe),
            (b.max_vertices_per_layer, &mut p.max_vertices_per_layer),
            (b.max_iterations_per_layer, &mut p.max_iterations_per_layer),
        ] {
            if let Some(v) = v {
                *dst = v;
            }
        }
        p
    }

    /// The default planner's parameters: the ladder, no steering cap but the speed
    /// limit, local sampling with radii `side·(0.05 … 1.05)`, fewer attempts per rung.
    pub fn fast(scale: &Scale) -> Self {
        LayeredParams {
            pieces: None,
            step: None,
            widths: scale.paper_layered_widths(),
            max_attempts: 20,
            max_iterations_per_layer: 400,
            local: true,
            kinematics: Kinematics::SMOOTH,
            ..Default::default()
        }
    }

    /// Checks ranges.
    pub fn validate(&self) -> Result<(), PlanError> {
        let bad = |o: &str, m: &str| Err(PlanError::InvalidOption { option: o.into(), message: m.into() });
        if self.pieces == Some(0) {
            return bad("pieces", "must be ≥ 1");
        }
        if self.pieces.is_some_and(|s| s > 1000) {
            return bad("pieces", "must be ≤ 1000");
        }
        if self.step.is_some_and(|s| !(s > 0.0 && s.is_finite())) {
            return bad("step", "must be a positive number");
        }
        if self.widths.is_empty() || self.widths.iter().any(|w| w.is_nan() || *w <= 0.0) {
            return bad("widths", "must be positive (and at least one)");
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
    /// The whole-path bound accumulated from the start (0 without a budget).
    risk: Vec<f64>,
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
        s: usize,
        times: &[f64],
        sampler: &StripeSampler,
        rng: &mut ChaCha8Rng,
        checker: &dyn MotionChecker,
        counter: &CheckCounter,
        term: &Termination,
        stats: &mut PlanStats,
        tree: &mut Vec<(Vec<f64>, Vec<f64>)>,
    ) -> Attempt {
        let mut layers =
            vec![Layer { verts: vec![p.start.clone()], parent: vec![usize::MAX], pieces: vec![None], risk: vec![0.0] }];
        let budget = self.params.path_budget;
        // a piece's whole-path bound (0 without a budget)
        let stop = || term.should_stop();
        let risk_of = |pc: &Piece| if budget.is_some() { checker.path_risk(pc, &stop).unwrap_or(1.0) } else { 0.0 };
        let within = |r: f64| budget.is_none_or(|d| r <= d);
        if s == 1 {
            let piece = Piece::segment(&p.start, &p.goal, times[0], times[1]);
            return if self.speed_ok(&p.start, &p.goal, times[1] - times[0])
                && counter.check(checker, &piece) == Motion::Accepted
                && within(risk_of(&piece))
            {
                Attempt::Found(vec![piece])
            } else {
                Attempt::Failed
            };
        }
        for i in 1..s {
            let last = i == s - 1;
            let mut layer = Layer { verts: vec![], parent: vec![], pieces: vec![], risk: vec![] };
            let mut goal_piece = None;
            for iter in 0..self.params.max_iterations_per_layer {
                if term.should_stop() {
                    return Attempt::Stopped;
                }
                stats.iterations += 1;
                let by_count = layer.verts.len() / self.params.samples_per_stripe;
                let by_iter = iter / self.params.iter_per_stripe;
                let stripe = 1 + if last { by_iter } else { by_count.max(by_iter) };
                let q = if self.params.local {
                    let nominal: Vec<f64> =
                        p.start.iter().zip(&p.goal).map(|(a, b)| a + (b - a) * i as f64 / s as f64).collect();
                    let r = sampler.width(stripe).min(self.params.widths[self.params.widths.len() - 1]);
                    let ws = &p.scene.workspace;
                    nominal
                        .iter()
                        .enumerate()
                        .map(|(d, c)| (c + r * rng.random_range(-1.0..=1.0)).clamp(ws.lower[d], ws.upper[d]))
                        .collect()
                } else {
                    sampler.sample(rng, stripe)
                };
                let prev = &layers[i - 1];
                let a = nearest(&prev.verts, &q);
                let dt = times[i] - times[i - 1];
                let cap = match (self.params.step, self.params.kinematics.max_speed) {
                    (Some(st), Some(v)) => st.min(v * dt * (1.0 - SPEED_CAP_MARGIN)),
                    (Some(st), None) => st,
                    (None, Some(v)) => v * dt * (1.0 - SPEED_CAP_MARGIN),
                    (None, None) => f64::INFINITY,
                };
                let q = steer(&prev.verts[a], &q, cap);
                // the goal must stay reachable under the speed limit
                if !self.speed_ok(&q, &p.goal, times[s] - times[i]) {
                    continue;
                }
                let piece = Piece::segment(&prev.verts[a], &q, times[i - 1], times[i]);
                if !self.piece_speed_ok(&piece) || counter.check(checker, &piece) != Motion::Accepted {
                    continue;
                }
                let acc = super::smooth::add_up(prev.risk[a], risk_of(&piece));
                if !within(acc) {
                    continue;
                }
                tree.push((prev.verts[a].clone(), q.clone()));
                if last {
                    let to_goal = Piece::segment(&q, &p.goal, times[i], times[i + 1]);
                    if self.speed_ok(&q, &p.goal, times[i + 1] - times[i])
                        && self.piece_speed_ok(&to_goal)
                        && counter.check(checker, &to_goal) == Motion::Accepted
                        && within(super::smooth::add_up(acc, risk_of(&to_goal)))
                    {
                        tree.push((q.clone(), p.goal.clone()));
                        layer.verts.push(q);
                        layer.parent.push(a);
                        layer.pieces.push(Some(piece));
                        layer.risk.push(acc);
                        goal_piece = Some(to_goal);
                        break;
                    }
                } else {
                    layer.verts.push(q);
                    layer.parent.push(a);
                    layer.pieces.push(Some(piece));
                    layer.risk.push(acc);
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

impl LayeredRrt {
    fn speed_ok(&self, a: &[f64], b: &[f64], dt: f64) -> bool {
        self.params.kinematics.max_speed.is_none_or(|v| dist(a, b) <= v * dt)
    }
    /// Whether a piece keeps the speed limit, by the check every returned piece passes.
    fn piece_speed_ok(&self, pc: &Piece) -> bool {
        self.params.kinematics.max_speed.is_none_or(|v| within_speed(pc, v))
    }
}

impl Planner for LayeredRrt {
    fn name(&self) -> &'static str {
        if self.params.local {
            "rrt-sos"
        } else {
            "rrt-sos-paper"
        }
    }

    fn solve(
        &mut self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
    ) -> Result<PlanOutcome, PlanError> {
        let t_start = Instant::now();
        self.params.validate()?;
        let mut stats = match begin(p, checker, term, self.params.kinematics.max_speed, t_start)? {
            Begin::Plan(stats) => stats,
            Begin::Answered(outcome) => return Ok(outcome),
        };
        let (t0, tf) = p.horizon;
        let ws = &p.scene.workspace;
        let sampler = StripeSampler::new(&ws.lower, &ws.upper, &p.start, &p.goal, self.params.widths.clone());
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let counter = CheckCounter::default();
        let mut tree = Vec::new();
        let mut status = PlanStatus::Exhausted;
        let mut found: Option<(usize, Vec<Piece>)> = None;
        let rungs: Vec<usize> = match self.params.pieces {
            Some(s) => vec![s],
            None => LADDER.to_vec(),
        };
        let mut tried = Vec::new();
        'ladder: for (k, &s) in rungs.iter().enumerate() {
            let times: Vec<f64> =
                (0..=s).map(|i| if i == s { tf } else { t0 + (tf - t0) * i as f64 / s as f64 }).collect();
            // each rung but the last gets half of the time that remains
            let rung_term = match term.remaining() {
                Some(left) if k + 1 < rungs.len() => term.clone().earliest(left / 2),
                _ => term.clone(),
            };
            tried.push(s);
            for _ in 0..self.params.max_attempts {
                stats.attempts += 1;
                match self
                    .attempt(p, s, &times, &sampler, &mut rng, checker, &counter, &rung_term, &mut stats, &mut tree)
                {
                    Attempt::Found(pieces) => {
                        found = Some((s, pieces));
                        break 'ladder;
                    }
                    Attempt::Stopped if term.expired() => {
                        status = if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached };
                        break 'ladder;
                    }
                    Attempt::Stopped => break,
                    Attempt::Failed if s == 1 => break,
                    Attempt::Failed => {}
                }
            }
        }
        let mut trajectory = None;
        if let Some((s, pieces)) = found {
            stats.pieces = Some(s);
            stats.time_to_feasible_s = Some(t_start.elapsed().as_secs_f64());
            let len: f64 = pieces.iter().map(|pc| dist(&pc.at(pc.t0), &pc.at(pc.t1))).sum();
            stats.feasible_path_length = Some(len);
            stats.path_length = Some(len);
            let mut out = Some(pieces.clone());
            if self.params.kinematics.smooth {
                let t_imp = Instant::now();
                let mut w: Vec<Waypoint> = pieces.iter().map(|pc| (pc.t0, pc.at(pc.t0))).collect();
                w[0].1 = p.start.clone();
                w.push((tf, p.goal.clone()));
                // the layer vertices exactly as certified
                for (k, pc) in pieces.iter().enumerate().skip(1) {
                    w[k].1 = pc.at(pc.t0);
                }
                let mut sm = SmoothStats { waypoints_before: w.len(), ..Default::default() };
                let short = shortcut(
                    w,
                    p.horizon,
                    true,
                    self.params.kinematics.max_speed,
                    checker,
                    &counter,
                    &mut rng,
                    term,
                    WorkBudget::UNLIMITED,
                    self.params.path_budget,
                    &mut sm,
                );
                sm.waypoints_after = short.len();
                let bounds = (ws.lower.as_slice(), ws.upper.as_slice());
                let limits = Limits::of(&self.params.kinematics);
                // a smoothed plan beyond the whole-path budget gives way to the next (the
                // layered pieces themselves are within it)
                let within_budget = |pcs: &[Piece]| {
                    self.params.path_budget.is_none_or(|d| checker.path_risk_sum(pcs, &|| term.should_stop()) <= d)
                };
                let smoothed = blend(&short, bounds, limits, true, checker, &counter, &mut sm, term)
                    .filter(|b| within_budget(b))
                    .or_else(|| {
                        sm.corners_sharp = short.len().saturating_sub(2);
                        let s = super::smooth::straight(&short, &ws.lower, &ws.upper);
                        (s.iter().all(|pc| self.piece_speed_ok(pc))
                            && (!checker.sound() || s.iter().all(|pc| counter.check(checker, pc) == Motion::Accepted))
                            && within_budget(&s))
                        .then_some(s)
                    });
                stats.improve_time_s = t_imp.elapsed().as_secs_f64();
                if smoothed.is_some() {
                    stats.path_length = Some(short.windows(2).map(|x| dist(&x[0].1, &x[1].1)).sum());
                    out = smoothed;
                }
                stats.smoothing = Some(sm);
            }
            if let Some(pieces) = out {
                trajectory = Some(Trajectory::new(pieces));
                status = PlanStatus::Exact;
            }
        }
        let (checked, accepted, secs) = counter.totals();
        stats.edges_checked = checked;
        stats.edges_accepted = accepted;
        stats.checker_time_s = secs;
        stats.vertices += 1;
        stats.planning_time_s = t_start.elapsed().as_secs_f64();
        let certified = trajectory.is_some() && checker.sound();
        let reason = trajectory.is_none().then(|| {
            let mut r = NoPlanReason::from_status(status, &stats, term);
            if let NoPlanReason::Exhausted { pieces_tried, .. } | NoPlanReason::DeadlineReached { pieces_tried, .. } =
                &mut r
            {
                *pieces_tried = tried.clone();
            }
            r
        });
        if stats.pieces.is_none() {
            stats.pieces = tried.last().copied();
        }
        Ok(PlanOutcome { status, trajectory, certified, stats, tree, reason })
    }
}
