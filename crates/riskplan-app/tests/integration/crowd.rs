//! Robots among moving people: pedestrians certified by their Gaussian tail
//! bound, receding-horizon plans from the robot's state, a robot body. Every plan is
//! checked by oracles that share no code with what they test: `verify` (the exact
//! path), a per-instant check of the pedestrians' tail with statrs's χ² distribution,
//! and Monte Carlo audits of body contact on the obstacles themselves (not grown).

use riskplan_app::verify::{audit_trajectory, verify, AuditOptions, Method};
use riskplan_app::{PlanRequest, RecedingRequest};
use riskplan_certify::checker::SceneKernel;
use riskplan_math::contour::RiskLevel;
use riskplan_plan::{PlanError, PlanStatus};
use riskplan_scene::{Piece, Scene, Trajectory};
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::sync::Arc;
use std::time::Duration;

/// A corridor `16 × 6` with `n` pedestrians walking along it (seeded), in 2-D.
fn corridor(n: usize, seed: u64, body: f64, delta: f64) -> String {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut obs = Vec::new();
    let mut k = 0;
    while obs.len() < n && k < 10_000 {
        k += 1;
        let (x, y): (f64, f64) = (rng.random_range(-6.0..6.0), rng.random_range(-2.5..2.5));
        // clear of the robot's start
        if (x + 7.0).hypot(y) < 3.0 {
            continue;
        }
        let vx = if rng.random_bool(0.5) { 1.0 } else { -1.0 } * rng.random_range(0.5..1.2);
        let vy: f64 = rng.random_range(-0.15..0.15);
        obs.push(serde_json::json!({"id": format!("p{}", obs.len()), "pedestrian": {
            "position": [x, y], "velocity": [vx, vy], "time": 0,
            "radius": {"dist": "uniform", "low": 0.2, "high": 0.3},
            "position_std": 0.03, "velocity_std": 0.08}}));
    }
    serde_json::json!({"format": "riskplan-scene/1", "name": "corridor", "dim": 2,
        "workspace": {"lower": [-8, -3], "upper": [8, 3]}, "horizon": [0, 30], "risk": delta,
        "robot_radius": body, "obstacles": obs, "planner": {"max_speed": 1.5, "max_accel": 3.0}})
    .to_string()
}

/// The pedestrians' per-instant oracle: at `n` times of each piece, the distance from
/// the nominal centre beyond the reach must be at least κ·√s with κ from statrs's χ²
/// quantile (independent of the crate's Mills/Chernoff bounds) — then by the triangle
/// inequality the contact probability is at most Δ.
fn pedestrian_oracle(scene: &Scene, pieces: &[Piece], delta: f64, n: usize) -> Result<(), String> {
    let chi = ChiSquared::new(scene.dim as f64).unwrap();
    let kappa = chi.inverse_cdf(1.0 - delta).sqrt();
    let body = riskplan_math::poly::rational_to_f64(&scene.body);
    for o in &scene.obstacles {
        let Some(p) = &o.pedestrian else { continue };
        let f = &p.file;
        let num = |x: &riskplan_scene::Num| x.f64();
        let r_max = riskplan_math::poly::rational_to_f64(&p.r_max);
        let (sp, sv) = (f.position_std.as_ref().map_or(0.0, num), f.velocity_std.as_ref().map_or(0.0, num));
        for pc in pieces {
            for j in 0..n {
                let t = pc.t0 + (pc.t1 - pc.t0) * j as f64 / (n - 1) as f64;
                let x = pc.at(t);
                let tau = t - num(&f.time);
                let d = x
                    .iter()
                    .enumerate()
                    .map(|(i, xi)| (xi - num(&f.position[i]) - num(&f.velocity[i]) * tau).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let s = (sp * sp + sv * sv * tau * tau).sqrt();
                let need = r_max + body + kappa * s;
                if d < need * (1.0 - 1e-9) {
                    let tail = chi.sf(((d - r_max - body) / s).max(0.0).powi(2));
                    return Err(format!("{} at t = {t}: distance {d} < {need} (tail {tail:e} vs Δ {delta})", o.id));
                }
            }
        }
    }
    Ok(())
}

fn audit_ok(scene: &Scene, traj: &Trajectory, delta: f64, samples: u64) {
    let opts = AuditOptions { times_per_piece: 6, samples, seed: 11, confidence: 0.98 };
    let a = audit_trajectory(scene, traj, delta, &opts).unwrap();
    assert!(!a.exceeds(), "{}: audit exceeds Δ = {delta}: {:?}", scene.name, a.exceedances.first());
}

fn velocity_at(pc: &Piece, t: f64) -> Vec<f64> {
    pc.velocity(t)
}

/// Consecutive receding-horizon plans, as a robot runs them (0.25 s of each): every
/// plan leaves the robot's state (C¹ at the hand-over), is certified — `verify`, the
/// pedestrian oracle, a Monte Carlo audit of body contact — and makes progress.
#[test]
fn consecutive_receding_plans_are_c1_and_certified() {
    let delta = 0.05;
    let text = corridor(8, 3, 0.25, delta);
    let scene = Arc::new(Scene::from_json(&text).unwrap());
    let kernel = SceneKernel::from(scene.clone());
    let (mut x, mut v, mut t) = (vec![-7.0, 0.0], vec![0.0, 0.0], 0.0);
    let goal = vec![6.5, 0.5];
    let mut previous: Option<Arc<Trajectory>> = None;
    let samples = common_samples();
    for step in 0..6 {
        let req = PlanRequest {
            delta: Some(RiskLevel::from_f64(delta).unwrap()),
            time_limit: Duration::from_millis(200),
            seed: 1 + step,
            receding: Some(RecedingRequest {
                t_now: t,
                position: x.clone(),
                velocity: Some(v.clone()),
                horizon: 3.0,
                goal: goal.clone(),
                warm_start: previous.clone(),
            }),
            ..Default::default()
        };
        let (_, out) = req.run(&kernel, None).unwrap_or_else(|e| panic!("step {step}: {e}"));
        assert!(out.certified, "step {step}: {:?}", out.reason);
        assert!(matches!(out.status, PlanStatus::Exact | PlanStatus::Progress));
        let traj = out.trajectory.expect("a plan");
        let first = &traj.pieces[0];
        assert_eq!(first.t0, t, "step {step}: the plan starts now");
        let (x0, v0) = (first.at(t), velocity_at(first, t));
        for d in 0..2 {
            assert!((x0[d] - x[d]).abs() < 1e-9 && (v0[d] - v[d]).abs() < 1e-6, "step {step}: not C¹ at the start");
        }
        let rep = verify(&kernel, &traj, &RiskLevel::from_f64(delta).unwrap(), Method::Exact, &Default::default());
        assert!(rep.safe, "step {step}: verify refuses the plan");
        pedestrian_oracle(&scene, &traj.pieces, delta, 200).unwrap_or_else(|e| panic!("step {step}: {e}"));
        audit_ok(&scene, &traj, delta, samples);
        // run 0.25 s of it
        let t_next = (t + 0.25).min(traj.pieces.last().unwrap().t1);
        let pc = traj.pieces.iter().find(|p| p.t0 <= t_next && t_next <= p.t1).unwrap();
        x = pc.at(t_next);
        v = velocity_at(pc, t_next);
        t = t_next;
        previous = Some(Arc::new(traj));
    }
    assert!(x[0] > -7.0 + 0.3, "no progress in 1.5 s: {x:?}");
}

fn common_samples() -> u64 {
    if std::env::var("RISKPLAN_TEST_TIER").is_ok_and(|v| v == "full") {
        4_000
    } else {
        2_000
    }
}

/// With a body, the default planner's plans pass a Monte Carlo audit of body–obstacle
/// contact (sampled on the obstacles themselves) on a static, a moving and a 3-D scene;
/// a disk grows into the disk of radius r + ρ exactly.
#[test]
fn bodies_are_certified_on_static_moving_and_3d_scenes() {
    for (name, rho) in [("illustrative-3", 0.05), ("example-b-lane-change", 0.05), ("example-d2-cluttered-3d", 0.03)] {
        let path = crate::common::repo().join("scenes").join(format!("{name}.json"));
        let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        v["robot_radius"] = rho.into();
        let scene = Arc::new(Scene::from_json(&v.to_string()).unwrap_or_else(|e| panic!("{name}: {e}")));
        for o in &scene.obstacles {
            assert!(o.original.is_some(), "{name}: {} kept its original", o.id);
        }
        let req = PlanRequest { time_limit: Duration::from_secs(20), ..Default::default() };
        let (_, out) = req.run(&scene, None).unwrap_or_else(|e| panic!("{name}: {e}"));
        let traj = out.trajectory.unwrap_or_else(|| panic!("{name}: no plan: {:?}", out.reason));
        assert!(out.certified);
        audit_ok(&scene, &traj, scene.risk_f64(), common_samples());
    }
    // the disk case: exactly the disk of radius r + ρ
    let path = crate::common::repo().join("scenes/example-b-lane-change.json");
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    v["robot_radius"] = "1/4".into();
    let grown = Scene::from_json(&v.to_string()).unwrap();
    let mut w = v.clone();
    w.as_object_mut().unwrap().remove("robot_radius");
    w["obstacles"][0]["poly"] = "(0.3 + 1/4)^2 - (x1 - (t + 0.4 + w1))^2 - (x2 - 1)^2".into();
    let by_hand = Scene::from_json(&w.to_string()).unwrap();
    assert_eq!(*grown.obstacles[0].poly, *by_hand.obstacles[0].poly);
}

/// Without its body the audit of a plan made for a point robot finds contact above Δ
/// near a pedestrian the plan grazes: the body audit is not vacuous.
#[test]
fn a_point_robot_plan_fails_the_body_audit() {
    let text = serde_json::json!({"format": "riskplan-scene/1", "name": "graze", "dim": 2,
        "workspace": {"lower": [-4, -2], "upper": [4, 2]}, "horizon": [0, 4], "risk": 0.05,
        "obstacles": [{"id": "p", "pedestrian": {"position": [0, 0], "velocity": [0, 0], "time": 0,
            "radius": 0.3, "position_std": 0.05, "velocity_std": 0.0}}]})
    .to_string();
    let point = Scene::from_json(&text).unwrap();
    // a straight pass at the point robot's Δ-radius (0.3 + 2.45·0.05 ≈ 0.42) plus a little
    let traj = Trajectory::new(vec![Piece::segment(&[-3.0, 0.45], &[3.0, 0.45], 0.0, 4.0)]);
    let rep = verify(&point, &traj, &RiskLevel::from_f64(0.05).unwrap(), Method::Exact, &Default::default());
    assert!(rep.safe);
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["robot_radius"] = 0.2.into();
    let bodied = Scene::from_json(&v.to_string()).unwrap();
    let rep = verify(&bodied, &traj, &RiskLevel::from_f64(0.05).unwrap(), Method::Exact, &Default::default());
    assert!(!rep.safe, "the body makes the pass unsafe");
    let opts = AuditOptions { times_per_piece: 20, samples: 20_000, seed: 3, confidence: 0.98 };
    let a = audit_trajectory(&bodied, &traj, 0.05, &opts).unwrap();
    assert!(a.exceeds(), "the body audit sees the contact: max {}", a.max_estimate);
}

/// Bad receding requests and bodies get typed errors naming the field.
#[test]
fn bad_receding_input_is_a_typed_error() {
    let text = corridor(4, 5, 0.25, 0.05);
    let scene = Arc::new(Scene::from_json(&text).unwrap());
    let base = RecedingRequest {
        t_now: 0.0,
        position: vec![-7.0, 0.0],
        velocity: None,
        horizon: 3.0,
        goal: vec![6.0, 0.0],
        warm_start: None,
    };
    let run = |r: RecedingRequest| PlanRequest { receding: Some(r), ..Default::default() }.run(&scene, None).err();
    let field = |e: Option<PlanError>| match e {
        Some(PlanError::InvalidRequest { field, .. }) => field,
        Some(PlanError::UnsafeEndpoint { which, .. }) | Some(PlanError::OutsideWorkspace { which, .. }) => which,
        other => format!("{other:?}"),
    };
    assert_eq!(field(run(RecedingRequest { t_now: 31.0, ..base.clone() })), "t_now");
    assert_eq!(field(run(RecedingRequest { t_now: -1.0, ..base.clone() })), "t_now");
    assert_eq!(field(run(RecedingRequest { horizon: 0.0, ..base.clone() })), "horizon");
    assert_eq!(field(run(RecedingRequest { velocity: Some(vec![5.0, 0.0]), ..base.clone() })), "velocity");
    assert_eq!(field(run(RecedingRequest { position: vec![-9.0, 0.0], ..base.clone() })), "position");
    // inside a pedestrian's contour
    let p0 = &scene.obstacles[0].pedestrian.as_ref().unwrap().file;
    let at = vec![p0.position[0].f64(), p0.position[1].f64()];
    assert_eq!(field(run(RecedingRequest { position: at, ..base.clone() })), "position");
    // a planner that does not plan receding requests
    let other = PlanRequest { receding: Some(base), planner: riskplan_plan::PlannerKind::TvSos, ..Default::default() };
    assert!(matches!(other.run(&scene, None), Err(PlanError::InvalidOption { .. })));
    // a body that does not fit, a negative one, a bad template
    for (edit, path) in [
        (serde_json::json!({"robot_radius": 3.5}), "robot_radius"),
        (serde_json::json!({"robot_radius": -0.1}), "robot_radius"),
    ] {
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["robot_radius"] = edit["robot_radius"].clone();
        let e = Scene::from_json(&v.to_string()).unwrap_err();
        assert_eq!(e.path, path, "{e}");
    }
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["obstacles"][1]["pedestrian"]["velocity_std"] = (-0.1).into();
    assert_eq!(Scene::from_json(&v.to_string()).unwrap_err().path, "obstacles[1].pedestrian.velocity_std");
    v["obstacles"][1]["pedestrian"]["velocity_std"] = 0.1.into();
    v["obstacles"][1]["pedestrian"]["radius"] = serde_json::json!({"dist": "normal", "mean": 0.3, "std": 0.1});
    assert_eq!(Scene::from_json(&v.to_string()).unwrap_err().path, "obstacles[1].pedestrian.radius");
    v["obstacles"][1]["pedestrian"]["radius"] = 0.3.into();
    v["obstacles"][1]["poly"] = "1 - x1^2".into();
    assert_eq!(Scene::from_json(&v.to_string()).unwrap_err().path, "obstacles[1]");
}

/// A pedestrian updated in a scene of many: the new revision rebuilds only it; the
/// others' contours, covers and the plan's answers are those of a scene built afresh.
#[test]
fn an_update_rebuilds_only_the_updated_pedestrian() {
    let text = corridor(20, 9, 0.0, 0.05);
    let file: riskplan_scene::SceneFile = serde_json::from_str(&text).unwrap();
    let cache = riskplan_scene::ContourCache::default();
    let s1 = Scene::from_file_cached(file.clone(), &cache).unwrap();
    let mut f2 = file.clone();
    f2.obstacles[4].pedestrian.as_mut().unwrap().position[0] =
        riskplan_scene::Num(num_rational::BigRational::from_float(0.5).unwrap());
    let s2 = Scene::from_file_reusing(f2.clone(), &cache, Some(&s1)).unwrap();
    for (i, (a, b)) in s1.obstacles.iter().zip(&s2.obstacles).enumerate() {
        let same = Arc::ptr_eq(a.pedestrian.as_ref().unwrap(), b.pedestrian.as_ref().unwrap());
        assert_eq!(same, i != 4, "obstacle {i}");
    }
    // the successor kernel answers as a fresh one on random segments
    let k1 = SceneKernel::from(Arc::new(s1));
    let d = vec![RiskLevel::from_f64(0.05).unwrap(); 20];
    let _ = k1.index(&d, &|| false);
    let s2 = Arc::new(s2);
    let k2 = k1.successor(s2.clone());
    let fresh = SceneKernel::from(Arc::new(Scene::from_file(f2).unwrap()));
    use rand::{Rng, SeedableRng};
    use riskplan_plan::MotionChecker;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let c2 = riskplan_certify::checker::SceneCertifier::with_deltas(&k2, d.clone(), Method::Exact);
    let cf = riskplan_certify::checker::SceneCertifier::with_deltas(&fresh, d, Method::Exact);
    for _ in 0..300 {
        let a = [rng.random_range(-8.0..8.0), rng.random_range(-3.0..3.0)];
        let b = [rng.random_range(-8.0..8.0), rng.random_range(-3.0..3.0)];
        let t0 = rng.random_range(0.0..25.0);
        let pc = Piece::segment(&a, &b, t0, t0 + rng.random_range(0.1..2.0));
        assert_eq!(c2.check(&pc), cf.check(&pc), "{pc:?}");
    }
}

/// A warm start whose first piece begins after `t_now` must not make a plan — nothing
/// would prove the robot safe before it. A pedestrian crosses the robot's position at
/// t ≈ 3; a constant warm piece on [5, 10] there is safe, the robot waiting at (3, 0) from
/// 0 to 5 is not.
#[test]
fn a_warm_start_that_begins_later_certifies_nothing_before_it() {
    let text = serde_json::json!({"format": "riskplan-scene/1", "name": "late", "dim": 2,
        "workspace": {"lower": [-8, -3], "upper": [8, 3]}, "horizon": [0, 30], "risk": 0.05,
        "obstacles": [{"id": "p", "pedestrian": {"position": [0, 0], "velocity": [1, 0], "time": 0,
            "radius": 0.3, "position_std": 0.01}}]})
    .to_string();
    let scene = Arc::new(Scene::from_json(&text).unwrap());
    let warm = Trajectory::new(vec![Piece::segment(&[3.0, 0.0], &[3.0, 0.0], 5.0, 10.0)]);
    let req = PlanRequest {
        time_limit: Duration::from_millis(300),
        receding: Some(RecedingRequest {
            t_now: 0.0,
            position: vec![3.0, 0.0],
            velocity: None,
            horizon: 10.0,
            goal: vec![3.0, 0.0],
            warm_start: Some(Arc::new(warm)),
        }),
        ..Default::default()
    };
    let (_, out) = req.run(&scene, None).unwrap();
    if let Some(t) = &out.trajectory {
        assert!(out.certified);
        assert_eq!(t.pieces[0].t0, 0.0, "the plan starts now");
        // whatever it is, it is certified from t_now: the oracle and verify agree
        pedestrian_oracle(&scene, &t.pieces, 0.05, 400).unwrap();
        let rep = verify(&scene, t, &RiskLevel::from_f64(0.05).unwrap(), Method::Exact, &Default::default());
        assert!(rep.safe);
    }
}
