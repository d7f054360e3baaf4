//! `verify` of a 2-piece trajectory against all 8 obstacles of example-d1-cluttered-2d
//! (16 constraints per piece), with the exact checker and with SOS certificates, warm
//! (through one `SceneKernel`, as the service's registry entry keeps it) and cold (from
//! the bare scene: its framed contours compiled on every call); and the planners' fast
//! path (the scene certifier, stopping at the first failure).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use riskplan_app::verify::{verify, Method, SceneCertifier, SceneKernel};
use riskplan_plan::MotionChecker;
use riskplan_scene::{Piece, Trajectory};
use std::sync::Arc;

mod common;

fn bench(c: &mut Criterion) {
    let s = common::reference_scene("example-d1-cluttered-2d");
    // (0,0) → (1.5, 0.5) → (5, 5): two straight pieces over the horizon [0, 1]
    let traj = Trajectory::new(vec![
        Piece::segment(&[0.0, 0.0], &[1.5, 0.5], 0.0, 0.5),
        Piece::segment(&[1.5, 0.5], &[5.0, 5.0], 0.5, 1.0),
    ]);
    let delta = s.risk.clone();
    let kernel = SceneKernel::from(Arc::new(s.clone()));
    c.bench_function("verify_2_pieces_d1_exact", |b| {
        b.iter(|| verify(&kernel, black_box(&traj), &delta, Method::Exact, &Default::default()))
    });
    c.bench_function("verify_2_pieces_d1_sos", |b| {
        b.iter(|| verify(&kernel, black_box(&traj), &delta, Method::Sos, &Default::default()))
    });
    c.bench_function("verify_2_pieces_d1_exact_cold", |b| {
        b.iter(|| verify(&s, black_box(&traj), &delta, Method::Exact, &Default::default()))
    });
    let cert = SceneCertifier::new(Arc::new(s.clone()), delta.clone(), Method::Exact);
    let safe = Piece::segment(&[0.0, 0.0], &[1.5, 0.5], 0.0, 0.5);
    c.bench_function("scene_certifier_piece_d1_exact", |b| b.iter(|| cert.check(black_box(&safe))));
}

criterion_group!(benches, bench);
criterion_main!(benches);
