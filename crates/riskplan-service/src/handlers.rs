//! The synchronous work behind each query (run on the blocking pool): plan, verify,
//! risk, apply. Inputs are checked here and turned into typed [`ServiceError`]s.

use super::error::{invalid, ServiceError};
use super::proto::{
    ApplyRequest, EmbeddedJson, Named, PlanReply, PlanRequest, RiskReply, RiskRequest, Segment, VerifyReply,
    VerifyRequest, MAX_GRID_SIDE, MAX_RISK_POINTS, MAX_VERIFY_PIECES,
};
use super::registry::{Entry, KernelStats, Registry};
use riskplan_app::verify::{verify_with, Detail, Method, VerifyOptions};
use riskplan_app::{self as app, PlannerKind};
use riskplan_math::contour::{BoundKind, RiskLevel};
use riskplan_scene::{Piece, Trajectory, TRAJECTORY_FORMAT};
use std::collections::BTreeMap;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn delta_of(d: Option<f64>) -> Result<Option<RiskLevel>, ServiceError> {
    d.map(|d| RiskLevel::from_f64(d).map_err(|e| invalid("delta", e.to_string()))).transpose()
}

/// The value of a closed-set field of a request, `None` when absent; a name outside the
/// set is `invalid_request` naming `field`, with the set's message ([`Named`]).
fn named<T: Copy>(value: &Option<Named<T>>, field: &str) -> Result<Option<T>, ServiceError> {
    value.as_ref().map(|n| n.get().map_err(|message| invalid(field, message))).transpose()
}

/// A plan query, typed: the flat wire `plan_request` converted once, here
/// ([`PlanQuery::from_wire`]), into what it asks for — a one-shot plan, or one step of
/// receding-horizon planning with what belongs to that alone. Nothing after the
/// conversion reads the wire request.
#[derive(Clone, Debug, PartialEq)]
pub enum PlanQuery {
    /// A plan from start to goal over the scene's horizon (`plan.receding` is `None`).
    OneShot {
        /// What to plan.
        plan: app::PlanRequest,
        /// The robot's body radius (`None`: the scene's).
        robot_radius: Option<f64>,
    },
    /// A receding-horizon step (docs/design.md §6.9): `plan.receding` holds the robot's
    /// state and window.
    Receding {
        /// What to plan.
        plan: app::PlanRequest,
        /// The robot's body radius (`None`: the scene's).
        robot_radius: Option<f64>,
        /// The robot whose last plan the server keeps and continues from.
        robot_id: Option<String>,
    },
}

impl PlanQuery {
    /// The typed query of a wire plan request, its time limit capped by `cap`; every
    /// error names the field at fault (the checks in the order they have always run:
    /// the time limit, the endpoints, the planner, certifier, Δ, pieces, risk mode, bound,
    /// then what a receding request needs and what belongs to one alone).
    pub fn from_wire(req: &PlanRequest, cap: Duration) -> Result<PlanQuery, ServiceError> {
        let time_limit = match req.time_limit {
            Some(s) => app::time_limit(s)?,
            None => app::DEFAULT_TIME_LIMIT,
        };
        let endpoints = match (&req.start, &req.goal) {
            (Some(_), _) if req.t_now.is_some() => {
                return Err(invalid("start", "a receding-horizon request starts at its position"))
            }
            (None, Some(_)) if req.t_now.is_some() => None,
            (Some(s), Some(g)) => Some((s.clone(), g.clone())),
            (None, None) => None,
            _ => {
                return Err(invalid(
                    if req.start.is_none() { "start" } else { "goal" },
                    "give both start and goal, or neither",
                ))
            }
        };
        let mut plan = app::PlanRequest {
            planner: named(&req.planner, "planner")?.unwrap_or(PlannerKind::RrtSos),
            certifier: named(&req.certifier, "certifier")?.unwrap_or(Method::Exact),
            delta: delta_of(req.delta)?,
            endpoints,
            seed: req.seed.unwrap_or(1),
            pieces: req.pieces.map(|s| usize::try_from(s).map_err(|_| invalid("pieces", "too large"))).transpose()?,
            improve: req.improve.unwrap_or(false),
            time_limit: time_limit.min(cap),
            max_speed: req.max_speed,
            max_accel: req.max_accel,
            smooth: req.smooth.unwrap_or(true),
            risk_mode: named(&req.risk_mode, "risk_mode")?.unwrap_or(app::RiskMode::PerObstacle),
            bound: named(&req.bound, "bound")?,
            receding: None,
        };
        let robot_radius = req.robot_radius;
        let Some(t_now) = req.t_now else {
            for (field, given) in [
                ("position", req.position.is_some()),
                ("velocity", req.velocity.is_some()),
                ("horizon", req.horizon.is_some()),
                ("robot_id", req.robot_id.is_some()),
                ("warm_start", req.warm_start.is_some()),
            ] {
                if given {
                    return Err(invalid(field, "belongs to a receding-horizon request: give t_now too"));
                }
            }
            return Ok(PlanQuery::OneShot { plan, robot_radius });
        };
        let position =
            req.position.clone().ok_or_else(|| invalid("position", "a receding-horizon request needs it"))?;
        let horizon = req.horizon.ok_or_else(|| invalid("horizon", "a receding-horizon request needs it"))?;
        let goal = req.goal.clone().ok_or_else(|| invalid("goal", "a receding-horizon request needs it"))?;
        let warm_start = match &req.warm_start {
            Some(p) if p.is_empty() => return Err(invalid("warm_start", "needs at least one piece")),
            Some(p) if p.len() > riskplan_scene::MAX_PIECES => {
                return Err(invalid("warm_start", format!("at most {} pieces", riskplan_scene::MAX_PIECES)))
            }
            Some(p) => Some(Arc::new(Trajectory::new(p.clone()))),
            None => None,
        };
        plan.receding =
            Some(app::RecedingRequest { t_now, position, velocity: req.velocity.clone(), horizon, goal, warm_start });
        Ok(PlanQuery::Receding { plan, robot_radius, robot_id: req.robot_id.clone() })
    }

    /// What to plan.
    pub fn plan(&self) -> &app::PlanRequest {
        match self {
            PlanQuery::OneShot { plan, .. } | PlanQuery::Receding { plan, .. } => plan,
        }
    }

    /// The robot's body radius asked for (`None`: the scene's).
    pub fn robot_radius(&self) -> Option<f64> {
        match self {
            PlanQuery::OneShot { robot_radius, .. } | PlanQuery::Receding { robot_radius, .. } => *robot_radius,
        }
    }
}

/// Replaces scene `name` or applies changes to it (an `apply` request); returns the
/// new revision.
pub fn apply(registry: &Registry, name: &str, req: ApplyRequest) -> Result<u64, ServiceError> {
    match (req.scene, req.changes) {
        (Some(EmbeddedJson(json)), None) => registry.put_scene(name, json),
        (None, Some(ch)) => registry.apply_changes(name, &ch),
        _ => Err(invalid("scene", "give exactly one of scene and changes")),
    }
}

/// Plans on a scene. `cap` bounds the time limit; `cancel` stops the planner early.
pub fn plan(
    registry: &Registry,
    entry: &Entry,
    req: &PlanRequest,
    cap: Duration,
    arrival: Instant,
    cancel: Arc<AtomicBool>,
) -> Result<PlanReply, ServiceError> {
    let query = PlanQuery::from_wire(req, cap)?;
    let robot_radius = query.robot_radius();
    let (mut request, robot_id) = match query {
        PlanQuery::OneShot { plan, .. } => (plan, None),
        PlanQuery::Receding { plan, robot_id, .. } => (plan, robot_id),
    };
    // the time limit counts from the request's arrival: queue time is spent from it
    let left = (arrival + request.time_limit).saturating_duration_since(Instant::now());
    if left.is_zero() {
        return Err(ServiceError::DeadlineExceeded("the plan's time limit passed while it waited for a worker".into()));
    }
    request.time_limit = left;
    // the robot's kept plan, unless the request sends one
    if let (Some(r), Some(id)) = (request.receding.as_mut(), robot_id.as_deref()) {
        check_robot_id(id)?;
        if r.warm_start.is_none() {
            r.warm_start = registry.robot_plan(&entry.scene.name, id);
        }
    }
    let kernel = match robot_radius {
        Some(rho) => registry.with_body(entry, rho)?,
        None => entry.kernel.clone(),
    };
    // `request.run`, in its two steps, so that whether the kernel held the scene index
    // at the plan's risk levels is seen before the planner (the metrics: `registry.kernels`)
    let mut prepared = request.prepare(&kernel)?;
    let held = prepared.kernel.peek_index(&prepared.deltas).is_some_and(|i| i.complete());
    let solved = prepared.solve(&request.termination(Some(cancel)));
    registry.kernels.covers(held);
    // the planner that ran (a receding request runs `receding` whatever it named)
    let (problem, ran, out) = (prepared.problem, prepared.kind, solved?);
    if let (Some(id), Some(t)) = (robot_id.as_deref(), out.trajectory.as_ref()) {
        registry.keep_robot_plan(&entry.scene.name, id, Arc::new(t.clone()));
    }
    // the final check's internal errors (docs/design.md §5.12): each answered by a re-plan
    if let Some(fc) = out.stats.final_check.as_ref() {
        for (n, what) in [
            (fc.disagreements, "the final check rejected a trajectory the fast edge check had accepted (planned again without the fast path)"),
            (fc.invalid, "the planner returned a trajectory that is not valid (planned again without smoothing)"),
        ] {
            #[cfg(feature = "transport")]
            if n > 0 {
                tracing::error!(scene = %entry.scene.name, planner = ran.as_str(), count = n, "internal error: {what}");
            }
            #[cfg(not(feature = "transport"))]
            let _ = (n, what);
        }
    }
    if let Some(r @ riskplan_plan::NoPlanReason::FinalCheckFailed { .. }) = &out.reason {
        #[cfg(feature = "transport")]
        tracing::error!(scene = %entry.scene.name, planner = ran.as_str(), "{}", r.message());
        #[cfg(not(feature = "transport"))]
        let _ = r;
    }
    let Some(traj) = out.trajectory else {
        return Err(ServiceError::NoPlan(app::no_plan_reason(&out, request.time_limit)));
    };
    Ok(PlanReply {
        format: TRAJECTORY_FORMAT.into(),
        pieces: traj.pieces,
        planner: ran,
        certified: out.certified,
        stats: out.stats,
        revision: entry.revision,
        scene: entry.scene.name.clone(),
        risk: problem.delta.to_f64(),
    })
}

/// A robot id: 1 to 128 characters, letters, digits, `-`, `_`, `.`.
fn check_robot_id(id: &str) -> Result<(), ServiceError> {
    if id.is_empty() || id.len() > 128 || !id.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) {
        return Err(invalid("robot_id", "1 to 128 characters: letters, digits, '-', '_', '.'"));
    }
    Ok(())
}

/// The piece of a straight segment of a verify request (`field`: where it is in the
/// request, for errors): `from` and `to` with the scene's dimension, its times within
/// the horizon (default: the horizon), checked as a one-piece trajectory.
fn segment_piece(scene: &riskplan_scene::Scene, s: &Segment, field: &str) -> Result<Piece, ServiceError> {
    if s.from.len() != scene.dim || s.to.len() != scene.dim {
        return Err(invalid(field, format!("from and to need {} coordinates", scene.dim)));
    }
    let t0 = s.t0.unwrap_or(scene.horizon.0);
    let t1 = s.t1.unwrap_or(scene.horizon.1);
    let traj = Trajectory::new(vec![Piece::segment(&s.from, &s.to, t0, t1)]);
    let diag = riskplan_scene::motion::dist(&scene.workspace.lower, &scene.workspace.upper);
    traj.validate(scene.dim, scene.horizon, diag)
        .map_err(|e| ServiceError::InvalidTrajectory { message: e.message.clone(), field: Some(field.to_string()) })?;
    Ok(traj.pieces.into_iter().next().expect("one piece"))
}

/// Verifies a trajectory, one segment or a batch of segments (each on its own), by the
/// planners' checker ([`verify_with`], docs/design.md §5.10); with `summary`, only the
/// first piece not safe gets a report.
pub fn verify_request(entry: &Entry, req: &VerifyRequest, deadline: Instant) -> Result<VerifyReply, ServiceError> {
    verify_observed(entry, req, deadline, None, 1)
}

/// The pieces of a verify request (a trajectory's, or a batch's segments), before
/// validation: what decides whether the job asks for spare workers.
pub fn verify_size(req: &VerifyRequest) -> usize {
    req.trajectory.as_ref().map_or(0, |t| t.pieces.len()) + req.segments.as_ref().map_or(0, Vec::len)
}

/// [`verify_request`], counting in `stats` (when given) whether the scene's kernel held
/// the covers at the request's risk level before the check, and after it; on `threads`
/// threads when the request has enough pieces ([`riskplan_app::verify::PARALLEL_MIN_PIECES`]).
pub fn verify_observed(
    entry: &Entry,
    req: &VerifyRequest,
    deadline: Instant,
    stats: Option<&KernelStats>,
    threads: usize,
) -> Result<VerifyReply, ServiceError> {
    let scene = &entry.scene;
    let batch = req.segments.is_some();
    let pieces: std::borrow::Cow<'_, [Piece]> = match (&req.trajectory, &req.segment, &req.segments) {
        (Some(t), None, None) => {
            if t.format != TRAJECTORY_FORMAT {
                return Err(ServiceError::InvalidTrajectory {
                    message: format!("format must be \"{TRAJECTORY_FORMAT}\""),
                    field: Some("trajectory.format".into()),
                });
            }
            let diag = riskplan_scene::motion::dist(&scene.workspace.lower, &scene.workspace.upper);
            t.validate_up_to(scene.dim, scene.horizon, diag, MAX_VERIFY_PIECES).map_err(|e| {
                ServiceError::InvalidTrajectory {
                    message: e.message.clone(),
                    field: Some(format!("trajectory.{}", e.path)),
                }
            })?;
            std::borrow::Cow::Borrowed(&t.pieces)
        }
        (None, Some(s), None) => std::borrow::Cow::Owned(vec![segment_piece(scene, s, "segment")?]),
        (None, None, Some(list)) => {
            if list.is_empty() || list.len() > MAX_VERIFY_PIECES {
                return Err(ServiceError::LimitExceeded {
                    message: format!("1 to {MAX_VERIFY_PIECES} segments, got {}", list.len()),
                    field: Some("segments".into()),
                });
            }
            let pieces: Result<Vec<Piece>, ServiceError> =
                list.iter().enumerate().map(|(i, s)| segment_piece(scene, s, &format!("segments[{i}]"))).collect();
            std::borrow::Cow::Owned(pieces?)
        }
        _ => return Err(invalid("trajectory", "give exactly one of trajectory, segment and segments")),
    };
    let delta = delta_of(req.delta)?.unwrap_or_else(|| scene.risk.clone());
    let method = named(&req.method, "method")?.unwrap_or(Method::Exact);
    let bounds = named(&req.bound, "bound")?.unwrap_or_default();
    let detail = if req.summary.unwrap_or(false) { Detail::FirstNotSafe } else { Detail::Every };
    let whole_path = req.whole_path.unwrap_or(false);
    if whole_path && batch {
        return Err(invalid("whole_path", "a batch of segments has no whole path: give a trajectory or one segment"));
    }
    if whole_path && pieces.len() > riskplan_app::verify::MAX_WHOLE_PATH_PIECES {
        return Err(ServiceError::LimitExceeded {
            message: format!(
                "whole_path takes at most {} pieces, the trajectory has {}",
                riskplan_app::verify::MAX_WHOLE_PATH_PIECES,
                pieces.len()
            ),
            field: Some("whole_path".into()),
        });
    }
    let opts = VerifyOptions { method, settings: Default::default(), bounds, detail, threads, whole_path };
    // the risk levels `verify_with` checks at (its covers' key)
    let deltas = stats.map(|_| vec![delta.clone(); scene.obstacles.len()]);
    let held = deltas.as_ref().is_some_and(|d| entry.kernel.peek_index(d).is_some_and(|i| i.complete()));
    let out = verify_with(&entry.kernel, &pieces, &delta, &opts, &|| Instant::now() >= deadline);
    if let Some(s) = stats {
        s.covers(held);
    }
    let out = out.map_err(|_| ServiceError::DeadlineExceeded(format!("verifying {} pieces", pieces.len())))?;
    let r = out.report;
    Ok(VerifyReply {
        safe: r.safe,
        method,
        risk: r.risk,
        bound: bounds,
        pieces: r.pieces,
        revision: entry.revision,
        checked: r.checked as u64,
        not_safe: r.not_safe as u64,
        first_not_safe: r.first_not_safe.map(|i| i as u64),
        not_safe_segments: if batch { out.not_safe_indices.iter().map(|&i| i as u64).collect() } else { Vec::new() },
        whole_path_risk: r.whole_path_risk,
    })
}

/// Cantelli bounds at points or on a grid (floating point, for displays).
pub fn risk(entry: &Entry, req: &RiskRequest, deadline: Instant) -> Result<RiskReply, ServiceError> {
    let scene = &entry.scene;
    let t = req.time.unwrap_or(scene.horizon.0);
    if !t.is_finite() {
        return Err(invalid("time", "must be finite"));
    }
    let points: Vec<Vec<f64>> = match (&req.points, &req.grid) {
        (Some(p), None) => {
            if p.len() > MAX_RISK_POINTS {
                return Err(ServiceError::LimitExceeded {
                    message: format!("{} points exceed the limit of {MAX_RISK_POINTS}", p.len()),
                    field: Some("points".into()),
                });
            }
            if let Some((i, _)) =
                p.iter().enumerate().find(|(_, x)| x.len() != scene.dim || x.iter().any(|v| !v.is_finite()))
            {
                return Err(invalid(&format!("points[{i}]"), format!("needs {} finite coordinates", scene.dim)));
            }
            p.clone()
        }
        (None, Some(g)) => {
            let n = g.n as usize;
            if n > MAX_GRID_SIDE {
                return Err(ServiceError::LimitExceeded {
                    message: format!(
                        "grid side {n} exceeds the limit of {MAX_GRID_SIDE} ({MAX_GRID_SIDE}² points ≤ {MAX_RISK_POINTS})"
                    ),
                    field: Some("grid.n".into()),
                });
            }
            if n < 2 || g.lower.len() != scene.dim || g.upper.len() != scene.dim || scene.dim < 2 {
                return Err(invalid(
                    "grid",
                    format!("needs n ≥ 2 and lower/upper with {} coordinates (dim ≥ 2)", scene.dim),
                ));
            }
            let mut pts = Vec::with_capacity(n * n);
            for j in 0..n {
                for i in 0..n {
                    let mut x = g.lower.clone();
                    x[0] = g.lower[0] + (g.upper[0] - g.lower[0]) * i as f64 / (n - 1) as f64;
                    x[1] = g.lower[1] + (g.upper[1] - g.lower[1]) * j as f64 / (n - 1) as f64;
                    pts.push(x);
                }
            }
            pts
        }
        _ => return Err(invalid("points", "give exactly one of points and grid")),
    };
    let bound = named(&req.bound, "bound")?.unwrap_or_default();
    let every = req.every_bound.unwrap_or(false);
    let mut per: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut by_bound: BTreeMap<String, BTreeMap<String, Vec<f64>>> = BTreeMap::new();
    let mut bounds = vec![0.0f64; points.len()];
    for o in &scene.obstacles {
        let mut all: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        let mut best = Vec::with_capacity(points.len());
        for p in &points {
            if Instant::now() >= deadline {
                return Err(ServiceError::DeadlineExceeded(format!("risk at {} points", points.len())));
            }
            let mut xt = p.clone();
            xt.push(t);
            if !bound.beyond_cantelli() && !every {
                // Cantelli's alone: no other bound to compute
                best.push(o.contour.bound_f64(&xt));
                continue;
            }
            let each = riskplan_certify::piece_bounds::point_bounds_f64(&o.contour, &xt);
            let mut b = 1.0f64;
            for (kind, v) in &each {
                if every {
                    all.entry(kind.as_str().to_string()).or_default().push(*v);
                }
                if bound.beyond_cantelli() || *kind == BoundKind::Cantelli {
                    b = b.min(*v);
                }
            }
            best.push(b);
        }
        for (b, x) in bounds.iter_mut().zip(&best) {
            *b = b.max(*x);
        }
        per.insert(o.id.clone(), best);
        if every {
            by_bound.insert(o.id.clone(), all);
        }
    }
    Ok(RiskReply { revision: entry.revision, time: t, points, bounds, obstacles: per, by_bound, bound })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::Codec;

    fn query(json: &str) -> Result<PlanQuery, ServiceError> {
        let req: PlanRequest = Codec::Json.decode(json.as_bytes()).expect("decodes");
        PlanQuery::from_wire(&req, Duration::from_secs(60))
    }

    fn field_and_message(r: Result<PlanQuery, ServiceError>) -> (String, String) {
        match r {
            Err(e) if e.code() == crate::proto::ErrorCode::InvalidRequest => {
                (e.field().unwrap_or_default(), e.to_string())
            }
            other => panic!("not invalid_request: {other:?}"),
        }
    }

    /// A name outside its set decodes and is `invalid_request` naming the field, with the
    /// set's own message; a name that is no string is no request (`malformed_payload`).
    #[test]
    fn unknown_names_are_invalid_requests_naming_the_field() {
        let (f, m) = field_and_message(query(r#"{"planner": "astar"}"#));
        assert_eq!(f, "planner");
        assert!(m.starts_with("unknown planner 'astar' (rrt-sos, rrt-sos-paper, mc-rrt,"), "{m}");
        let (f, m) = field_and_message(query(r#"{"certifier": "bogus"}"#));
        assert_eq!((f.as_str(), m.as_str()), ("certifier", "unknown method 'bogus' (expected sos, exact or both)"));
        let (f, m) = field_and_message(query(r#"{"risk_mode": "everything"}"#));
        assert_eq!(f, "risk_mode");
        assert_eq!(m, "unknown risk_mode 'everything' (per-obstacle, joint, joint-weighted, trajectory)");
        let (f, m) = field_and_message(query(r#"{"bound": "markov"}"#));
        assert_eq!((f.as_str(), m.as_str()), ("bound", "unknown bound 'markov' (expected auto or cantelli)"));
        // the checks keep their order: the time limit before the planner
        assert_eq!(field_and_message(query(r#"{"planner": "astar", "time_limit": 0}"#)).0, "time_limit");
        let e = Codec::Json.decode::<PlanRequest>(br#"{"planner": 3}"#).expect_err("not a name");
        assert_eq!(e.1.as_deref(), Some("planner"));
    }

    /// One-shot and receding requests are told apart once, with the errors of each kind.
    #[test]
    fn a_plan_request_is_one_shot_or_receding() {
        let one = query(r#"{"planner": "mc-rrt", "start": [0, 0], "goal": [1, 1], "robot_radius": 0.1}"#).unwrap();
        assert!(matches!(&one, PlanQuery::OneShot { robot_radius: Some(r), .. } if *r == 0.1));
        assert_eq!(one.plan().planner, PlannerKind::McRrt);
        assert_eq!(one.plan().endpoints, Some((vec![0.0, 0.0], vec![1.0, 1.0])));
        let step = r#"{"t_now": 0.5, "position": [0, 0], "horizon": 1, "goal": [1, 1], "robot_id": "r1"}"#;
        match query(step).unwrap() {
            PlanQuery::Receding { plan, robot_id, .. } => {
                assert_eq!(robot_id.as_deref(), Some("r1"));
                let r = plan.receding.expect("the window");
                assert_eq!((r.t_now, r.horizon, r.goal), (0.5, 1.0, vec![1.0, 1.0]));
            }
            other => panic!("not receding: {other:?}"),
        }
        assert_eq!(field_and_message(query(r#"{"horizon": 1}"#)).0, "horizon");
        assert_eq!(field_and_message(query(r#"{"t_now": 0, "position": [0, 0], "goal": [1, 1]}"#)).0, "horizon");
        assert_eq!(field_and_message(query(r#"{"t_now": 0, "start": [0, 0], "goal": [1, 1]}"#)).0, "start");
    }
}
