//! The default planner's guarantees: any scale and placement, smooth output, short
//! paths, and the joint risk mode — each checked against an oracle that does not share
//! the planner's code (exact evaluation of the contours at many times of every piece,
//! and Monte Carlo audits).

use crate::common;
use crate::common::oracle;
use riskplan_app::verify::{audit_trajectory_joint, AuditOptions};
use riskplan_app::{PlanRequest, PlannerKind, RiskMode};
use riskplan_plan::smooth::max_velocity_jump;
use riskplan_scene::{Scene, Trajectory};
use std::sync::Arc;
use std::time::Duration;

/// Velocity jumps at piece joints below this fraction of the top speed are rounding:
/// the blend coefficients are expanded in absolute time.
const VELOCITY_JUMP_TOLERANCE: f64 = 1e-6;

fn plan(s: &Arc<Scene>, request: PlanRequest) -> (Trajectory, riskplan_plan::PlanStats) {
    let (_, out) = request.run(s.clone(), None).unwrap_or_else(|e| panic!("{}: {e}", s.name));
    let t = out.trajectory.unwrap_or_else(|| panic!("{}: no plan: {:?} {:?}", s.name, out.reason, out.stats));
    assert!(out.certified, "{}", s.name);
    (t, out.stats)
}

/// The copy of a scene with space scaled by `k` and shifted by `shift`, and time shifted
/// by `dt`: every obstacle polynomial `P(x, ω, t)` becomes `P((x − shift)/k, ω, t − dt)`,
/// so its Δ-contours are the image of the original's; the planner block is dropped (the
/// paper's absolute parameters must not be needed).
fn transformed(name: &str, k: f64, shift: &[f64], dt: f64) -> Scene {
    let text = std::fs::read_to_string(common::reference_dir().join(format!("{name}.json"))).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let dim = v["dim"].as_u64().unwrap() as usize;
    let map = |x: f64, d: usize| x * k + shift[d];
    for key in ["lower", "upper"] {
        let arr: Vec<f64> = v["workspace"][key].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        v["workspace"][key] = serde_json::json!(arr.iter().enumerate().map(|(d, &x)| map(x, d)).collect::<Vec<_>>());
    }
    for key in ["start", "goal"] {
        let arr: Vec<f64> = v[key].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        v[key] = serde_json::json!(arr.iter().enumerate().map(|(d, &x)| map(x, d)).collect::<Vec<_>>());
    }
    let h: Vec<f64> = v["horizon"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    v["horizon"] = serde_json::json!([h[0] + dt, h[1] + dt]);
    for o in v["obstacles"].as_array_mut().unwrap() {
        let mut p = o["poly"].as_str().unwrap().to_string();
        // placeholders first, so that a substituted text is not substituted again
        for d in (1..=dim).rev() {
            p = p.replace(&format!("x{d}"), &format!("§{d}"));
        }
        p = replace_t(&p);
        for d in 1..=dim {
            p = p.replace(&format!("§{d}"), &format!("((x{d} - ({}))/{k})", shift[d - 1]));
        }
        o["poly"] = serde_json::json!(p);
    }
    v.as_object_mut().unwrap().remove("planner");
    v.as_object_mut().unwrap().remove("expected");
    v["name"] = serde_json::json!(format!("{name}-scaled"));
    let shifted_t = format!("(t - {dt})");
    let text = serde_json::to_string(&v).unwrap().replace("§t", &shifted_t);
    Scene::from_json(&text).unwrap_or_else(|e| panic!("{name} scaled: {e}"))
}

/// Replaces the time variable `t` (a lone identifier) by a placeholder.
fn replace_t(p: &str) -> String {
    let chars: Vec<char> = p.chars().collect();
    let mut out = String::new();
    for (i, &c) in chars.iter().enumerate() {
        let ident = |c: char| c.is_alphanumeric() || c == '_' || c == '§';
        let alone = c == 't' && (i == 0 || !ident(chars[i - 1])) && (i + 1 == chars.len() || !ident(chars[i + 1]));
        if alone {
            out.push_str("§t");
        } else {
            out.push(c);
        }
    }
    out
}

/// A scene and its copy scaled ×100, shifted by (1000, −500) and with the horizon
/// shifted by 10 both plan with default options, and the copy's plan is safe by the
/// independent oracle.
#[test]
fn scaled_and_shifted_copies_plan_with_default_options() {
    for name in ["illustrative-3", "example-d1-cluttered-2d", "illustrative-4", "example-b-lane-change"] {
        let original = Arc::new(common::scene(name));
        plan(&original, PlanRequest::default());
        let copy = Arc::new(transformed(name, 100.0, &[1000.0, -500.0], 10.0));
        assert!(copy.file.planner.is_none());
        let (t, stats) = plan(&copy, PlanRequest::default());
        oracle::check_trajectory(&copy, &t.pieces, &copy.risk).unwrap_or_else(|e| panic!("{name} scaled: {e}"));
        println!("{name} ×100: {} pieces, length {:?}", t.pieces.len(), stats.path_length);
    }
}

/// With smoothing on (the default), the velocity is continuous at every piece joint,
/// and no corner was left sharp.
#[test]
fn default_plans_are_c1() {
    for name in common::PLANNING_SCENES {
        let s = Arc::new(common::scene(name));
        for seed in 1..=common::size("C1_SEEDS", 1, 3) as u64 {
            let (t, stats) = plan(&s, PlanRequest { seed, ..PlanRequest::default() });
            let jump = max_velocity_jump(&t.pieces);
            let sm = stats.smoothing.expect("smoothing stats");
            assert_eq!(sm.corners_sharp, 0, "{name} seed {seed}: {sm:?}");
            assert!(jump < VELOCITY_JUMP_TOLERANCE, "{name} seed {seed}: velocity jump {jump} ({sm:?})");
            oracle::check_trajectory(&s, &t.pieces, &s.risk).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        // without smoothing, the corners jump
        let (t, _) = plan(&s, PlanRequest { smooth: false, ..PlanRequest::default() });
        if t.pieces.len() > 1 && name == "example-d1-cluttered-2d" {
            assert!(max_velocity_jump(&t.pieces) > 1e-3, "{name}: unsmoothed plan has no corner");
        }
    }
}

/// Default plans on illustrative-3 and d1 are within 5 % of the length of the paper
/// planner's improved path (Dijkstra over every certified pair of tree vertices).
#[test]
fn default_plans_are_within_five_percent_of_the_improved_path() {
    for name in ["illustrative-3", "example-d1-cluttered-2d"] {
        let s = Arc::new(common::scene(name));
        let (_, improved) = plan(
            &s,
            PlanRequest {
                planner: PlannerKind::RrtSosPaper,
                improve: true,
                time_limit: Duration::from_secs(120),
                ..PlanRequest::default()
            },
        );
        let best = improved.path_length.unwrap();
        for seed in 1..=5 {
            let (_, st) = plan(&s, PlanRequest { seed, ..PlanRequest::default() });
            let len = st.path_length.unwrap();
            println!("{name} seed {seed}: {len:.4} vs improved {best:.4}");
            assert!(len <= 1.05 * best, "{name} seed {seed}: length {len} > 1.05 × {best}");
        }
    }
}

/// `risk_mode: joint`: on every planning scene, the Monte Carlo estimate of the
/// probability of colliding with *any* obstacle stays ≤ Δ (99 % one-sided), for both
/// allocations, and the Δᵢ reported add up to Δ. Where the endpoints alone need more
/// than Δ in total (the lane change: start and goal each 0.6 from a vehicle), the
/// request is refused with a typed `UnsafeEndpoint`; most scenes plan.
#[test]
fn joint_risk_bounds_the_probability_of_any_collision() {
    let mut planned = 0;
    for name in common::PLANNING_SCENES {
        let s = Arc::new(common::scene(name));
        for mode in [RiskMode::JointUniform, RiskMode::JointWeighted] {
            let request = PlanRequest { risk_mode: mode, ..PlanRequest::default() };
            let (t, stats) = match request.run(s.clone(), None) {
                Err(e) => {
                    assert!(matches!(e, riskplan_plan::PlanError::UnsafeEndpoint { .. }), "{name}: {e}");
                    println!("{name} {mode:?}: refused: {e}");
                    continue;
                }
                Ok((_, out)) => {
                    let t = out.trajectory.unwrap_or_else(|| panic!("{name} {mode:?}: no plan: {:?}", out.reason));
                    assert!(out.certified);
                    (t, out.stats)
                }
            };
            planned += usize::from(mode == RiskMode::JointWeighted);
            let alloc = stats.risk_allocation.expect("allocation reported");
            assert_eq!(alloc.len(), s.obstacles.len());
            let total: f64 = alloc.iter().map(|(_, d)| d).sum();
            assert!((total - s.risk_f64()).abs() < 1e-12, "{name}: Σ Δᵢ = {total}");
            // every piece is safe for obstacle i at its Δᵢ, by the independent oracle
            for (o, (id, d)) in s.obstacles.iter().zip(&alloc) {
                assert_eq!(&o.id, id);
                let single = Scene { obstacles: vec![o.clone()], ..(*s).clone() };
                let di = riskplan_math::contour::RiskLevel::from_f64(*d).unwrap();
                oracle::check_trajectory(&single, &t.pieces, &di)
                    .unwrap_or_else(|e| panic!("{name} {mode:?}: obstacle {id} at Δᵢ = {d}: {e}"));
            }
            let opts = AuditOptions { times_per_piece: 40, samples: 4000, seed: 11, ..AuditOptions::default() };
            let a = audit_trajectory_joint(&s, &t, s.risk_f64(), &opts).unwrap();
            assert!(!a.exceeds(), "{name} {mode:?}: P(any collision) above Δ: {:?}", a.exceedances);
            println!("{name} {mode:?}: max P(any) estimate {:.4}", a.max_estimate);
        }
    }
    assert!(planned >= 4, "joint-weighted planned on {planned} of 6 scenes");
}

/// Relative margins below this are not asked of the SOS method: its
/// certificate is a floating-point SDP solution re-checked rigorously, so a margin at
/// the solver's tolerance may be lost.
const SOS_RELATIVE_MARGIN: f64 = 1e-4;

/// On a static scene with a quartic obstacle, the workspace near x ≈ 12 and the horizon
/// [10, 13], the SOS method certifies every piece that the exact method certifies with a
/// relative margin ≥ 1e-4 (the restriction is centred before the SDP, else the re-check
/// would reject it). Pieces: the default plan's, and straight segments passing the
/// obstacle at several distances.
#[test]
fn sos_certifies_pieces_away_from_the_origin() {
    use riskplan_app::verify::{verify, Method, Status};
    let text = r#"{
        "format": "riskplan-scene/1", "name": "quartic-at-12", "dim": 2,
        "workspace": {"lower": [10, -2], "upper": [14, 2]}, "horizon": [10, 13], "risk": 0.1,
        "params": {"w": {"dist": "uniform", "low": 0.9, "high": 1.1}},
        "obstacles": [{"id": "quartic", "poly": "0.3*w*(1 + 0.5*(x1 - 12)) - (x1 - 12)^4 - x2^4 - 0.5*(x1 - 12)^2*x2^2"}],
        "start": [10.2, -1.6], "goal": [13.8, 1.6]
    }"#;
    let s = Arc::new(Scene::from_json(text).unwrap());
    let (plan_t, _) = plan(&s, PlanRequest::default());
    let mut pieces = plan_t.pieces.clone();
    for k in 0..40 {
        // horizontal and slanted segments passing above and below the obstacle, nearer and nearer
        let y = 1.95 - 1.1 * (k / 2) as f64 / 19.0;
        let y = if k % 2 == 0 { y } else { -y };
        let seg = riskplan_scene::Piece::segment(&[10.0, y], &[14.0, y * (1.0 - 0.01 * k as f64)], 10.0, 13.0);
        pieces.push(riskplan_plan::smooth::inside(seg, &s.workspace.lower, &s.workspace.upper));
    }
    let (mut asked, mut sos_ok) = (0, 0);
    for p in &pieces {
        let t = Trajectory::new(vec![p.clone()]);
        let exact = verify(&s, &t, &s.risk, Method::Exact, &Default::default());
        if !exact.safe {
            continue;
        }
        // the constraint's scale: its largest value along the piece (f64, 9 times)
        let c = &exact.pieces[0].obstacles[0].constraints;
        let scale = (0..=8)
            .map(|k| {
                let t = p.t0 + (p.t1 - p.t0) * k as f64 / 8.0;
                let mut x = p.at(t);
                x.push(t);
                let (m, e2) = s.obstacles[0].contour.moments_f64(&x);
                (m * m - 0.9 * e2).abs().max(m.abs())
            })
            .fold(0.0, f64::max);
        let margin = c.iter().filter_map(|r| r.margin).fold(f64::INFINITY, f64::min);
        if margin < SOS_RELATIVE_MARGIN * scale {
            continue;
        }
        asked += 1;
        let sos = verify(&s, &t, &s.risk, Method::Sos, &Default::default());
        if sos.safe {
            sos_ok += 1;
        } else {
            let why: Vec<_> = sos.pieces[0].obstacles[0]
                .constraints
                .iter()
                .filter(|r| r.status != Status::Safe)
                .map(|r| (r.name.clone(), r.reason.clone()))
                .collect();
            println!("SOS rejects a piece exact certifies with margin {margin:e} (scale {scale:e}): {why:?}");
        }
    }
    println!("SOS certifies {sos_ok} of {asked} pieces certified by exact with relative margin ≥ 1e-4");
    assert!(asked >= 20, "only {asked} pieces to compare");
    assert!(sos_ok * 100 >= asked * 99, "SOS certifies {sos_ok} of {asked}");
}
