//! The generator's scenes as riskplan reads them (moved from the unit tests of
//! `src/robust/generate.rs`, which needed `riskplan`: the generator's own crate,
//! `riskplan-oracle`, does not depend on it). Every scene of a suite loads, covers what
//! the generator promises, and its polynomial text is the structure the oracle
//! evaluates.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha12Rng;
use riskplan_oracle::generate::{generate, Shape, MAX_PARAMS, MAX_PEDESTRIAN_PARAMS, MOMENTS_SCENE_EVERY};
use riskplan_scene::Scene;
use std::collections::BTreeSet;
use std::f64::consts::PI;

const SUITE: usize = 120;

/// A uniform draw in [lo, hi) (the generator's private helper, same formula).
fn unif(rng: &mut ChaCha12Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

#[test]
fn coverage_and_every_scene_loads() {
    let mut families = BTreeSet::new();
    let mut dims = BTreeSet::new();
    let mut shapes = BTreeSet::new();
    let mut motions = BTreeSet::new();
    let mut intents = BTreeSet::new();
    let (mut wmin, mut wmax) = (f64::INFINITY, 0.0f64);
    let (mut speed, mut feasible, mut two_d, mut moments_scenes, mut pedestrian_scenes) = (0, 0, 0, 0, 0);
    for i in 0..SUITE {
        let g = generate(1, i);
        let text = g.json();
        let scene = Scene::from_json(&text).unwrap_or_else(|e| panic!("scene {i}: {e}\n{text}"));
        assert_eq!(scene.obstacles.len(), g.obstacles.len());
        assert!(g.horizon.0 != 0.0 && g.horizon.0 < g.horizon.1);
        assert!((0.01..=0.2).contains(&g.delta));
        assert!(!g.obstacles.is_empty() && g.obstacles.len() <= 8, "scene {i}");
        pedestrian_scenes += g.obstacles.iter().any(|o| matches!(o.shape, Shape::Pedestrian { .. })) as usize;
        for o in &g.obstacles {
            let max = if matches!(o.shape, Shape::Pedestrian { .. }) { MAX_PEDESTRIAN_PARAMS } else { MAX_PARAMS };
            assert!(o.params.len() <= max && !o.params.is_empty());
            families.extend(o.params.iter().map(|p| p.dist.family()));
            shapes.insert(o.shape.class());
            motions.insert(format!("{:?}", o.motion.kind));
        }
        dims.insert(g.dim);
        two_d += (g.dim == 2) as usize;
        intents.insert(format!("{:?}", g.intent));
        feasible += g.intent.feasible() as usize;
        speed += g.max_speed.is_some() as usize;
        moments_scenes += g.has_moments_param() as usize;
        wmin = wmin.min(g.width());
        wmax = wmax.max(g.width());
        for d in 0..g.dim {
            assert!(g.lower[d] <= g.start[d] && g.start[d] <= g.upper[d]);
            assert!(g.lower[d] <= g.goal[d] && g.goal[d] <= g.upper[d]);
        }
    }
    assert_eq!(families.len(), 8, "{families:?}");
    assert_eq!(dims.len(), 2);
    assert_eq!(shapes.len(), 4, "{shapes:?}");
    assert!((15..=60).contains(&pedestrian_scenes), "{pedestrian_scenes}");
    assert_eq!(motions.len(), 3, "{motions:?}");
    assert_eq!(intents.len(), 4, "{intents:?}");
    assert!(wmin < 2.0 && wmax > 50.0, "{wmin} {wmax}");
    assert!((90..=106).contains(&feasible), "{feasible}");
    assert!((15..=45).contains(&speed), "{speed}");
    assert!((60..=100).contains(&two_d), "{two_d}");
    assert!((10..=SUITE / MOMENTS_SCENE_EVERY).contains(&moments_scenes), "{moments_scenes}");
}

/// The structured P and the polynomial text agree (evaluated by the crate's parser
/// at a few points), and each shape's {P ≥ 0} is bounded by its bounding radius. (The
/// oracle crate checks the same with its own parser, `generate::tests`.)
#[test]
fn structure_matches_text_and_shapes_are_bounded() {
    let mut rng = ChaCha12Rng::seed_from_u64(5);
    let mut seen = BTreeSet::new();
    for i in 0..40 {
        let g = generate(2, i);
        let scene = Scene::from_json(&g.json()).unwrap();
        for (o, so) in g.obstacles.iter().zip(&scene.obstacles) {
            seen.insert(o.shape.class());
            let w: Vec<f64> = o.params.iter().map(|p| p.dist.sample(&mut rng)).collect();
            let t = unif(&mut rng, g.horizon.0, g.horizon.1);
            let c = o.motion.centre(t);
            for _ in 0..3 {
                let x: Vec<f64> = c.iter().map(|c| c + o.bound * unif(&mut rng, -1.5, 1.5)).collect();
                let direct = o.eval(&x, t, &w);
                let mut assign: Vec<(String, f64)> = (0..g.dim).map(|d| (format!("x{}", d + 1), x[d])).collect();
                assign.push(("t".into(), t));
                assign.extend(o.params.iter().zip(&w).map(|(p, v)| (p.name.clone(), *v)));
                let parsed = eval_qpoly(&scene, &so.poly, &assign);
                let scale = 1.0 + direct.abs() + o.bound.powi(4);
                assert!((direct - parsed).abs() <= 1e-6 * scale, "scene {i} {}: {direct} vs {parsed}", o.id);
            }
            // bounded: P < 0 on a sphere of twice the bounding radius, at the mean parameters
            let mean: Vec<f64> = o.params.iter().map(|p| p.dist.mean_sd().0).collect();
            for k in 0..64 {
                let th = k as f64 / 64.0 * 2.0 * PI;
                let mut x = c.clone();
                x[0] += 2.0 * o.bound * th.cos();
                x[1] += 2.0 * o.bound * th.sin();
                assert!(o.eval(&x, t, &mean) < 0.0, "scene {i} {} unbounded", o.id);
            }
            assert!(o.eval(&c, t, &mean) > 0.0 || matches!(o.shape, Shape::Peanut { .. }));
        }
    }
    assert_eq!(seen.len(), 4, "{seen:?}");
}

/// Evaluates a riskplan polynomial exactly at named values (test only: checks the
/// text against the structure).
fn eval_qpoly(scene: &Scene, p: &riskplan_math::poly::QPoly, assign: &[(String, f64)]) -> f64 {
    use num_rational::BigRational;
    use num_traits::Zero;
    let mut vals = vec![BigRational::zero(); scene.vars.len()];
    for (n, v) in assign {
        if let Some(i) = scene.vars.get(n) {
            vals[i as usize] = BigRational::from_float(*v).unwrap();
        }
    }
    riskplan_math::poly::rational_to_f64(&p.eval(&vals))
}
