//! Risk bound at a point over all obstacles of example-d1-cluttered-2d (8 discs):
//! the exact rational bound (what `riskplan risk` prints) and the f64 one (plots).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use num_rational::BigRational;
use riskplan::scene::Scene;

fn scene() -> Scene {
    let dir = std::env::var("RISKPLAN_REFERENCE_SCENES")
        .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/reference/scenes").to_string());
    let text = std::fs::read_to_string(format!("{dir}/example-d1-cluttered-2d.json")).expect("reference scene");
    Scene::from_json(&text).expect("valid scene")
}

fn bench(c: &mut Criterion) {
    let s = scene();
    let xq: Vec<BigRational> = [2.5, 3.1, 0.0].iter().map(|&v| BigRational::from_float(v).unwrap()).collect();
    let xf = [2.5, 3.1, 0.0];
    c.bench_function("risk_bound_exact_d1_all_obstacles", |b| {
        b.iter(|| s.obstacles.iter().map(|o| o.contour.risk_at(black_box(&xq)).bound).max())
    });
    c.bench_function("risk_bound_f64_d1_all_obstacles", |b| {
        b.iter(|| s.obstacles.iter().map(|o| o.contour.bound_f64(black_box(&xf))).fold(0.0, f64::max))
    });
    c.bench_function("scene_load_d1_with_contours", |b| {
        let dir = std::env::var("RISKPLAN_REFERENCE_SCENES")
            .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/reference/scenes").to_string());
        let text = std::fs::read_to_string(format!("{dir}/example-d1-cluttered-2d.json")).unwrap();
        b.iter(|| Scene::from_json(black_box(&text)).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
