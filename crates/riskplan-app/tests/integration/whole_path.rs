//! The whole-path bound in `verify` (docs/design.md §5.14): with ω drawn once,
//! P(the trajectory meets an obstacle at some time) ≤ the report's `whole_path_risk`.
//! Oracle sharing no code with the bound: illustrative-3's disk ‖x‖ ≤ w, w ~ U[0.3, 0.4],
//! is met by a trajectory exactly when w ≥ d_min, its smallest distance from the origin
//! (straight pieces: in closed form), so the whole-path probability is
//! (0.4 − d_min)/0.1 clamped to [0, 1] — per piece, and for the trajectory with the
//! trajectory's d_min (not the sum over pieces).

use crate::common::{scene, size};
use riskplan_app::verify::{audit_whole_path, verify_with, AuditOptions, Detail, SceneKernel, VerifyOptions};
use riskplan_app::PlanRequest;
use riskplan_certify::whole_path::PathRiskHow;
use riskplan_scene::Piece;
use std::sync::Arc;

/// The smallest distance from the origin of the segment a → b.
fn d_min(a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let vv = dx * dx + dy * dy;
    let s = if vv > 0.0 { (-(a[0] * dx + a[1] * dy) / vv).clamp(0.0, 1.0) } else { 0.0 };
    ((a[0] + s * dx).powi(2) + (a[1] + s * dy).powi(2)).sqrt()
}

fn truth(d: f64) -> f64 {
    ((0.4 - d) / 0.1).clamp(0.0, 1.0)
}

/// A trajectory of four straight pieces that runs beside the disk (at 0.37 from its
/// centre over two pieces): each piece's bound and the whole trajectory's cover the
/// closed form, and pooling the pieces keeps the trajectory's bound below the sum of the
/// pieces' (the events of consecutive pieces beside one obstacle are nested, not added).
#[test]
fn whole_path_bounds_cover_the_closed_form_and_pool_nested_pieces() {
    let s = scene("illustrative-3");
    let delta = s.risk.clone();
    let pts = [[-0.9, -0.9], [-0.6, 0.37], [0.0, 0.37], [0.6, 0.37], [0.9, 0.9]];
    let pieces: Vec<Piece> =
        (0..4).map(|i| Piece::segment(&pts[i], &pts[i + 1], i as f64 / 4.0, (i + 1) as f64 / 4.0)).collect();
    let kernel = SceneKernel::new(Arc::new(s));
    let opts = VerifyOptions { whole_path: true, detail: Detail::FirstNotSafe, ..Default::default() };
    let report = verify_with(&kernel, &pieces, &delta, &opts, &|| false).unwrap().report;
    let w = report.whole_path_risk.expect("asked for");
    assert_eq!(w.obstacles.len(), 1);
    let o = &w.obstacles[0];
    let whole = truth((0..4).map(|i| d_min(pts[i], pts[i + 1])).fold(f64::INFINITY, f64::min));
    for (i, &b) in o.pieces.iter().enumerate() {
        let t = truth(d_min(pts[i], pts[i + 1]));
        assert!(b >= t, "piece {i}: bound {b} below the closed form {t}");
    }
    assert!(w.bound >= whole && o.bound >= whole, "trajectory: bound {} below the closed form {whole}", w.bound);
    let sum: f64 = o.pieces.iter().sum();
    println!("whole path: truth {whole:.3}, bound {:.3} ({}), pieces {:?} (sum {sum:.3})", o.bound, o.how, o.pieces);
    // the disk's radius is uniform: the partition bounds the trajectory at once, within a
    // few hundredths of the closed form, far below the sum over the pieces
    assert_eq!(o.how, PathRiskHow::Partition, "every parameter has a distribution function");
    assert!(o.bound <= whole + 0.02, "the partition is tight: {} vs the closed form {whole}", o.bound);
    assert!(o.bound < sum, "one partition beats Boole over the pieces: {} vs {sum}", o.bound);
    assert!(w.bound <= 1.0);
}

/// Without the option, no whole-path bound is computed or reported.
#[test]
fn whole_path_is_opt_in() {
    let s = scene("illustrative-3");
    let delta = s.risk.clone();
    let pieces = vec![Piece::segment(&[-0.9, 0.5], &[0.9, 0.5], 0.0, 1.0)];
    let kernel = SceneKernel::new(Arc::new(s));
    let report = verify_with(&kernel, &pieces, &delta, &VerifyOptions::default(), &|| false).unwrap().report;
    assert!(report.whole_path_risk.is_none());
    let json = serde_json::to_string(&report).unwrap();
    assert!(!json.contains("whole_path_risk"), "{json}");
}

/// example-d1's default plan (per-instant risk, Δ = 0.1): the whole-path bound of every
/// obstacle and of the trajectory is at least the seeded Monte Carlo audit of the
/// whole-path event (one draw of the 16 centre offsets per scenario, 100 times per piece;
/// the audit's lower Clopper–Pearson end at 99 %, so a sound bound fails with
/// probability ≤ 1 % per comparison at most, and the seed is fixed).
#[test]
fn whole_path_bound_covers_the_audit_on_d1() {
    let s = Arc::new(scene("example-d1-cluttered-2d"));
    let delta = s.risk.clone();
    let (_, out) = PlanRequest::default().run(s.clone(), None).unwrap();
    let traj = out.trajectory.expect("a plan");
    let kernel = SceneKernel::new(s.clone());
    let opts = VerifyOptions { whole_path: true, detail: Detail::FirstNotSafe, ..Default::default() };
    let t = std::time::Instant::now();
    let report = verify_with(&kernel, &traj.pieces, &delta, &opts, &|| false).unwrap().report;
    let seconds = t.elapsed().as_secs_f64();
    let w = report.whole_path_risk.expect("asked for");
    let samples = size("WHOLE_PATH_SAMPLES", 20_000, 100_000) as u64;
    let audit = AuditOptions { times_per_piece: 100, samples, seed: 22, confidence: 0.98 };
    let (per, any) = audit_whole_path(&s, &traj, &audit).unwrap();
    for ((id, est), o) in per.iter().zip(&w.obstacles) {
        assert_eq!(id, &o.id);
        println!(
            "{id}: bound {:.2e} ({}), audit {:.2e} [{:.2e}, {:.2e}]",
            o.bound, o.how, est.estimate, est.lower, est.upper
        );
        assert!(o.bound >= est.lower, "{id}: bound {} below the audit's lower end {}", o.bound, est.lower);
    }
    println!(
        "d1 default plan, {} pieces: whole-path bound {:.3e} in {seconds:.2} s, audit {:.3e} [{:.3e}, {:.3e}]",
        traj.pieces.len(),
        w.bound,
        any.estimate,
        any.lower,
        any.upper
    );
    assert!(w.bound >= any.lower, "bound {} below the audit's lower end {}", w.bound, any.lower);
}

/// A scene of 40 disks with Gaussian centres (σ = 0.05) and uniform radius scales, far
/// from the origin (workspace [500, 563] × [−300, −237]): past 16 obstacles each
/// obstacle's whole-path partition is written in its own frame, about its refined centre
/// (`SceneKernel::path_frames`, docs/design.md §5.14), the pieces' boxes moved into it.
/// The default plan's whole-path bound of every obstacle and of the trajectory is at least
/// the seeded Monte Carlo audit's lower end (the library's sampler: no code shared with
/// the partition, its frames or its screen).
#[test]
fn whole_path_bound_in_obstacle_frames_covers_the_audit() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(40);
    let (x0, y0, side) = (500.0, -300.0, 63.0);
    let mut params = serde_json::Map::new();
    let mut obstacles = Vec::new();
    while obstacles.len() < 40 {
        let (cx, cy): (f64, f64) = (x0 + rng.random_range(0.0..side), y0 + rng.random_range(0.0..side));
        let r: f64 = rng.random_range(1.0..2.5);
        let clear = |x: f64, y: f64| ((cx - x).powi(2) + (cy - y).powi(2)).sqrt() > r + 3.0;
        if !clear(x0 + 1.0, y0 + 1.0) || !clear(x0 + side - 1.0, y0 + side - 1.0) {
            continue;
        }
        let k = obstacles.len() + 1;
        params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
        params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
        let (cx, cy, r) = ((cx * 100.0).round() / 100.0, (cy * 100.0).round() / 100.0, (r * 100.0).round() / 100.0);
        obstacles.push(serde_json::json!({
            "id": format!("disk{k}"),
            "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - ({cy}))^2"),
        }));
    }
    let text = serde_json::json!({
        "format": "riskplan-scene/1", "name": "disks-40-far", "dim": 2,
        "workspace": {"lower": [x0, y0], "upper": [x0 + side, y0 + side]},
        "horizon": [0, 1], "risk": 0.1, "params": params, "obstacles": obstacles,
        "start": [x0 + 1.0, y0 + 1.0], "goal": [x0 + side - 1.0, y0 + side - 1.0],
    })
    .to_string();
    let s = Arc::new(riskplan_scene::Scene::from_json(&text).unwrap());
    let kernel = SceneKernel::new(s.clone());
    let (_, out) = PlanRequest::default().run(&kernel, None).unwrap();
    let traj = out.trajectory.expect("a plan");
    let frames = kernel.path_frames(&|| false).unwrap();
    let scene_frame = riskplan_certify::checker::scene_frame(&s);
    assert!(frames.iter().all(|f| *f != scene_frame), "every static obstacle gets its own frame");
    let reported = out.stats.whole_path_risk.expect("every certified plan reports it");
    let opts = VerifyOptions { whole_path: true, detail: Detail::FirstNotSafe, ..Default::default() };
    let w = verify_with(&kernel, &traj.pieces, &s.risk, &opts, &|| false).unwrap().report.whole_path_risk.unwrap();
    let samples = size("WHOLE_PATH_SAMPLES", 20_000, 100_000) as u64;
    let audit = AuditOptions { times_per_piece: 100, samples, seed: 40, confidence: 0.98 };
    let (per, any) = audit_whole_path(&s, &traj, &audit).unwrap();
    for ((id, est), o) in per.iter().zip(&w.obstacles) {
        if est.estimate > 0.0 {
            println!("{id}: bound {:.2e}, audit {:.2e} [{:.2e}, {:.2e}]", o.bound, est.estimate, est.lower, est.upper);
        }
        assert!(o.bound >= est.lower, "{id}: bound {} below the audit's lower end {}", o.bound, est.lower);
    }
    println!(
        "{} pieces: plan's bound {reported:.3e}, verify's {:.3e}, audit {:.3e} [{:.3e}, {:.3e}]",
        traj.pieces.len(),
        w.bound,
        any.estimate,
        any.lower,
        any.upper
    );
    assert!(
        reported >= any.lower && w.bound >= any.lower,
        "bounds {reported}, {} below the audit's lower end {}",
        w.bound,
        any.lower
    );
}

/// 48 disks `(r·s)² − (x − cx)² − (y − cy)²`, s ~ U[0.9, 1.1], far from the
/// origin (workspace [10⁴, 10⁴ + 70]²), so that every obstacle's whole-path partition is
/// written in its own refined frame and screened by the tree of hulls and parts. Random
/// polylines (1 to 6 straight pieces, some of zero duration) are driven *through* the disks.
/// Closed form, sharing no code with the bound: the trajectory meets disk k iff
/// s ≥ d_min/r, so P_k = (1.1 − d_min/r)/0.2 clamped. Every obstacle's `verify` bound is at
/// least P_k, and the plan bound (with the slack) is at least Σ_k P_k's lower end: max_k P_k.
#[test]
fn review_whole_path_bounds_in_obstacle_frames_cover_the_closed_form_of_each_disk() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    let (x0, side) = (10_000.0, 70.0);
    let mut params = serde_json::Map::new();
    let mut obstacles = Vec::new();
    let mut disks = Vec::new();
    for k in 1..=48 {
        let (cx, cy, r): (f64, f64, f64) = (
            ((x0 + rng.random_range(3.0..side - 3.0)) * 100.0f64).round() / 100.0,
            ((x0 + rng.random_range(3.0..side - 3.0)) * 100.0f64).round() / 100.0,
            (rng.random_range(0.8..2.0) * 100.0f64).round() / 100.0,
        );
        params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
        obstacles.push(serde_json::json!({"id": format!("disk{k}"), "poly": format!("({r}*s{k})^2 - (x1 - {cx})^2 - (x2 - {cy})^2")}));
        disks.push((cx, cy, r));
    }
    let text = serde_json::json!({
        "format": "riskplan-scene/1", "name": "review-48-far", "dim": 2,
        "workspace": {"lower": [x0, x0], "upper": [x0 + side, x0 + side]}, "horizon": [0, 10], "risk": 0.1,
        "params": params, "obstacles": obstacles,
    })
    .to_string();
    let s = Arc::new(riskplan_scene::Scene::from_json(&text).unwrap());
    let kernel = SceneKernel::new(s.clone());
    let frames = kernel.path_frames(&|| false).unwrap();
    for (f, &(cx, cy, _)) in frames.iter().zip(&disks) {
        assert!(f.center.iter().all(|v| v.is_finite()));
        assert!((f.center[0] - cx).abs() < 1.0 && (f.center[1] - cy).abs() < 1.0, "frame {f:?} far from ({cx}, {cy})");
    }
    let seg = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let vv = dx * dx + dy * dy;
        let u = if vv > 0.0 { (((c[0] - a[0]) * dx + (c[1] - a[1]) * dy) / vv).clamp(0.0, 1.0) } else { 0.0 };
        ((a[0] + u * dx - c[0]).powi(2) + (a[1] + u * dy - c[1]).powi(2)).sqrt()
    };
    let (mut met, mut grazing) = (0, 0);
    for case in 0..150 {
        // a polyline through the centres of a few disks, offset by up to 1.2 radii
        let n = rng.random_range(1..=6);
        let mut pts: Vec<[f64; 2]> = Vec::new();
        for _ in 0..=n {
            let (cx, cy, r) = disks[rng.random_range(0..disks.len())];
            let (ang, off): (f64, f64) = (rng.random_range(0.0..std::f64::consts::TAU), rng.random_range(0.0..1.2) * r);
            pts.push([(cx + off * ang.cos()).clamp(x0, x0 + side), (cy + off * ang.sin()).clamp(x0, x0 + side)]);
        }
        let mut t = 0.0;
        let pieces: Vec<Piece> = pts
            .windows(2)
            .map(|w| {
                let h = if rng.random_bool(0.15) { 0.0 } else { rng.random_range(0.1..1.5) };
                let p = if h == 0.0 {
                    Piece { t0: t, t1: t, coeffs: vec![vec![w[0][0], 0.0], vec![w[0][1], 0.0]] }
                } else {
                    Piece::segment(&w[0], &w[1], t, t + h)
                };
                t += h;
                p
            })
            .collect();
        let truths: Vec<f64> = disks
            .iter()
            .map(|&(cx, cy, r)| {
                let d = pieces
                    .iter()
                    .map(|p| {
                        let at = |t: f64| [p.coeffs[0][0] + p.coeffs[0][1] * t, p.coeffs[1][0] + p.coeffs[1][1] * t];
                        seg(at(p.t0), at(p.t1), [cx, cy])
                    })
                    .fold(f64::INFINITY, f64::min);
                ((1.1 - d / r) / 0.2).clamp(0.0, 1.0)
            })
            .collect();
        let w = riskplan_app::verify::whole_path_risk(&kernel, &pieces, &|| false).unwrap();
        for (k, (o, &p)) in w.obstacles.iter().zip(&truths).enumerate() {
            // (1e-6: the closed form's own float rounding)
            assert!(
                o.bound >= p - 1e-6,
                "case {case}, disk {k}: bound {} below the closed form {p} ({pieces:?})",
                o.bound
            );
            met += (p > 0.0) as usize;
            grazing += (p > 0.0 && p < 0.5) as usize;
        }
        let effort = riskplan_certify::whole_path::CellEffort::PLAN;
        let plan = riskplan_app::verify::plan_whole_path_risk(&kernel, &pieces, effort, 0.01 * 0.1, false, &|| false)
            .unwrap()
            .unwrap();
        let top = truths.iter().copied().fold(0.0, f64::max);
        assert!(plan >= top - 1e-6, "case {case}: plan bound {plan} below the closed form {top}");
    }
    println!("{met} (obstacle, trajectory) pairs met, {grazing} grazing");
    assert!(met > 150 && grazing > 25, "{met} met, {grazing} grazing");
}
