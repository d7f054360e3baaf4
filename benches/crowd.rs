//! Millisecond obstacle updates and receding-horizon replanning, library-level (the
//! service round trip is `riskplan sim crowd`, docs/benchmarks.md "Robots among moving
//! people"):
//!
//! - `update/one_of_<n>`: one pedestrian's new prediction in a corridor of n pedestrians —
//!   the scene rebuilt from the previous revision (`Scene::from_file_reusing`), the kernel's
//!   successor and the covers at Δ = 0.01 (`SceneKernel::index`): what an `apply` costs
//!   the server beyond decoding and persisting;
//! - `update_all_then_plan/<n>`: every pedestrian's prediction new, then the first
//!   receding-horizon plan (window 3 s, robot body 0.25, Δ = 0.01) from the robot's start.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use num_rational::BigRational;
use riskplan::SceneKernel;
use riskplan_app::crowd::{start_goal, Crowd, CrowdParams};
use riskplan_app::{PlanRequest, RecedingRequest};
use riskplan_math::contour::RiskLevel;
use riskplan_scene::{ContourCache, Num, Scene, SceneFile};
use std::sync::Arc;
use std::time::Duration;

/// A corridor scene file with `n` pedestrians predicted at time `t` (seeded).
fn corridor(n: usize, t: f64) -> SceneFile {
    let (start, _) = start_goal();
    let mut crowd = Crowd::new(n, 7, CrowdParams::default(), start, 2.0);
    let obstacles: Vec<serde_json::Value> = (0..n)
        .map(|i| serde_json::json!({"id": crowd.walkers[i].id.clone(), "pedestrian": crowd.prediction(i, t)}))
        .collect();
    let v = serde_json::json!({"format": "riskplan-scene/1", "name": "corridor", "dim": 2,
        "workspace": {"lower": [-8, -3], "upper": [8, 3]}, "horizon": [0, 60], "risk": 0.01,
        "robot_radius": 0.25, "obstacles": obstacles, "planner": {"max_speed": 1.5, "max_accel": 3.0}});
    serde_json::from_value(v).expect("a valid scene file")
}

/// `file` with every pedestrian (or only the first) moved a little and predicted at `t`.
fn moved(file: &SceneFile, all: bool, step: u64) -> SceneFile {
    let mut f = file.clone();
    let dx = BigRational::new((step % 97 + 1).into(), 1000.into());
    for o in f.obstacles.iter_mut().take(if all { usize::MAX } else { 1 }) {
        if let Some(p) = o.pedestrian.as_mut() {
            p.position[0] = Num(&p.position[0].0 + &dx);
            p.time = Num(BigRational::new((step % 100).into(), 100.into()));
        }
    }
    f
}

fn updates(c: &mut Criterion) {
    let mut g = c.benchmark_group("update");
    let delta = RiskLevel::from_f64(0.01).unwrap();
    for n in [30usize, 60] {
        let cache = ContourCache::default();
        let file = corridor(n, 0.0);
        let scene = Arc::new(Scene::from_file_cached(file.clone(), &cache).unwrap());
        let kernel = SceneKernel::from(scene.clone());
        let deltas = vec![delta.clone(); n];
        let _ = kernel.index(&deltas, &|| false);
        let mut step = 0u64;
        g.bench_function(format!("one_of_{n}"), |b| {
            b.iter(|| {
                step += 1;
                let f = moved(&file, false, step);
                let s = Arc::new(Scene::from_file_reusing(f, &cache, Some(&scene)).unwrap());
                let k = kernel.successor(s);
                black_box(k.index(&deltas, &|| false));
            })
        });
    }
    g.finish();
}

fn replans(c: &mut Criterion) {
    let mut g = c.benchmark_group("update_all_then_plan");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    let (start, goal) = start_goal();
    for n in [30usize, 60] {
        let cache = ContourCache::default();
        let file = corridor(n, 0.0);
        let scene = Arc::new(Scene::from_file_cached(file.clone(), &cache).unwrap());
        let kernel = SceneKernel::from(scene.clone());
        let mut step = 0u64;
        g.bench_function(format!("{n}"), |b| {
            b.iter(|| {
                step += 1;
                let f = moved(&file, true, step);
                let s = Arc::new(Scene::from_file_reusing(f, &cache, Some(&scene)).unwrap());
                let k = kernel.successor(s);
                let req = PlanRequest {
                    time_limit: Duration::from_millis(40),
                    receding: Some(RecedingRequest {
                        t_now: 0.0,
                        position: start.to_vec(),
                        velocity: None,
                        horizon: 3.0,
                        goal: goal.to_vec(),
                        warm_start: None,
                    }),
                    ..Default::default()
                };
                black_box(req.run(&k, None).ok());
            })
        });
    }
    g.finish();
}

criterion_group!(benches, updates, replans);
criterion_main!(benches);
