//! RRT-SOS for static scenes (Section V-A.3; authors' `RRT_SOS_Static.m`,
//! docs/design.md §6.1–§6.3): straight edges, nearest vertex, widening-stripe
//! sampling, a goal-connection test after every accepted vertex, and the optional
//! improve step (a graph of all certified edges between tree vertices, shortest
//! path by Dijkstra). Every edge is judged by the [`MotionChecker`] — for RRT-SOS,
//! the continuous-time certificate of eq. (15).
//!
//! Where the authors' code has gaps we do the sound thing: an iteration cap and a
//! [`Termination`]; improve edges in both directions (a static segment is
//! undirected); stripes also widen after repeated failures so sampling cannot
//! stall; the returned pieces (constant speed over the horizon) are re-checked as
//! the exact floats returned.

use super::sampling::{width_range, StripeSampler};
use super::scale::Scale;
use crate::NoPlanReason;
use crate::{
    begin, constant_speed, dist, nearest, Begin, CheckCounter, Kinematics, Motion, MotionChecker, PlanError,
    PlanOutcome, PlanStatus, Planner, Problem, Termination,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use riskplan_scene::{Piece, RrtSosBlock, Trajectory};
use std::collections::{BinaryHeap, HashMap};
use std::time::Instant;

/// Parameters of the static RRT-SOS planner (defaults: the authors' values).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RrtParams {
    /// Steering step `rlim` (workspace units).
    pub step: f64,
    /// Stripe half-widths around the start–goal line (`0.1:0.1:1`).
    pub widths: Vec<f64>,
    /// Accepted vertices per stripe before widening.
    pub samples_per_stripe: usize,
    /// Consecutive rejected samples before widening anyway (the authors' sampler can stall).
    pub failures_per_widen: usize,
    /// Cap on sampling iterations (the authors have none).
    pub max_iterations: u64,
    /// Run the improve step after the first feasible path.
    pub improve: bool,
    /// Speed limit (the path's length over the horizon; the paper's planner neither
    /// smooths nor blends).
    pub kinematics: Kinematics,
}

impl Default for RrtParams {
    fn default() -> Self {
        RrtParams {
            step: 1.0,
            widths: width_range(0.1, 0.1, 1.0),
            samples_per_stripe: 10,
            failures_per_widen: 50,
            max_iterations: 100_000,
            improve: false,
            kinematics: Kinematics::default(),
        }
    }
}

impl RrtParams {
    /// The paper's parameters: the scene's `planner.rrt_sos` block where present
    /// (rlim, width, samples_per_stripe), else the paper's values in the problem's own
    /// units ([`Scale`]).
    pub fn paper(block: Option<&RrtSosBlock>, scale: &Scale) -> Self {
        let mut p = RrtParams { step: scale.paper_step(), widths: scale.paper_static_widths(), ..Default::default() };
        let Some(b) = block else { return p };
        if let Some(r) = b.rlim {
            p.step = r;
        }
        if let Some(w) = &b.width {
            if let Some(v) = &w.values {
                p.widths = v.clone();
            } else if let (Some(a), Some(s), Some(e)) = (w.start, w.step, w.stop) {
                p.widths = width_range(a, s, e);
            }
        }
        if let Some(n) = b.samples_per_stripe {
            p.samples_per_stripe = n;
        }
        p
    }

    /// Checks ranges.
    pub fn validate(&self) -> Result<(), PlanError> {
        let bad = |o: &str, m: &str| Err(PlanError::InvalidOption { option: o.into(), message: m.into() });
        if !(self.step > 0.0 && self.step.is_finite()) {
            return bad("step", "must be a positive number");
        }
        if self.samples_per_stripe == 0 || self.failures_per_widen == 0 {
            return bad("samples_per_stripe", "must be ≥ 1");
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be ≥ 1");
        }
        if self.widths.iter().any(|w| w.is_nan() || *w <= 0.0) {
            return bad("widths", "must be positive");
        }
        Ok(())
    }
}

/// The static RRT-SOS planner.
#[derive(Clone, Debug, Default)]
pub struct StaticRrt {
    /// Parameters.
    pub params: RrtParams,
}

impl StaticRrt {
    /// With parameters.
    pub fn new(params: RrtParams) -> Self {
        StaticRrt { params }
    }
}

struct Tree {
    verts: Vec<Vec<f64>>,
    parent: Vec<usize>,
}

impl Tree {
    fn nearest(&self, q: &[f64]) -> usize {
        nearest(&self.verts, q)
    }
    fn path_to(&self, mut i: usize) -> Vec<usize> {
        let mut out = vec![i];
        while self.parent[i] != usize::MAX {
            i = self.parent[i];
            out.push(i);
        }
        out.reverse();
        out
    }
    fn edges(&self) -> Vec<(Vec<f64>, Vec<f64>)> {
        (1..self.verts.len()).map(|i| (self.verts[self.parent[i]].clone(), self.verts[i].clone())).collect()
    }
}

/// Moves `q` towards `from` so that the step is at most `step`.
pub fn steer(from: &[f64], q: &[f64], step: f64) -> Vec<f64> {
    let d = dist(from, q);
    if d <= step {
        return q.to_vec();
    }
    from.iter().zip(q).map(|(a, b)| a + step * (b - a) / d).collect()
}

fn path_length(points: &[Vec<f64>]) -> f64 {
    points.windows(2).map(|w| dist(&w[0], &w[1])).sum()
}

impl Planner for StaticRrt {
    fn name(&self) -> &'static str {
        "rrt-sos-paper"
    }

    fn solve(
        &mut self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
    ) -> Result<PlanOutcome, PlanError> {
        let t_start = Instant::now();
        self.params.validate()?;
        crate::static_only(p)?;
        let mut stats = match begin(p, checker, term, self.params.kinematics.max_speed, t_start)? {
            Begin::Plan(stats) => stats,
            Begin::Answered(outcome) => return Ok(outcome),
        };
        let counter = CheckCounter::default();
        let ws = &p.scene.workspace;
        let sampler = StripeSampler::new(&ws.lower, &ws.upper, &p.start, &p.goal, self.params.widths.clone());
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let seg = |a: &[f64], b: &[f64]| Piece::segment(a, b, p.horizon.0, p.horizon.1);
        let mut tree = Tree { verts: vec![p.start.clone()], parent: vec![usize::MAX] };
        let mut goal_index = None;
        let mut status = PlanStatus::Exhausted;
        let (mut failures, mut widen) = (0usize, 0usize);
        // Iteration 0: the straight line itself.
        if counter.check(checker, &seg(&p.start, &p.goal)) == Motion::Accepted {
            tree.verts.push(p.goal.clone());
            tree.parent.push(0);
            goal_index = Some(1);
        }
        while goal_index.is_none() {
            if term.should_stop() {
                status = if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached };
                break;
            }
            if stats.iterations >= self.params.max_iterations {
                break;
            }
            stats.iterations += 1;
            let stripe = 1 + tree.verts.len() / self.params.samples_per_stripe + widen;
            let q = sampler.sample(&mut rng, stripe);
            let v = tree.nearest(&q);
            let q = steer(&tree.verts[v], &q, self.params.step);
            if counter.check(checker, &seg(&tree.verts[v], &q)) != Motion::Accepted {
                failures += 1;
                if failures >= self.params.failures_per_widen {
                    widen += 1;
                    failures = 0;
                }
                continue;
            }
            failures = 0;
            tree.verts.push(q.clone());
            tree.parent.push(v);
            let qi = tree.verts.len() - 1;
            if counter.check(checker, &seg(&q, &p.goal)) == Motion::Accepted {
                tree.verts.push(p.goal.clone());
                tree.parent.push(qi);
                goal_index = Some(tree.verts.len() - 1);
            }
        }
        let mut trajectory = None;
        if let Some(gi) = goal_index {
            stats.time_to_feasible_s = Some(t_start.elapsed().as_secs_f64());
            let feasible: Vec<Vec<f64>> = tree.path_to(gi).into_iter().map(|i| tree.verts[i].clone()).collect();
            stats.feasible_path_length = Some(path_length(&feasible));
            let mut candidates = vec![feasible];
            if self.params.improve {
                let t_imp = Instant::now();
                if let Some(better) = improve(&tree, gi, &seg, checker, &counter, term) {
                    candidates.insert(0, better);
                }
                stats.improve_time_s = t_imp.elapsed().as_secs_f64();
            }
            // Re-check the pieces exactly as returned (constant speed, rounded floats):
            // a sound checker must have accepted the very floats returned. (A sampling
            // checker's re-check would only redraw scenarios; it is skipped.)
            let duration = p.horizon.1 - p.horizon.0;
            for pts in candidates {
                if self.params.kinematics.max_speed.is_some_and(|v| path_length(&pts) > v * duration) {
                    continue;
                }
                let pieces = constant_speed(&pts, p.horizon);
                if !checker.sound() || pieces.iter().all(|pc| counter.check(checker, pc) == Motion::Accepted) {
                    stats.path_length = Some(path_length(&pts));
                    trajectory = Some(Trajectory::new(pieces));
                    status = PlanStatus::Exact;
                    break;
                }
            }
        }
        let (checked, accepted, secs) = counter.totals();
        stats.edges_checked = checked;
        stats.edges_accepted = accepted;
        stats.checker_time_s = secs;
        stats.vertices = tree.verts.len() as u64;
        stats.attempts = 1;
        stats.planning_time_s = t_start.elapsed().as_secs_f64();
        let certified = trajectory.is_some() && checker.sound();
        let reason = trajectory.is_none().then(|| match (goal_index, self.params.kinematics.max_speed) {
            (Some(_), Some(v)) => NoPlanReason::OutOfReach {
                distance: stats.feasible_path_length.unwrap_or(0.0),
                max_speed: v,
                duration: p.horizon.1 - p.horizon.0,
            },
            _ => NoPlanReason::from_status(status, &stats, term),
        });
        Ok(PlanOutcome { status, trajectory, certified, stats, tree: tree.edges(), reason })
    }
}

#[derive(PartialEq)]
struct Entry(f64, usize);
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

/// The improve step: certify every pair of tree vertices (both directions: a static
/// segment is undirected), then Dijkstra from the start (vertex 0) to the goal.
/// Stops early, keeping the feasible path, when `term` says so.
fn improve(
    tree: &Tree,
    goal: usize,
    seg: &dyn Fn(&[f64], &[f64]) -> Piece,
    checker: &dyn MotionChecker,
    counter: &CheckCounter,
    term: &Termination,
) -> Option<Vec<Vec<f64>>> {
    let n = tree.verts.len();
    let mut adj: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
    for i in 0..n {
        for j in i + 1..n {
            if term.should_stop() {
                return None;
            }
            if counter.check(checker, &seg(&tree.verts[i], &tree.verts[j])) == Motion::Accepted {
                let w = dist(&tree.verts[i], &tree.verts[j]);
                adj.entry(i).or_default().push((j, w));
                adj.entry(j).or_default().push((i, w));
            }
        }
    }
    let mut best = vec![f64::INFINITY; n];
    let mut prev = vec![usize::MAX; n];
    let mut heap = BinaryHeap::new();
    best[0] = 0.0;
    heap.push(Entry(0.0, 0));
    while let Some(Entry(d, u)) = heap.pop() {
        if d > best[u] {
            continue;
        }
        for &(v, w) in adj.get(&u).map(|v| v.as_slice()).unwrap_or(&[]) {
            if d + w < best[v] {
                best[v] = d + w;
                prev[v] = u;
                heap.push(Entry(d + w, v));
            }
        }
    }
    if !best[goal].is_finite() {
        return None;
    }
    let mut path = vec![goal];
    while path[path.len() - 1] != 0 {
        path.push(prev[path[path.len() - 1]]);
    }
    path.reverse();
    Some(path.into_iter().map(|i| tree.verts[i].clone()).collect())
}
