//! The synchronous work behind each query (run on the blocking pool): plan, verify,
//! risk. Inputs are checked here and turned into typed [`ServiceError`]s.

use super::error::{invalid, ServiceError};
use super::proto::{
    PlanReply, PlanRequest, RiskReply, RiskRequest, VerifyReply, VerifyRequest, MAX_GRID_SIDE, MAX_RISK_POINTS,
};
use super::registry::Entry;
use crate::plan::{McChecker, McCheckerParams, MotionChecker, PlanStatus, Problem, Termination};
use crate::scene::{Piece, Trajectory, TRAJECTORY_FORMAT};
use crate::verify::{verify, Method, SceneCertifier};
use num_rational::BigRational;
use std::collections::BTreeMap;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// Default plan time limit (seconds) when the request gives none.
pub const DEFAULT_PLAN_SECONDS: f64 = 10.0;

fn delta_of(entry: &Entry, d: Option<f64>) -> Result<BigRational, ServiceError> {
    match d {
        None => Ok(entry.scene.risk.clone()),
        Some(d) if d > 0.0 && d < 1.0 => {
            crate::poly::f64_shortest_decimal(d).ok_or_else(|| invalid("delta", "must be finite"))
        }
        Some(d) => Err(invalid("delta", format!("the risk level Δ must be in (0, 1), got {d}"))),
    }
}

fn method_of(m: Option<&str>, field: &str) -> Result<Method, ServiceError> {
    m.unwrap_or("exact").parse().map_err(|e: String| invalid(field, e))
}

/// Plans on a scene. `cap` bounds the time limit; `cancel` stops the planner early.
pub fn plan(entry: &Entry, req: &PlanRequest, cap: f64, cancel: Arc<AtomicBool>) -> Result<PlanReply, ServiceError> {
    let scene = entry.scene.clone();
    let limit = req.time_limit.unwrap_or(DEFAULT_PLAN_SECONDS);
    if !(limit > 0.0 && limit.is_finite()) {
        return Err(invalid("time_limit", format!("must be a positive number of seconds, got {limit}")));
    }
    let limit = limit.min(cap);
    let planner_name = req.planner.clone().unwrap_or_else(|| "rrt-sos".into());
    let mut problem = match (&req.start, &req.goal) {
        (Some(s), Some(g)) => Problem {
            scene: scene.clone(),
            start: s.clone(),
            goal: g.clone(),
            horizon: scene.horizon,
            delta: scene.risk.clone(),
            seed: 1,
        },
        (None, None) => Problem::from_scene(scene.clone(), 1).map_err(ServiceError::Plan)?,
        _ => {
            return Err(invalid(
                if req.start.is_none() { "start" } else { "goal" },
                "give both start and goal, or neither",
            ))
        }
    };
    problem.seed = req.seed.unwrap_or(1);
    problem.delta = delta_of(entry, req.delta)?;
    let pieces = req.pieces.map(|s| usize::try_from(s).map_err(|_| invalid("pieces", "too large"))).transpose()?;
    let mut planner =
        crate::plan::rrt_planner(&problem, pieces, req.improve.unwrap_or(false)).map_err(|e| match e {
            crate::plan::PlanError::InvalidOption { option, message } => invalid(&option, message),
            other => ServiceError::Plan(other),
        })?;
    let checker: Box<dyn MotionChecker> = match planner_name.as_str() {
        "rrt-sos" => Box::new(SceneCertifier::new(
            scene.clone(),
            problem.delta.clone(),
            method_of(req.certifier.as_deref(), "certifier")?,
        )),
        "mc-rrt" => {
            let model =
                scene.mc_model().map_err(|e| invalid("planner", format!("mc-rrt needs sampleable parameters: {e}")))?;
            Box::new(McChecker::new(
                model,
                crate::poly::rational_to_f64(&problem.delta),
                McCheckerParams::default(),
                problem.seed,
            ))
        }
        other => return Err(invalid("planner", format!("unknown planner '{other}' (rrt-sos or mc-rrt)"))),
    };
    let term = Termination::after(Duration::from_secs_f64(limit)).with_cancel(cancel);
    let out = planner.solve(&problem, checker.as_ref(), &term).map_err(|e| match e {
        crate::plan::PlanError::InvalidOption { option, message } => invalid(&option, message),
        other => ServiceError::Plan(other),
    })?;
    let Some(traj) = out.trajectory else {
        let why = match out.status {
            PlanStatus::DeadlineReached => format!("no plan within the time limit of {limit} s"),
            PlanStatus::Cancelled => "the plan was cancelled".into(),
            _ => "no plan within the planner's iteration limits".into(),
        };
        return Err(ServiceError::NoPlan(format!(
            "{why} ({} iterations, {} edges checked)",
            out.stats.iterations, out.stats.edges_checked
        )));
    };
    Ok(PlanReply {
        format: TRAJECTORY_FORMAT.into(),
        pieces: traj.pieces,
        planner: planner_name,
        certified: out.certified,
        stats: out.stats,
        revision: entry.revision,
        scene: scene.name.clone(),
        risk: crate::poly::rational_to_f64(&problem.delta),
    })
}

/// Verifies a trajectory or one segment.
pub fn verify_request(entry: &Entry, req: &VerifyRequest) -> Result<VerifyReply, ServiceError> {
    let scene = &entry.scene;
    let traj = match (&req.trajectory, &req.segment) {
        (Some(t), None) => {
            if t.format != TRAJECTORY_FORMAT {
                return Err(ServiceError::InvalidTrajectory {
                    message: format!("format must be \"{TRAJECTORY_FORMAT}\""),
                    field: Some("trajectory.format".into()),
                });
            }
            t.clone()
        }
        (None, Some(s)) => {
            if s.from.len() != scene.dim || s.to.len() != scene.dim {
                return Err(invalid("segment", format!("from and to need {} coordinates", scene.dim)));
            }
            let t0 = s.t0.unwrap_or(scene.horizon.0);
            let t1 = s.t1.unwrap_or(scene.horizon.1);
            Trajectory::new(vec![Piece::segment(&s.from, &s.to, t0, t1)])
        }
        _ => return Err(invalid("trajectory", "give exactly one of trajectory and segment")),
    };
    let diag = crate::plan::dist(&scene.workspace.lower, &scene.workspace.upper);
    traj.validate(scene.dim, scene.horizon, diag).map_err(|e| ServiceError::InvalidTrajectory {
        message: e.message.clone(),
        field: Some(format!("trajectory.{}", e.path)),
    })?;
    let delta = delta_of(entry, req.delta)?;
    let method = method_of(req.method.as_deref(), "method")?;
    let r = verify(scene, &traj, &delta, method, &Default::default());
    Ok(VerifyReply { safe: r.safe, method: r.method, risk: r.risk, pieces: r.pieces, revision: entry.revision })
}

/// Cantelli bounds at points or on a grid (floating point, for displays).
pub fn risk(entry: &Entry, req: &RiskRequest) -> Result<RiskReply, ServiceError> {
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
                    message: format!("grid side {n} exceeds the limit of {MAX_GRID_SIDE}"),
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
    let mut per: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut bounds = vec![0.0f64; points.len()];
    for o in &scene.obstacles {
        let v: Vec<f64> = points
            .iter()
            .map(|p| {
                let mut xt = p.clone();
                xt.push(t);
                o.contour.bound_f64(&xt)
            })
            .collect();
        for (b, x) in bounds.iter_mut().zip(&v) {
            *b = b.max(*x);
        }
        per.insert(o.id.clone(), v);
    }
    Ok(RiskReply { revision: entry.revision, time: t, points, bounds, obstacles: per })
}
