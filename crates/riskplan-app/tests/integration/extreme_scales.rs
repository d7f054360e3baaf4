//! Scenes at extreme numeric scales, where an error model of the compiled edge check
//! (docs/design.md §5.10) that ignores underflow would certify unsafe pieces —
//! coefficients of E[P²] that are subnormal (10⁻³²⁰) or underflow to zero (10⁻³³⁶), and a
//! subnormal coefficient in the obstacle itself. Every planner that accepts a scene, on
//! seeds 1–5 (1–2 in the quick tier): a plan called certified must pass `verify` (exact
//! method) and the independent oracle (term by term at 1 000 times per piece, exact
//! rational arithmetic wherever floating point is not conclusive); the keep-in scene has
//! no safe path at all and must get no certified plan.

use crate::common;
use crate::common::oracle;
use riskplan_math::contour::BoundChoice;

use riskplan_app::verify::{verify, Method};
use riskplan_app::{PlanRequest, PlannerKind};
use riskplan_scene::Scene;
use std::sync::Arc;
use std::time::Duration;

/// The scenes, in `tests/scenes/extreme/`: three superellipses at 10²⁰–10⁴¹ and a subnormal
/// coefficient, a horizon of 10⁻³⁰⁰ (blends whose coefficients overflow to ∞ and NaN, which
/// the exact fallback must not read as 0 and certify) and a horizon at t ≈ 10¹⁸ (pieces
/// rounded apart: a trajectory that jumps and misses its endpoints must not be certified).
const SCENES: [&str; 6] = [
    "superellipse-at-1e21",
    "superellipse-at-1e20-grazing",
    "keep-in-superellipse-at-1e41",
    "subnormal-coefficient",
    "tiny-horizon",
    "far-time",
];

/// The scenes the default planner must plan (certified).
const PLANNED: [&str; 4] =
    ["superellipse-at-1e21", "superellipse-at-1e20-grazing", "subnormal-coefficient", "tiny-horizon"];

/// The scene with no safe path.
const NO_PATH: &str = "keep-in-superellipse-at-1e41";

fn load(name: &str) -> Arc<Scene> {
    let p = crate::common::repo().join("tests/scenes/extreme").join(format!("{name}.json"));
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    Arc::new(Scene::from_json(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
}

/// Plans `name` with `planner` on `seed` and checks what a certified answer claims.
/// Returns whether a certified plan came back.
fn plan_and_check(name: &str, planner: PlannerKind, seed: u64) -> bool {
    plan_and_check_with(name, planner, seed, BoundChoice::default())
}

/// [`plan_and_check`] with a choice of bounds.
fn plan_and_check_with(name: &str, planner: PlannerKind, seed: u64, bound: BoundChoice) -> bool {
    let s = load(name);
    let request =
        PlanRequest { planner, seed, time_limit: Duration::from_secs(4), bound: Some(bound), ..PlanRequest::default() };
    let out = match request.run(s.clone(), None) {
        Ok((_, out)) => out,
        Err(e) => {
            println!("{name} {planner} seed {seed}: refused: {e}");
            return false;
        }
    };
    let fc = out.stats.final_check.clone();
    println!(
        "{name} {planner} seed {seed}: {:?}, certified {}, {} pieces, final check {fc:?}",
        out.status,
        out.certified,
        out.trajectory.as_ref().map_or(0, |t| t.pieces.len())
    );
    if let Some(f) = &fc {
        assert_eq!(f.disagreements, 0, "{name} {planner} seed {seed}: the final check disagreed with the fast path");
    }
    let Some(t) = out.trajectory.filter(|_| out.certified) else { return false };
    // what `verify` takes as input: finite, contiguous, pieces that meet
    let diag = riskplan_plan::dist(&s.workspace.lower, &s.workspace.upper);
    t.validate(s.dim, s.horizon, diag)
        .unwrap_or_else(|e| panic!("{name} {planner} seed {seed}: a certified plan is not a valid trajectory: {e}"));
    let r = riskplan_app::verify::verify_until(
        &(&s).into(),
        &t,
        &s.risk,
        Method::Exact,
        &Default::default(),
        bound,
        &|| false,
    )
    .expect("never interrupted");
    assert!(
        r.safe,
        "{name} {planner} seed {seed}: a certified plan fails verify: {}",
        serde_json::to_string(&r).unwrap()
    );
    oracle::check_trajectory(&s, &t.pieces, &s.risk)
        .unwrap_or_else(|e| panic!("{name} {planner} seed {seed}: a certified piece fails the oracle: {e}"));
    true
}

#[test]
fn certified_plans_at_extreme_scales_pass_exact_verification() {
    let seeds = common::size("EXTREME_SEEDS", 1, 5) as u64;
    for name in SCENES {
        for planner in PlannerKind::ALL {
            for seed in 1..=seeds {
                let certified = plan_and_check(name, planner, seed);
                if name == NO_PATH {
                    // no path is safe by Cantelli's bound; the support bound proves the
                    // thin gap between the disk and the keep-in boundary (its plans, if
                    // any, were checked above by verify and the oracle)
                    let by_cantelli = plan_and_check_with(name, planner, seed, BoundChoice::Cantelli);
                    assert!(!by_cantelli, "{name}: {planner} seed {seed} certified a Cantelli plan where none exists");
                    println!("{name} {planner} seed {seed}: certified with bound auto: {certified}");
                }
            }
        }
    }
}

/// The default planner plans the scenes that have a path (where the compiled path's error
/// model does not hold, the compiled path is refused, not the plan).
#[test]
fn the_default_planner_plans_the_scenes_with_a_path() {
    for name in PLANNED {
        assert!(plan_and_check(name, PlannerKind::RrtSos, 1), "{name}: no certified plan from rrt-sos");
    }
}

/// A motion checker that claims to be sound and accepts every piece: a stand-in for a
/// fast path with a bug.
struct Lying;

impl riskplan_plan::MotionChecker for Lying {
    fn name(&self) -> &str {
        "lying"
    }
    fn sound(&self) -> bool {
        true
    }
    fn check(&self, _: &riskplan_scene::Piece) -> riskplan_plan::Motion {
        riskplan_plan::Motion::Accepted
    }
    fn check_point(&self, _: &[f64], _: f64) -> riskplan_plan::Motion {
        riskplan_plan::Motion::Accepted
    }
}

/// illustrative-3 moved to UTM-like coordinates (x ≈ 5·10⁵, y ≈ 5·10⁶): the final check
/// composes in its own exact frame there.
fn utm_scene() -> Arc<Scene> {
    let text = r#"{"format": "riskplan-scene/1", "name": "illustrative-3-utm", "dim": 2,
        "workspace": {"lower": [499999, 4999999], "upper": [500001, 5000001]}, "horizon": [0, 1], "risk": 0.1,
        "params": {"w": {"dist": "uniform", "low": 0.3, "high": 0.4}},
        "obstacles": [{"id": "disk", "poly": "w^2 - (x1 - 500000)^2 - (x2 - 5000000)^2"}],
        "start": [499999, 4999999], "goal": [500001, 5000001]}"#;
    Arc::new(Scene::from_json(text).unwrap())
}

/// A disk across the straight line from start to goal and 16 small disks in a corner:
/// with more than 16 obstacles the final check clears distant ones by its box test.
fn seventeen_disks() -> Arc<Scene> {
    let mut obstacles = vec![serde_json::json!({"id": "middle", "poly": "w^2 - (x1 - 5)^2 - (x2 - 5)^2"})];
    for i in 0..16 {
        let (cx, cy) = (0.6 + 0.6 * (i % 4) as f64, 7.6 + 0.6 * (i / 4) as f64);
        obstacles.push(
            serde_json::json!({"id": format!("corner{i}"), "poly": format!("(w/8)^2 - (x1 - {cx})^2 - (x2 - {cy})^2")}),
        );
    }
    let text = serde_json::json!({"format": "riskplan-scene/1", "name": "seventeen-disks", "dim": 2,
        "workspace": {"lower": [0, 0], "upper": [10, 10]}, "horizon": [0, 1], "risk": 0.1,
        "params": {"w": {"dist": "uniform", "low": 0.9, "high": 1.1}},
        "obstacles": obstacles, "start": [0.5, 0.5], "goal": [9.5, 9.5]});
    Arc::new(Scene::from_json(&text.to_string()).unwrap())
}

/// Defence in depth (docs/design.md §5.12): a checker that accepts the straight line
/// through the obstacle in the middle is caught by the final check — in the scene's own
/// coordinates (illustrative-3), in the check's own frame (UTM-like coordinates) and with
/// its box tests of distant obstacles (17 disks); the disagreement is counted, the plan
/// is made again without the fast path, and what comes back certified passes `verify`
/// and the independent oracle.
#[test]
fn the_final_check_catches_a_lying_checker_and_plans_again() {
    for s in [Arc::new(common::scene("illustrative-3")), utm_scene(), seventeen_disks()] {
        let request = PlanRequest { seed: 1, time_limit: Duration::from_secs(20), ..PlanRequest::default() };
        let mut prepared = request.prepare(s.clone()).unwrap();
        prepared.checker = Box::new(Lying);
        let out = prepared.solve(&request.termination(None)).unwrap();
        let fc = out.stats.final_check.clone().expect("final check stats");
        assert_eq!(fc.disagreements, 1, "{}: {fc:?}", s.name);
        assert!(out.certified, "{}", s.name);
        let t = out.trajectory.expect("a plan after the re-plan");
        assert!(t.pieces.len() > 1, "{}: the straight line through the disk came back", s.name);
        let r = verify(&s, &t, &s.risk, Method::Exact, &Default::default());
        assert!(r.safe, "{}", s.name);
        oracle::check_trajectory(&s, &t.pieces, &s.risk).unwrap();
    }
}
