//! With default options (`bound: auto`) the paper's scenes plan at the risk levels robots
//! use, and the certified safe regions of a uniform-radius disk and of a Gaussian-centre
//! disk start where the truth says they may.
//!
//! Every plan is re-verified at its Δ and audited by the independent oracle's own Monte Carlo
//! (`riskplan_oracle::bounds`: its own parser and sampler), 2·10⁵ scenarios per audited
//! point in the full tier: the risk of each obstacle at each audited point is ≤ Δ at 99 %
//! (the lower confidence limit of the estimate does not exceed Δ).

use super::common::{self, size};
use rand::SeedableRng;
use rand_chacha::ChaCha12Rng;
use riskplan_app::verify::{point_status, verify_until, Method, PointStatus, SceneKernel};
use riskplan_app::PlanRequest;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_oracle::bounds::{binomial_lower_limit, SceneBounds};
use riskplan_scene::{Scene, Trajectory};
use std::sync::Arc;

/// One-sided confidence of the audit: risk ≤ Δ at 99 %.
const AUDIT_ALPHA: f64 = 0.01;

fn plan(s: &Arc<Scene>, delta: &str) -> Trajectory {
    let req = PlanRequest { delta: Some(RiskLevel::parse(delta).unwrap()), ..PlanRequest::default() };
    let (_, out) = req.run(s.clone(), None).unwrap_or_else(|e| panic!("{} at Δ = {delta}: {e}", s.name));
    assert!(out.certified, "{} at Δ = {delta}: {:?} {:?}", s.name, out.status, out.reason);
    out.trajectory.unwrap()
}

/// `verify` (default bounds) at Δ, and the independent Monte Carlo audit of every obstacle
/// at `times` points per piece with `n` scenarios each.
fn verify_and_audit(s: &Arc<Scene>, t: &Trajectory, delta: &str) {
    let d = RiskLevel::parse(delta).unwrap();
    let kernel = SceneKernel::new(s.clone());
    let r =
        verify_until(&kernel, t, &d, Method::Exact, &Default::default(), BoundChoice::default(), &|| false).unwrap();
    assert!(r.safe, "{} at Δ = {delta}: the plan fails verify", s.name);
    let oracle = SceneBounds::from_scene_json(&serde_json::to_value(&s.file).unwrap()).unwrap();
    let n = size("AUDIT_SCENARIOS", 20_000, 200_000);
    let times = size("AUDIT_TIMES", 6, 12);
    let mut rng = ChaCha12Rng::seed_from_u64(1919);
    let mut worst = 0.0f64;
    for pc in &t.pieces {
        for k in 0..=times {
            let tt = pc.t0 + (pc.t1 - pc.t0) * k as f64 / times as f64;
            let x = pc.at(tt);
            for ob in &oracle.obstacles {
                let Some(h) = ob.mc_hits(&x, tt, n, &mut rng) else { continue };
                let lower = binomial_lower_limit(h as u64, n as u64, AUDIT_ALPHA);
                worst = worst.max(h as f64 / n as f64);
                assert!(
                    lower <= d.to_f64(),
                    "{} at Δ = {delta}: obstacle {} at t = {tt}, x = {x:?}: {h}/{n} hits, lower limit {lower} > Δ",
                    s.name,
                    ob.id
                );
            }
        }
    }
    println!("{} at Δ = {delta}: {} pieces, worst audited estimate {worst:e} ({n} scenarios)", s.name, t.pieces.len());
}

#[test]
fn paper_scenes_plan_at_the_risk_levels_robots_use() {
    for (name, delta) in
        [("example-d1-cluttered-2d", "0.001"), ("example-d1-cluttered-2d", "0.0001"), ("example-c-delivery", "0.001")]
    {
        let s = Arc::new(common::scene(name));
        let t = plan(&s, delta);
        verify_and_audit(&s, &t, delta);
    }
}

#[test]
fn illustrative_3_at_1e_3_is_planned_no_longer_than_3() {
    let s = Arc::new(common::scene("illustrative-3"));
    let t = plan(&s, "0.001");
    // arc length, by 200 chords per piece
    let length: f64 = t
        .pieces
        .iter()
        .map(|pc| {
            let pts: Vec<Vec<f64>> = (0..=200).map(|k| pc.at(pc.t0 + (pc.t1 - pc.t0) * k as f64 / 200.0)).collect();
            pts.windows(2).map(|w| riskplan_plan::dist(&w[0], &w[1])).sum::<f64>()
        })
        .sum();
    assert!(length <= 3.0, "illustrative-3 at Δ = 0.001: length {length}");
    verify_and_audit(&s, &t, "0.001");
}

/// The smallest distance from `centre` (along `dirs` directions, steps of 0.005) beyond
/// which every point up to `far` is proven below Δ.
fn safe_radius(s: &Scene, centre: &[f64], t: f64, delta: &str, far: f64, dirs: usize) -> f64 {
    let d = vec![RiskLevel::parse(delta).unwrap(); s.obstacles.len()];
    let mut worst = 0.0f64;
    for k in 0..dirs {
        let a = std::f64::consts::TAU * k as f64 / dirs as f64;
        let mut r = far;
        let mut last_unsafe = 0.0;
        while r > 0.0 {
            let x = [centre[0] + r * a.cos(), centre[1] + r * a.sin()];
            if point_status(s, &x, t, &d, BoundChoice::default()) != PointStatus::Safe {
                last_unsafe = r;
                break;
            }
            r -= 0.005;
        }
        worst = worst.max(last_unsafe + 0.005);
    }
    worst
}

#[test]
fn certified_safe_regions_start_near_the_truth() {
    // illustrative-1: a disk of radius w ~ U[0.3, 0.4] (truth 0.4, Cantelli 0.87)
    let s = common::scene("illustrative-1");
    let r = safe_radius(&s, &[0.0, 0.0], 0.0, "0.001", 0.99, 16);
    println!("illustrative-1 at Δ = 0.001: safe from r = {r}");
    assert!(r <= 0.45, "illustrative-1: the certified safe region starts at {r}");
    // a disk of radius 0.3 with a Gaussian centre, σ = 0.05 (truth ≈ 0.45, Cantelli ≈ 3.2)
    let path = crate::common::repo().join("tests/scenes/bounds/gaussian-centre-disk.json");
    let s = Scene::from_json(&std::fs::read_to_string(path).unwrap()).unwrap();
    let r = safe_radius(&s, &[0.0, 0.0], 0.0, "0.001", 3.9, 16);
    println!("Gaussian-centre disk at Δ = 0.001: safe from r = {r}");
    assert!(r <= 0.65, "Gaussian-centre disk: the certified safe region starts at {r}");
}

/// The final check proves what the planners' higher-moment cover proves far from the
/// origin. On the 512-disk benchmark scene (workspace 226 wide) a blend grazes a disk near
/// x ≈ 145: Cantelli's g₁ fails there (the exact witness is negative), and the fast path
/// covers the piece with the fourth-moment bound on a sub-interval; the final check's
/// compiled fallback composes the central moments in intervals rather than as the fast path
/// does, and must find a cover too — else the plan counts as a disagreement and is made
/// again without the fast path, far slower. Here: the checker accepts the piece, the final
/// check passes it, `verify` reports a moment bound, and the independent Monte Carlo audit
/// keeps the risk below Δ.
#[test]
fn the_final_check_proves_a_grazing_piece_far_from_the_origin_as_the_planner_does() {
    use riskplan_app::verify::{final_check, SceneCertifier};
    use riskplan_plan::MotionChecker;
    use riskplan_scene::Piece;
    let side = 10.0 * 512f64.sqrt();
    let text = serde_json::json!({
        "format": "riskplan-scene/1",
        "name": "one-disk-of-512",
        "dim": 2,
        "workspace": {"lower": [0, 0], "upper": [side, side]},
        "horizon": [0, 1],
        "risk": 0.05,
        "params": {
            "s": {"dist": "uniform", "low": 0.9, "high": 1.1},
            "d": {"dist": "normal", "mean": 0, "std": 0.05}
        },
        "obstacles": [{"id": "disk218", "poly": "(0.91*s)^2 - (x1 - 144.67 - d)^2 - (x2 - 145.97)^2"}],
    })
    .to_string();
    let s = Arc::new(Scene::from_json(&text).unwrap());
    // the blend of seed 7's plan (quadratic in absolute time)
    let piece = Piece {
        t0: 0.5954217861364366,
        t1: 0.7083776252912468,
        coeffs: vec![
            vec![10.11810821166074, 190.98028292735262, 26.533510537544064],
            vec![-9.185171528592138, 259.70961336294874, -26.597521261808986],
        ],
    };
    let kernel = SceneKernel::new(s.clone());
    let deltas = vec![s.risk.clone()];
    let checker = SceneCertifier::with_deltas(&kernel, deltas.clone(), Method::Exact);
    assert_eq!(checker.check(&piece), riskplan_plan::Motion::Accepted, "the planners' checker");
    let t = Trajectory::new(vec![piece.clone()]);
    let start = piece.at(piece.t0);
    let fc = final_check(&kernel, &t, (&start, None), piece.t0, &deltas, BoundChoice::default(), &|| false).unwrap();
    assert_eq!(fc.failure, None, "the final check must prove what the fast path proved");
    let r = verify_until(&kernel, &t, &s.risk, Method::Exact, &Default::default(), BoundChoice::default(), &|| false)
        .unwrap();
    let bounds: Vec<String> =
        r.pieces[0].obstacles[0].bounds.iter().map(|b| serde_json::to_string(&b.bound).unwrap()).collect();
    assert!(bounds.iter().any(|b| b.contains("moment")), "Cantelli alone does not prove it: {bounds:?}");
    verify_and_audit(&s, &t, "0.05");
}
