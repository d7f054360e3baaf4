//! Risk bound at a point over all obstacles of example-d1-cluttered-2d (8 discs):
//! the exact rational bound (what `riskplan risk` prints) and the f64 one (plots).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use num_rational::BigRational;
use riskplan_scene::Scene;

mod common;

fn bench(c: &mut Criterion) {
    let s = common::reference_scene("example-d1-cluttered-2d");
    let xq: Vec<BigRational> = [2.5, 3.1, 0.0].iter().map(|&v| BigRational::from_float(v).unwrap()).collect();
    let xf = [2.5, 3.1, 0.0];
    c.bench_function("risk_bound_exact_d1_all_obstacles", |b| {
        b.iter(|| s.obstacles.iter().map(|o| o.contour.risk_at(black_box(&xq)).bound).max())
    });
    c.bench_function("risk_bound_f64_d1_all_obstacles", |b| {
        b.iter(|| s.obstacles.iter().map(|o| o.contour.bound_f64(black_box(&xf))).fold(0.0, f64::max))
    });
    c.bench_function("scene_load_d1_with_contours", |b| {
        let text = common::reference_text("example-d1-cluttered-2d");
        b.iter(|| Scene::from_json(black_box(&text)).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
