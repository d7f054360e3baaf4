//! Receding-horizon planning (docs/design.md §6.9): from the robot's current state — a
//! time `t_now`, a position and a velocity — a certified trajectory on
//! `[t_now, t_now + H]` towards a goal, C¹ at the start (it leaves with the given
//! velocity), within the speed and acceleration limits. It ends at the goal, at rest,
//! when the goal is reachable within the window; otherwise at the end point of best
//! progress, the vertex whose Euclidean distance to the goal is smallest (among the
//! vertices that last the whole window, when there are any).
//!
//! The search is a beam search, then a kinodynamic tree, over states `(x, v, t)`: every edge is a piece of
//! constant acceleration over a fixed duration `H / steps` (C¹ by construction; its
//! acceleration is bounded exactly by the limit; its speed, convex along the piece, is
//! largest at an end), certified by the motion checker like every edge of every planner.
//! From each new vertex the goal is tried with a cubic Hermite piece that arrives at rest.
//! A previous plan (the warm start) that still holds from `t_now` is certified piece by
//! piece and grafted onto the tree first. It is an anytime planner: at the deadline it
//! answers with the best progress found so far.

use super::path::{taylor_shift, within_speed};
use super::{
    check_endpoints_receding, Built, CheckCounter, MotionChecker, PlanError, PlanOutcome, PlanStats, PlanStatus,
    Planner, PlannerSpec, Problem, Progress, Termination,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use riskplan_certify::checker::SceneCertifier;
use riskplan_scene::motion::{dist, Motion};
use riskplan_scene::Piece;
use std::time::Instant;

/// `receding`: the receding-horizon planner, every edge certified by the scene certifier.
pub static SPEC: PlannerSpec = PlannerSpec {
    certified: true,
    build: |s| {
        let k = s.kinematics();
        k.validate()?;
        Ok(Built {
            planner: Box::new(Receding { params: RecedingParams::default(), kinematics: limits(s.problem, k)? }),
            checker: Box::new(
                SceneCertifier::with_deltas(s.kernel, s.deltas.to_vec(), s.options.certifier)
                    .with_bounds(s.options.bounds),
            ),
        })
    },
    paper_runs: |_| Vec::new(),
};

/// Edges per window: each tree edge lasts `H / STEPS` (docs/design.md §6.9).
pub const STEPS: usize = 8;

/// Probability that a sample is the goal itself.
pub const GOAL_BIAS: f64 = 0.2;

/// States kept per layer by the beam search (docs/design.md §6.9).
pub const BEAM: usize = 6;

/// A motion primitive of the beam search: a target velocity for the next edge, relative
/// to the goal's direction (the edge accelerates towards it within the limit).
#[derive(Clone, Debug)]
enum Primitive {
    /// Towards the goal at this share of the speed limit, never past the goal within
    /// the edge.
    Goal(f64),
    /// Along the goal's direction turned by `turn` ([`turned`]) at this share of the
    /// speed limit.
    Turned(Vec<f64>, f64),
    /// Keep the current velocity.
    Coast,
    /// Brake towards rest.
    Stop,
}

impl Primitive {
    /// The target velocity from a state of velocity `v` whose unit direction to the goal
    /// is `dir`; `reach` is the speed that arrives at the goal at the edge's end.
    fn target(&self, dir: &[f64], v: &[f64], speed: f64, reach: f64) -> Vec<f64> {
        match self {
            Primitive::Goal(share) => dir.iter().map(|c| c * (share * speed).min(reach)).collect(),
            Primitive::Turned(turn, share) => turned(turn, dir).iter().map(|c| c * share * speed).collect(),
            Primitive::Coast => v.to_vec(),
            Primitive::Stop => vec![0.0; v.len()],
        }
    }
}

/// The unit vector `d` turned by `turn`: in 2-D `turn = [cos, sin]` rotates it; in other
/// dimensions `turn` is a perturbation added to it, renormalised.
fn turned(turn: &[f64], d: &[f64]) -> Vec<f64> {
    if d.len() == 2 && turn.len() == 2 {
        vec![d[0] * turn[0] - d[1] * turn[1], d[0] * turn[1] + d[1] * turn[0]]
    } else {
        let v: Vec<f64> = d.iter().zip(turn).map(|(a, b)| a + b).collect();
        let n = norm(&v).max(f64::MIN_POSITIVE);
        v.iter().map(|c| c / n).collect()
    }
}

/// Shares of the speed limit the primitives move at.
pub const PRIMITIVE_SPEEDS: [f64; 2] = [1.0, 0.5];

/// The primitives (docs/design.md §6.9): towards the goal, and (2-D) its direction turned
/// by ±30°, ±60°, ±90°, ±135°, 180° — otherwise twelve random perturbations of it — at
/// each of [`PRIMITIVE_SPEEDS`]; then coasting and braking.
fn primitives(dim: usize, rng: &mut ChaCha8Rng) -> Vec<Primitive> {
    let turns: Vec<Vec<f64>> = if dim == 2 {
        [30.0f64, -30.0, 60.0, -60.0, 90.0, -90.0, 135.0, -135.0, 180.0]
            .iter()
            .map(|deg| vec![deg.to_radians().cos(), deg.to_radians().sin()])
            .collect()
    } else {
        (0..12)
            .map(|k| {
                let scale = 0.5 * (1 + k / 4) as f64;
                (0..dim).map(|_| scale * rng.random_range(-1.0..1.0)).collect()
            })
            .collect()
    };
    let mut out = Vec::new();
    for share in PRIMITIVE_SPEEDS {
        out.push(Primitive::Goal(share));
        out.extend(turns.iter().map(|t| Primitive::Turned(t.clone(), share)));
    }
    out.push(Primitive::Coast);
    out.push(Primitive::Stop);
    out
}

/// Most vertices of the tree (a bound on memory; the deadline usually comes first).
pub const MAX_VERTICES: usize = 20_000;

/// The default speed limit when neither the request nor the scene gives one: the
/// workspace's diagonal over the scene's horizon (derived, not absolute).
pub fn default_speed(p: &Problem) -> f64 {
    let ws = &p.scene.workspace;
    let diag = ws.lower.iter().zip(&ws.upper).map(|(l, u)| (u - l) * (u - l)).sum::<f64>().sqrt();
    diag / (p.scene.horizon.1 - p.scene.horizon.0)
}

/// The default acceleration limit: the speed limit reached from rest in a quarter of the
/// window.
pub fn default_accel(v: f64, window: f64) -> f64 {
    v / (0.25 * window)
}

/// Parameters of the receding-horizon search.
#[derive(Clone, Debug, PartialEq)]
pub struct RecedingParams {
    /// Edges per window.
    pub steps: usize,
    /// Probability of sampling the goal.
    pub goal_bias: f64,
    /// Most vertices.
    pub max_vertices: usize,
    /// States kept per layer by the beam search.
    pub beam: usize,
}

impl Default for RecedingParams {
    fn default() -> Self {
        RecedingParams { steps: STEPS, goal_bias: GOAL_BIAS, max_vertices: MAX_VERTICES, beam: BEAM }
    }
}

/// The speed and acceleration limits of a receding plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Speed limit.
    pub speed: f64,
    /// Acceleration limit.
    pub accel: f64,
}

fn limits(p: &Problem, k: super::Kinematics) -> Result<Limits, PlanError> {
    let speed = k.max_speed.unwrap_or_else(|| default_speed(p));
    let accel = k.max_accel.unwrap_or_else(|| default_accel(speed, p.horizon.1 - p.horizon.0));
    if !(speed > 0.0 && speed.is_finite() && accel > 0.0 && accel.is_finite()) {
        return Err(PlanError::InvalidOption {
            option: "max_speed".into(),
            message: "must be a positive number".into(),
        });
    }
    Ok(Limits { speed, accel })
}

/// The receding-horizon planner.
pub struct Receding {
    /// Search parameters.
    pub params: RecedingParams,
    /// Limits.
    pub kinematics: Limits,
}

#[derive(Clone, Debug)]
struct Vertex {
    x: Vec<f64>,
    v: Vec<f64>,
    t: f64,
    parent: Option<usize>,
    piece: Option<Piece>,
}

/// A piece on `[t0, t0 + h]` given by its coefficients in local time `s = t − t0`, in
/// absolute time (the trajectory format's).
fn from_local(t0: f64, t1: f64, local: &[Vec<f64>]) -> Piece {
    Piece { t0, t1, coeffs: local.iter().map(|row| taylor_shift(row, -t0)).collect() }
}

/// Position and velocity of a piece at `t`.
fn state_at(pc: &Piece, t: f64) -> (Vec<f64>, Vec<f64>) {
    (pc.at(t), pc.velocity(t))
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Relative allowance on the limits for the rounding of the expanded coefficients.
const LIMIT_SLACK: f64 = 1e-9;

impl Receding {
    /// The constant-acceleration piece from `(x, v)` at `t0` over `h` towards velocity
    /// `vd` (acceleration clipped to the limit, end speed to the speed limit).
    fn accelerate(&self, x: &[f64], v: &[f64], t0: f64, t1: f64, vd: &[f64]) -> Piece {
        let lim = self.kinematics;
        let h = t1 - t0;
        let mut a: Vec<f64> = vd.iter().zip(v).map(|(d, v)| (d - v) / h).collect();
        let an = norm(&a);
        if an > lim.accel {
            a.iter_mut().for_each(|c| *c *= lim.accel / an);
        }
        // the end speed: |v + a h| ≤ speed (v is within it; shrink a along itself)
        let mut s = 1.0;
        for _ in 0..40 {
            let v1: Vec<f64> = v.iter().zip(&a).map(|(v, a)| v + s * a * h).collect();
            if norm(&v1) <= lim.speed * (1.0 - LIMIT_SLACK) {
                break;
            }
            s *= 0.8;
        }
        let local: Vec<Vec<f64>> = x.iter().zip(v).zip(&a).map(|((&x, &v), &a)| vec![x, v, 0.5 * s * a]).collect();
        from_local(t0, t1, &local)
    }

    /// The cubic Hermite piece from `(x, v)` at `t0` to the goal at rest at `t0 + h`, when
    /// within the limits (its acceleration is affine in time: largest at an end).
    fn arrive(&self, x: &[f64], v: &[f64], t0: f64, h: f64, goal: &[f64]) -> Option<Piece> {
        let lim = self.kinematics;
        // x(s) = x + v s + c2 s² + c3 s³, x(h) = g, x'(h) = 0
        let mut local = Vec::with_capacity(x.len());
        let (mut a0, mut a1) = (0.0, 0.0);
        for ((&x, &v), &g) in x.iter().zip(v).zip(goal) {
            let d = g - x;
            let c2 = (3.0 * d - 2.0 * v * h) / (h * h);
            let c3 = (v * h - 2.0 * d) / (h * h * h);
            a0 += (2.0 * c2).powi(2);
            a1 += (2.0 * c2 + 6.0 * c3 * h).powi(2);
            local.push(vec![x, v, c2, c3]);
        }
        if a0.sqrt().max(a1.sqrt()) > lim.accel * (1.0 + LIMIT_SLACK) {
            return None;
        }
        let pc = from_local(t0, t0 + h, &local);
        within_speed(&pc, lim.speed * (1.0 + LIMIT_SLACK)).then_some(pc)
    }

    fn path(verts: &[Vertex], mut i: usize) -> Vec<Piece> {
        let mut pieces = Vec::new();
        while let Some(p) = verts[i].parent {
            if let Some(pc) = &verts[i].piece {
                pieces.push(pc.clone());
            }
            i = p;
        }
        pieces.reverse();
        pieces
    }
}

impl Planner for Receding {
    fn name(&self) -> &'static str {
        "receding"
    }

    fn solve(
        &mut self,
        p: &Problem,
        checker: &dyn MotionChecker,
        term: &Termination,
    ) -> Result<PlanOutcome, PlanError> {
        let started = Instant::now();
        check_endpoints_receding(p, checker)?;
        let lim = self.kinematics;
        let dim = p.scene.dim;
        let v0 = p.start_velocity.clone().unwrap_or_else(|| vec![0.0; dim]);
        if v0.len() != dim || v0.iter().any(|c| !c.is_finite()) {
            return Err(PlanError::InvalidRequest {
                field: "velocity".into(),
                message: format!("needs {dim} finite coordinates"),
            });
        }
        if norm(&v0) > lim.speed * (1.0 + LIMIT_SLACK) {
            return Err(PlanError::InvalidRequest {
                field: "velocity".into(),
                message: format!("speed {} exceeds max_speed {}", norm(&v0), lim.speed),
            });
        }
        let mut stats = PlanStats { checker: checker.name().to_string(), seed: p.seed, ..Default::default() };
        if term.should_stop() {
            let status = if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::DeadlineReached };
            let reason = super::NoPlanReason::from_status(status, &stats, term);
            return Ok(PlanOutcome::no_plan(status, stats, reason));
        }
        checker.prepare(term);
        let (t_now, t_end) = p.horizon;
        let h = (t_end - t_now) / self.params.steps as f64;
        let counter = CheckCounter::default();
        let goal = p.goal.clone();
        let mut verts = vec![Vertex { x: p.start.clone(), v: v0.clone(), t: t_now, parent: None, piece: None }];
        let mut reached: Option<Vec<Piece>> = None;
        // the last vertex of the warm start's chain (0: none)
        let mut warm_end = 0usize;
        // the warm start: the previous plan from t_now on, if it starts here
        if let Some(prev) = &p.warm_start {
            let mut at = 0usize;
            for pc in prev.pieces.iter().filter(|pc| pc.t1 > t_now) {
                let mut pc = pc.clone();
                if pc.t0 < t_now {
                    pc.t0 = t_now;
                }
                // contiguous from t_now: the first piece covers t_now, each next one starts
                // where the chain ends (nothing before a piece is certified by it)
                if pc.t0 != verts[at].t {
                    break;
                }
                if at == 0 {
                    let (x, v) = state_at(&pc, t_now);
                    let tol = 1e-6 * (1.0 + norm(&p.start));
                    if dist(&x, &p.start) > tol || dist(&v, &v0) > 1e-6 * (1.0 + lim.speed) {
                        break;
                    }
                }
                if pc.t1 > t_end || counter.check(checker, &pc) != Motion::Accepted {
                    break;
                }
                let (x, v) = state_at(&pc, pc.t1);
                verts.push(Vertex { x, v, t: pc.t1, parent: Some(at), piece: Some(pc) });
                at = verts.len() - 1;
            }
            if at > 0 && dist(&verts[at].x, &goal) <= 1e-9 * (1.0 + norm(&goal)) && norm(&verts[at].v) == 0.0 {
                reached = Some(Self::path(&verts, at));
            }
            warm_end = at;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let ws = &p.scene.workspace;
        let mut iterations = 0u64;
        // the goal straight from the root first
        let try_goal = |i: usize, verts: &[Vertex], counter: &CheckCounter| -> Option<Piece> {
            let vx = &verts[i];
            let d = dist(&vx.x, &goal);
            let base = (1.5 * d / lim.speed).max(h);
            for f in [1.0, 1.5, 2.25, 3.4, 5.0] {
                let dur = base * f;
                if vx.t + dur > t_end {
                    break;
                }
                if let Some(pc) = self.arrive(&vx.x, &vx.v, vx.t, dur, &goal) {
                    if counter.check(checker, &pc) == Motion::Accepted {
                        return Some(pc);
                    }
                }
            }
            None
        };
        if reached.is_none() {
            if let Some(pc) = try_goal(0, &verts, &counter) {
                reached = Some(vec![pc]);
            }
        }
        // the beam search over the window's layers (docs/design.md §6.9): from the
        // robot's state, then continuing the warm start's chain, each layer's best states
        // (by distance to the goal, one per cell) grow by the motion primitives
        if reached.is_none() {
            let prims = primitives(dim, &mut rng);
            let cell = (0.5 * lim.speed * h).max(f64::MIN_POSITIVE);
            let mut layer = vec![0usize];
            'layers: for k in 0..self.params.steps {
                if term.should_stop() {
                    break;
                }
                let t1 = if k + 1 == self.params.steps { t_end } else { t_now + (k + 1) as f64 * h };
                let mut children: Vec<(f64, usize)> = Vec::new();
                for &i in &layer {
                    let vx = verts[i].clone();
                    let to = dist(&vx.x, &goal);
                    let dir: Vec<f64> = if to > 0.0 {
                        vx.x.iter().zip(&goal).map(|(a, b)| (b - a) / to).collect()
                    } else {
                        let mut e = vec![0.0; dim];
                        e[0] = 1.0;
                        e
                    };
                    for prim in &prims {
                        let vd = prim.target(&dir, &vx.v, lim.speed, to / (t1 - vx.t));
                        let pc = self.accelerate(&vx.x, &vx.v, vx.t, t1, &vd);
                        iterations += 1;
                        if counter.check(checker, &pc) != Motion::Accepted {
                            continue;
                        }
                        let (x, v) = state_at(&pc, pc.t1);
                        let d = dist(&x, &goal);
                        verts.push(Vertex { x, v, t: pc.t1, parent: Some(i), piece: Some(pc) });
                        children.push((d, verts.len() - 1));
                    }
                    if term.should_stop() {
                        break;
                    }
                }
                if children.is_empty() {
                    break;
                }
                // the best child per cell, then the best cells
                children.sort_by(|a, b| a.0.total_cmp(&b.0));
                let mut seen = std::collections::HashSet::new();
                layer = children
                    .iter()
                    .filter(|(_, c)| {
                        seen.insert(verts[*c].x.iter().map(|q| (q / cell).floor() as i64).collect::<Vec<_>>())
                    })
                    .map(|&(_, c)| c)
                    .take(self.params.beam)
                    .collect();
                for &c in &layer {
                    if let Some(g) = try_goal(c, &verts, &counter) {
                        let mut path = Self::path(&verts, c);
                        path.push(g);
                        reached = Some(path);
                        break 'layers;
                    }
                }
            }
        }
        // the warm start's chain continued to the window's end (it ends one replanning
        // period short of it): a candidate beside the beam's
        if reached.is_none() && warm_end > 0 && verts[warm_end].t < t_end {
            if let Some(g) = try_goal(warm_end, &verts, &counter) {
                let mut path = Self::path(&verts, warm_end);
                path.push(g);
                reached = Some(path);
            }
        }
        if reached.is_none() && warm_end > 0 && verts[warm_end].t < t_end {
            let vx = verts[warm_end].clone();
            let keep = vx.v.clone();
            let stop = vec![0.0; dim];
            for vd in [&keep, &stop] {
                let pc = self.accelerate(&vx.x, &vx.v, vx.t, t_end, vd);
                iterations += 1;
                if counter.check(checker, &pc) == Motion::Accepted {
                    let (x, v) = state_at(&pc, pc.t1);
                    verts.push(Vertex { x, v, t: pc.t1, parent: Some(warm_end), piece: Some(pc) });
                    break;
                }
            }
        }
        // the random tree, only when nothing lasted the window yet (a robot replans in a
        // tenth of a second: a plan now beats a slightly better one later)
        let mut lasted = verts.iter().any(|v| v.parent.is_some() && v.t >= t_end);
        while reached.is_none() && !lasted && verts.len() < self.params.max_vertices {
            if term.should_stop() {
                break;
            }
            iterations += 1;
            let target: Vec<f64> = if rng.random_bool(self.params.goal_bias) {
                goal.clone()
            } else {
                (0..dim).map(|d| rng.random_range(ws.lower[d]..=ws.upper[d])).collect()
            };
            // the nearest vertex that can still grow, in space
            let d2 = |x: &[f64]| x.iter().zip(&target).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
            let Some((i, _)) = verts
                .iter()
                .enumerate()
                .filter(|(_, v)| v.t + h <= t_end * (1.0 + f64::EPSILON) + f64::EPSILON)
                .map(|(i, v)| (i, d2(&v.x)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
            else {
                break;
            };
            let vx = verts[i].clone();
            let to = dist(&vx.x, &target);
            let speed = match rng.random_range(0..10) {
                0 | 1 => 0.0,
                2 | 3 => rng.random_range(0.0..lim.speed),
                _ => lim.speed,
            };
            let vd: Vec<f64> = if to > 0.0 {
                vx.x.iter().zip(&target).map(|(a, b)| (b - a) / to * speed).collect()
            } else {
                vec![0.0; dim]
            };
            let t1 = if vx.t + h >= t_end { t_end } else { vx.t + h };
            let pc = self.accelerate(&vx.x, &vx.v, vx.t, t1, &vd);
            if counter.check(checker, &pc) != Motion::Accepted {
                continue;
            }
            let (x, v) = state_at(&pc, pc.t1);
            verts.push(Vertex { x, v, t: pc.t1, parent: Some(i), piece: Some(pc) });
            let n = verts.len() - 1;
            lasted = verts[n].t >= t_end;
            if let Some(g) = try_goal(n, &verts, &counter) {
                let mut path = Self::path(&verts, n);
                path.push(g);
                reached = Some(path);
            }
        }
        let (checked, accepted, secs) = counter.totals();
        stats.iterations = iterations;
        stats.vertices = verts.len() as u64;
        stats.edges_checked = checked;
        stats.edges_accepted = accepted;
        stats.checker_time_s = secs;
        let d_start = dist(&p.start, &goal);
        let (pieces, reached_goal) = match reached {
            Some(mut path) => {
                // hold at the goal until the window ends, when that is certified
                if let Some(last) = path.last() {
                    if last.t1 < t_end {
                        let hold = Piece::segment(&goal, &goal, last.t1, t_end);
                        if counter.check(checker, &hold) == Motion::Accepted {
                            path.push(hold);
                        }
                    }
                }
                (path, true)
            }
            None => {
                // best progress among the vertices that last the whole window; when none
                // does, the plan that lasts longest (a robot runs out of a short plan and
                // stops), then best progress
                let latest = verts.iter().skip(1).map(|v| v.t).fold(f64::NEG_INFINITY, f64::max);
                let best = (1..verts.len())
                    .filter(|&i| verts[i].t >= latest.min(t_end))
                    .min_by(|&a, &b| dist(&verts[a].x, &goal).total_cmp(&dist(&verts[b].x, &goal)));
                match best {
                    Some(i) => (Self::path(&verts, i), false),
                    None => (Vec::new(), false),
                }
            }
        };
        stats.planning_time_s = started.elapsed().as_secs_f64();
        if pieces.is_empty() {
            let status = if term.cancelled() { PlanStatus::Cancelled } else { PlanStatus::Exhausted };
            let reason = super::NoPlanReason::from_status(status, &stats, term);
            return Ok(PlanOutcome::no_plan(status, stats, reason));
        }
        let end = pieces.last().map(|pc| pc.at(pc.t1)).unwrap_or_default();
        let remaining = dist(&end, &goal);
        stats.path_length = Some(super::trajectory_length(&pieces));
        stats.time_to_feasible_s = Some(stats.planning_time_s);
        let progress = Progress {
            reached_goal,
            start_distance: d_start,
            remaining_distance: if reached_goal { 0.0 } else { remaining },
            end_time: pieces.last().map_or(t_now, |pc| pc.t1),
        };
        stats.progress = Some(progress);
        Ok(PlanOutcome {
            status: if reached_goal { PlanStatus::Exact } else { PlanStatus::Progress },
            trajectory: Some(riskplan_scene::Trajectory::new(pieces)),
            certified: checker.sound(),
            stats,
            tree: Vec::new(),
            reason: None,
        })
    }
}
