//! The default static planner: bidirectional RRT (RRT-Connect, Kuffner & LaValle 2000)
//! with every edge certified (eq. 15), then certified shortcutting and C¹ corner blends
//! ([`super::smooth`]). Docs: docs/design.md §6.6.
//!
//! Two trees grow from start and goal. Each iteration extends one tree by one step
//! towards a uniform sample (or, with probability [`ConnectParams::goal_bias`], towards
//! the other tree's root) and then pulls the other tree greedily towards the new vertex,
//! step by step, until it reaches it (a path) or an edge is rejected; then the trees
//! swap roles. The straight line from start to goal is tried first. Lengths come from
//! the problem's [`Scale`]: the step is about the spacing of the obstacles.

use super::scale::Scale;
use super::smooth::{add_up, blend, shortcut, straight, time_at_constant_speed, Limits, SmoothStats, WorkBudget};
use crate::{
    dist, nearest, within_speed, CheckCounter, Kinematics, Motion, MotionChecker, NoPlanReason, PlanError, PlanOutcome,
    PlanStats, PlanStatus, Planner, Problem, Termination,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use riskplan_scene::{Piece, Trajectory};
use std::time::Instant;

/// Options of the connect planner.
#[derive(Clone, Debug, PartialEq)]
pub struct ConnectParams {
    /// Steering step; `None`: [`Scale::connect_step`].
    pub step: Option<f64>,
    /// Probability of steering towards the other tree's root.
    pub goal_bias: f64,
    /// Cap on iterations.
    pub max_iterations: u64,
    /// Speed limit (the path's length over the horizon), acceleration limit of the
    /// corner blends, and whether to shortcut and blend the path (C¹ output).
    pub kinematics: Kinematics,
    /// Candidate paths grown before shortcutting keeps the shortest (smoothing only).
    pub candidates: usize,
    /// The whole-path budget (`risk_mode: trajectory`, docs/design.md §5.14): every vertex
    /// keeps the sum of its path's edge bounds ([`MotionChecker::path_risk`]) within it.
    pub path_budget: Option<f64>,
}

impl Default for ConnectParams {
    fn default() -> Self {
        ConnectParams {
            step: None,
            goal_bias: 0.1,
            max_iterations: 200_000,
            kinematics: Kinematics::SMOOTH,
            candidates: 4,
            path_budget: None,
        }
    }
}

/// The connect planner.
#[derive(Clone, Debug, Default)]
pub struct ConnectRrt {
    /// Options.
    pub params: ConnectParams,
}

struct Tree {
    verts: Vec<Vec<f64>>,
    parent: Vec<usize>,
    /// The whole-path bound accumulated from the root (0 without a budget).
    risk: Vec<f64>,
}

impl Tree {
    fn root(p: Vec<f64>) -> Tree {
        Tree { verts: vec![p], parent: vec![usize::MAX], risk: vec![0.0] }
    }
    fn add(&mut self, p: Vec<f64>, parent: usize, edge_risk: f64) -> usize {
        self.verts.push(p);
        self.risk.push(add_up(self.risk[parent], edge_risk));
        self.parent.push(parent);
        self.verts.len() - 1
    }
    fn path_to_root(&self, mut i: usize) -> Vec<Vec<f64>> {
        let mut out = vec![self.verts[i].clone()];
        while self.parent[i] != usize::MAX {
            i = self.parent[i];
            out.push(self.verts[i].clone());
        }
        out
    }
}

/// An edge check: `Some(the edge's whole-path bound)` (0 without a budget) when accepted.
type EdgeCheck<'a> = dyn Fn(&[f64], &[f64]) -> Option<f64> + 'a;

fn steer(from: &[f64], to: &[f64], step: f64) -> Vec<f64> {
    let d = dist(from, to);
    if d <= step {
        to.to_vec()
    } else {
        from.iter().zip(to).map(|(a, b)| a + step * (b - a) / d).collect()
    }
}

/// Post-processing (candidate paths and shortcuts; not the corner blends, which the C¹
/// output needs) may spend this many times the checking work of the search for the first
/// path ([`MotionChecker::work`], docs/design.md §6.8): as much again (on many obstacles a
/// larger budget buys a slightly shorter path for a whole plan many times its first path).
pub const SMOOTH_WORK_FACTOR: u64 = 1;

/// ... and at least this much: on small scenes the search decides a few dozen obstacles in
/// all, and this lets the shortcuts reach their usual length (a larger floor buys the small
/// scenes next to no length for more post-processing time; on 512 disks the checker's guess
/// ([`MotionChecker::likely_rejected`]) spares most refused shortcuts their check).
///
/// [`MotionChecker::likely_rejected`]: riskplan_scene::motion::MotionChecker::likely_rejected
pub const SMOOTH_MIN_WORK: u64 = 250;

/// Fresh searches tried when the re-check of an unsmoothed path's timed pieces refuses
/// one of them.
pub const RAW_PATH_RETRIES: usize = 4;

impl ConnectRrt {
    /// Grows a fresh pair of trees until they connect (the path from start to goal), or
    /// `Err` with the status when `term` or the iteration cap stops it.
    #[allow(clippy::too_many_arguments)]
    fn grow(
        &self,
        p: &Problem,
        step: f64,
        ok: &EdgeCheck<'_>,
        rng: &mut ChaCha8Rng,
        term: &Termination,
        stats: &mut PlanStats,
        tree_edges: &mut Vec<(Vec<f64>, Vec<f64>)>,
        over_budget: &dyn Fn() -> bool,
    ) -> Result<Vec<Vec<f64>>, PlanStatus> {
        let ws = &p.scene.workspace;
        let mut trees = [Tree::root(p.start.clone()), Tree::root(p.goal.clone())];
        let mut a = 0usize; // the tree being extended
        let result = loop {
            if term.should_stop() {
                break Err(if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached });
            }
            if stats.iterations >= self.params.max_iterations || over_budget() {
                break Err(PlanStatus::Exhausted);
            }
            stats.iterations += 1;
            let b = 1 - a;
            let q: Vec<f64> = if rng.random_bool(self.params.goal_bias) {
                trees[b].verts[0].clone()
            } else {
                ws.lower.iter().zip(&ws.upper).map(|(&l, &u)| rng.random_range(l..=u)).collect()
            };
            let v = nearest(&trees[a].verts, &q);
            let new = steer(&trees[a].verts[v], &q, step);
            let within =
                |t: &Tree, from: usize, r: f64| self.params.path_budget.is_none_or(|d| add_up(t.risk[from], r) <= d);
            let edge = if dist(&new, &trees[a].verts[v]) == 0.0 { None } else { ok(&trees[a].verts[v], &new) };
            let Some(r) = edge.filter(|&r| within(&trees[a], v, r)) else {
                a = b;
                continue;
            };
            tree_edges.push((trees[a].verts[v].clone(), new.clone()));
            let k = trees[a].add(new.clone(), v, r);
            // connect: pull tree b towards `new`
            let mut cur = nearest(&trees[b].verts, &new);
            let mut path = None;
            loop {
                let s = steer(&trees[b].verts[cur], &new, step);
                let Some(r) = ok(&trees[b].verts[cur], &s).filter(|&r| within(&trees[b], cur, r)) else {
                    break;
                };
                tree_edges.push((trees[b].verts[cur].clone(), s.clone()));
                let reached = s == new;
                cur = trees[b].add(s, cur, r);
                // the joined path's bound: both trees' sums (`new` is the meeting vertex)
                if reached && !within(&trees[a], k, trees[b].risk[cur]) {
                    break;
                }
                if reached {
                    let mut from_a = trees[a].path_to_root(k);
                    from_a.reverse();
                    let from_b = trees[b].path_to_root(cur);
                    // `new` is the last of from_a and the first of from_b
                    from_a.extend(from_b.into_iter().skip(1));
                    if a == 1 {
                        from_a.reverse();
                    }
                    path = Some(from_a);
                    break;
                }
            }
            if let Some(path) = path {
                break Ok(path);
            }
            a = b;
        };
        stats.vertices += (trees[0].verts.len() + trees[1].verts.len()) as u64;
        result
    }
}

impl Planner for ConnectRrt {
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
        crate::static_only(p)?;
        let mut stats = match crate::begin(p, checker, term, self.params.kinematics.max_speed, t_start)? {
            crate::Begin::Plan(stats) => PlanStats { attempts: 1, ..stats },
            crate::Begin::Answered(outcome) => return Ok(outcome),
        };
        let step = self.params.step.unwrap_or_else(|| Scale::of(p).connect_step());
        let counter = CheckCounter::default();
        let work_start = counter.work(checker);
        let seg = |a: &[f64], b: &[f64]| Piece::segment(a, b, p.horizon.0, p.horizon.1);
        let budget = self.params.path_budget;
        let stop = || term.should_stop();
        // an edge's whole-path bound when accepted (0 without a budget; 1 when the checker
        // gives none: the budget then refuses it)
        let ok = |a: &[f64], b: &[f64]| {
            let piece = seg(a, b);
            (counter.check(checker, &piece) == Motion::Accepted)
                .then(|| if budget.is_some() { checker.path_risk(&piece, &stop).unwrap_or(1.0) } else { 0.0 })
                .filter(|&r| budget.is_none_or(|d| r <= d))
        };
        let within_budget = |pieces: &[Piece]| budget.is_none_or(|d| checker.path_risk_sum(pieces, &stop) <= d);
        let ws = &p.scene.workspace;
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let mut tree_edges = Vec::new();
        let mut status = PlanStatus::Exhausted;
        let direct = ok(&p.start, &p.goal).is_some();
        let mut found: Option<Vec<Vec<f64>>> = direct.then(|| vec![p.start.clone(), p.goal.clone()]);
        if found.is_none() {
            match self.grow(p, step, &ok, &mut rng, term, &mut stats, &mut tree_edges, &|| false) {
                Ok(path) => found = Some(path),
                Err(s) => status = s,
            }
        }
        // the time to the first certified path, and the work of its search: post-processing
        // may spend a multiple of that work (at least SMOOTH_MIN_WORK), deterministically
        let first = t_start.elapsed();
        let work_now = counter.work(checker);
        let search_work = work_now.saturating_sub(work_start);
        let work_budget = WorkBudget::until(
            work_now.saturating_add(search_work.saturating_mul(SMOOTH_WORK_FACTOR).max(SMOOTH_MIN_WORK)),
        );
        let mut trajectory = None;
        let mut reason = None;
        if let Some(points) = found {
            stats.time_to_feasible_s = Some(first.as_secs_f64());
            stats.feasible_path_length = Some(points.windows(2).map(|w| dist(&w[0], &w[1])).sum());
            let timed = time_at_constant_speed(&points, p.horizon);
            // a re-check of the very pieces returned (a sampling checker's re-check would
            // only redraw scenarios: skipped)
            let accept = |pieces: Vec<Piece>| {
                ((!checker.sound() || pieces.iter().all(|pc| counter.check(checker, pc) == Motion::Accepted))
                    && within_budget(&pieces))
                .then_some(pieces)
            };
            let length = |w: &[super::smooth::Waypoint]| w.windows(2).map(|x| dist(&x[0].1, &x[1].1)).sum::<f64>();
            let pieces = if self.params.kinematics.smooth {
                let t_imp = Instant::now();
                let mut sm = SmoothStats { waypoints_before: timed.len(), ..Default::default() };
                let shorten = |path, rng: &mut ChaCha8Rng, sm: &mut SmoothStats| {
                    let budget = self.params.path_budget;
                    shortcut(path, p.horizon, false, None, checker, &counter, rng, term, work_budget, budget, sm)
                };
                let mut short = shorten(timed.clone(), &mut rng, &mut sm);
                // more candidate paths (fresh trees) while the work budget lasts: the shortest
                // after shortcutting is kept (a tree may find a long way round). Bounded by
                // work, not by time, so that the same seed gives the same plan however fast
                // the machine or the front end (only the request's own deadline cuts it)
                let over = || !work_budget.left(&counter, checker);
                for _ in 1..self.params.candidates {
                    if direct || over() || term.should_stop() {
                        break;
                    }
                    let Ok(other) = self.grow(p, step, &ok, &mut rng, term, &mut stats, &mut tree_edges, &over) else {
                        break;
                    };
                    let t = time_at_constant_speed(&other, p.horizon);
                    let s = shorten(t, &mut rng, &mut sm);
                    if length(&s) < length(&short) {
                        short = s;
                    }
                }
                sm.waypoints_after = short.len();
                let short_len = length(&short);
                // the blended path; else the shortcut polyline; else the tree's path
                let limits = Limits::of(&self.params.kinematics);
                // a blended plan beyond the whole-path budget gives way to its polyline
                let blended = blend(&short, (&ws.lower, &ws.upper), limits, false, checker, &counter, &mut sm, term)
                    .filter(|b| within_budget(b));
                let out = match blended {
                    Some(b) => {
                        stats.path_length = Some(short_len);
                        Some(b)
                    }
                    None => match accept(straight(&short, &ws.lower, &ws.upper)) {
                        Some(s) => {
                            sm.corners_sharp = short.len().saturating_sub(2);
                            stats.path_length = Some(short_len);
                            Some(s)
                        }
                        None => {
                            stats.path_length = stats.feasible_path_length;
                            accept(straight(&timed, &ws.lower, &ws.upper))
                        }
                    },
                };
                stats.improve_time_s = t_imp.elapsed().as_secs_f64();
                stats.smoothing = Some(sm);
                out
            } else {
                stats.path_length = stats.feasible_path_length;
                let mut raw = accept(straight(&timed, &ws.lower, &ws.upper));
                // the re-check of the timed pieces can refuse an edge the search accepted
                // (the same segment parametrized by its own times rounds differently, and a
                // proof near the contour may not survive that): fresh trees, a few times
                let mut retries = 0;
                while raw.is_none() && retries < RAW_PATH_RETRIES && !term.should_stop() {
                    retries += 1;
                    let Ok(path) = self.grow(p, step, &ok, &mut rng, term, &mut stats, &mut tree_edges, &|| false)
                    else {
                        break;
                    };
                    stats.path_length = Some(path.windows(2).map(|w| dist(&w[0], &w[1])).sum());
                    raw = accept(straight(&time_at_constant_speed(&path, p.horizon), &ws.lower, &ws.upper));
                }
                raw
            };
            match pieces {
                Some(pieces) => {
                    let length = stats.path_length.unwrap_or(0.0);
                    // every returned piece keeps the limit (§6.8): blended pieces do by
                    // construction, the straight fallbacks at the path's speed L/T unless
                    // L/T is above it (or at it, within rounding)
                    let too_fast = |v: &f64| {
                        length > v * (p.horizon.1 - p.horizon.0) || pieces.iter().any(|pc| !within_speed(pc, *v))
                    };
                    if let Some(v) = self.params.kinematics.max_speed.filter(too_fast) {
                        reason = Some(NoPlanReason::OutOfReach {
                            distance: length,
                            max_speed: v,
                            duration: p.horizon.1 - p.horizon.0,
                        });
                    } else {
                        trajectory = Some(Trajectory::new(pieces));
                        status = PlanStatus::Exact;
                    }
                }
                None => status = PlanStatus::Exhausted,
            }
        }
        let (checked, accepted, secs) = counter.totals();
        stats.edges_checked = checked;
        stats.edges_accepted = accepted;
        stats.checker_time_s = secs;
        stats.planning_time_s = t_start.elapsed().as_secs_f64();
        let certified = trajectory.is_some() && checker.sound();
        if trajectory.is_none() && reason.is_none() {
            reason = Some(NoPlanReason::from_status(status, &stats, term));
        }
        Ok(PlanOutcome { status, trajectory, certified, stats, tree: tree_edges, reason })
    }
}
