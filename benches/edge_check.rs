//! The planner's edge check: the scene certifier on straight edges.
//!
//! - `kernel/disk_near`: one degree-4 contour (illustrative-3), an edge that passes near
//!   the obstacle (inside its cover, so the compiled restriction and both proofs run);
//! - `edges/<scene>`: 256 seeded random edges of the planner's length; the time is per
//!   batch, divide by 256 for an edge and by the obstacle count for an obstacle;
//! - `growth/disks-<n>`: the same on the constant-density disk family (8 … 512 disks);
//! - `first_plan/disks-<n>`: the default planner's first certified plan on that family;
//! - `bounds/*`: the same random edges with `bound: cantelli` and `auto`, and on
//!   a disk of radius 0.3 with a Gaussian centre (σ = 0.05) at Δ = 10⁻³ one edge that
//!   Cantelli proves (3.5 from the centre) and one that only the moment bounds prove (0.7).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use riskplan_app::verify::{Method, SceneCertifier};
use riskplan_math::contour::BoundChoice;
use riskplan_plan::MotionChecker;
use riskplan_scene::{Piece, Scene};
use std::sync::Arc;

mod common;

fn edges(s: &Scene, len: f64, n: usize, seed: u64) -> Vec<Piece> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (lo, hi) = (&s.workspace.lower, &s.workspace.upper);
    (0..n)
        .map(|_| {
            let a: Vec<f64> = lo.iter().zip(hi).map(|(&l, &h)| rng.random_range(l..h)).collect();
            let dir: Vec<f64> = (0..a.len()).map(|_| rng.random_range(-1.0..1.0)).collect();
            let norm = dir.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-9);
            let b: Vec<f64> =
                a.iter().zip(&dir).enumerate().map(|(d, (x, v))| (x + len * v / norm).clamp(lo[d], hi[d])).collect();
            Piece::segment(&a, &b, s.horizon.0, s.horizon.1)
        })
        .collect()
}

fn certifier(s: Scene) -> SceneCertifier {
    certifier_with(s, BoundChoice::default())
}

fn certifier_with(s: Scene, bound: BoundChoice) -> SceneCertifier {
    let delta = s.risk.clone();
    let c = SceneCertifier::new(Arc::new(s), delta, Method::Exact).with_bounds(bound);
    let _ = c.index(); // build the covers outside the measurement
    c
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("kernel");
    let cert = certifier(common::reference_scene("illustrative-3"));
    let near = Piece::segment(&[-1.0, -0.8], &[1.0, -0.8], 0.0, 1.0);
    assert_eq!(cert.check(&near), riskplan_plan::Motion::Accepted);
    g.bench_function("disk_near", |b| b.iter(|| cert.check(black_box(&near))));
    g.finish();

    let mut g = c.benchmark_group("edges");
    for (stem, len) in [("illustrative-3", 1.0), ("example-d1-cluttered-2d", 1.0)] {
        let s = common::reference_scene(stem);
        let es = edges(&s, len, 256, 1);
        let cert = certifier(s);
        g.bench_function(stem, |b| {
            b.iter(|| es.iter().filter(|e| cert.check(e) == riskplan_plan::Motion::Accepted).count())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("bounds");
    for (stem, len) in [("illustrative-3", 1.0), ("example-d1-cluttered-2d", 1.0)] {
        for bound in [BoundChoice::Cantelli, BoundChoice::Auto] {
            let s = common::reference_scene(stem);
            let es = edges(&s, len, 256, 1);
            let cert = certifier_with(s, bound);
            // warm: the compiled bounds are built by the first check that needs them
            let _ = es.iter().filter(|e| cert.check(e) == riskplan_plan::Motion::Accepted).count();
            g.bench_function(format!("{stem}-{bound}"), |b| {
                b.iter(|| es.iter().filter(|e| cert.check(e) == riskplan_plan::Motion::Accepted).count())
            });
        }
    }
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/scenes/bounds/gaussian-centre-disk.json");
    let gauss = Scene::from_json(&std::fs::read_to_string(path).expect("scene")).expect("scene");
    let cert = certifier_with(gauss, BoundChoice::Auto);
    for (name, y) in [("gaussian-disk-cantelli-edge", 3.5), ("gaussian-disk-moment-edge", 0.7)] {
        let e = Piece::segment(&[-1.0, y], &[1.0, y], 0.0, 1.0);
        assert_eq!(cert.check(&e), riskplan_plan::Motion::Accepted, "{name}");
        g.bench_function(name, |b| b.iter(|| cert.check(black_box(&e))));
    }
    g.finish();

    let mut g = c.benchmark_group("growth");
    g.sample_size(20);
    for n in [8usize, 32, 128, 512] {
        let s = Scene::from_json(&common::disks_scene(n, 1)).expect("disk scene");
        let es = edges(&s, 5.0, 256, 2);
        let t = std::time::Instant::now();
        let cert = certifier(s);
        eprintln!("disks-{n}: covers built in {:.3} s ({} cells)", t.elapsed().as_secs_f64(), cert.index().cells());
        let sizes: Vec<f64> = cert.index().cover_hulls().iter().flatten().map(|h| h[0].1 - h[0].0).collect();
        let mut c = Vec::new();
        let mut total = 0;
        for e in &es {
            let bb = riskplan_certify::checker::piece_bbox(riskplan_certify::PieceRef {
                t0: e.t0,
                t1: e.t1,
                coeffs: &e.coeffs,
            });
            cert.index().candidates(bb.as_deref(), e.t0, e.t1, &mut c);
            total += c.len();
        }
        eprintln!(
            "  mean cover width {:.2}, max {:.2}; candidates per edge {:.2}",
            sizes.iter().sum::<f64>() / sizes.len() as f64,
            sizes.iter().cloned().fold(0.0, f64::max),
            total as f64 / es.len() as f64
        );
        g.bench_function(format!("disks-{n}"), |b| {
            b.iter(|| es.iter().filter(|e| cert.check(e) == riskplan_plan::Motion::Accepted).count())
        });
    }
    g.finish();

    // time to the first certified plan on the same family (the scene's SceneKernel kept,
    // as the service's registry entry keeps it: the covers built so far are kept, and an
    // obstacle's are built when an edge first needs them); no smoothing
    let mut g = c.benchmark_group("first_plan");
    g.sample_size(10);
    // (per pass: warm, steady)
    let mut edge_8: [Option<f64>; 2] = [None; 2];
    for n in [8usize, 32, 128, 512] {
        let s = Arc::new(Scene::from_json(&common::disks_scene(n, 1)).expect("disk scene"));
        let kernel = riskplan_app::verify::SceneKernel::from(s.clone());
        let request = riskplan_app::PlanRequest { smooth: false, ..Default::default() };
        let (_, out) = request.run(&kernel, None).expect("plan");
        assert!(out.certified, "disks-{n}: {:?}", out.reason);
        let smoothed = riskplan_app::PlanRequest::default().run(&kernel, None).expect("plan").1;
        // the whole default plan, warm (targets: ≤ 3× its first path; its edges' cost
        // ≤ 5× that on 8 disks; docs/benchmarks.md, "In process"), seeds 1–8, medians; then
        // the same eight plans again ("steady": what their searches build on first use is
        // built by then — on a small scene the covers, built per obstacle where edges go;
        // from 64 obstacles every cover is built by the first plan, and a first pass still
        // compiles each obstacle's contour and moment bounds when an edge first comes near
        // it, a share of some first paths on 512 disks; a service answering the same robots
        // reaches this state)
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2])
        };
        for (k, pass) in ["warm", "steady"].into_iter().enumerate() {
            let mut ratios = Vec::new();
            let mut per_edge = Vec::new();
            for seed in 1..=8 {
                let req = riskplan_app::PlanRequest { seed, ..Default::default() };
                let st = req.run(&kernel, None).expect("plan").1.stats;
                let first = st.time_to_feasible_s.unwrap_or(f64::NAN);
                let edge = st.checker_time_s / st.edges_checked.max(1) as f64 * 1e6;
                let sm = st.smoothing.as_ref();
                ratios.push(st.planning_time_s / first);
                per_edge.push(edge);
                eprintln!(
                    "disks-{n} seed {seed}, whole default plan ({pass}): first path {:.3} ms, whole {:.2} ms ({:.1}x), post-processing {:.2} ms (shortcuts {:.2}, reduction {:.2}, blends {:.2}), final check {:.2} ms (verify path {:.2}, whole-path bound {:.2} ms), {} edges at {:.2} us each, length {:.2}",
                    first * 1e3,
                    st.planning_time_s * 1e3,
                    st.planning_time_s / first,
                    st.improve_time_s * 1e3,
                    sm.map_or(0.0, |s| s.shortcut_seconds) * 1e3,
                    sm.map_or(0.0, |s| s.reduction_seconds) * 1e3,
                    sm.map_or(0.0, |s| s.blend_seconds) * 1e3,
                    st.final_check.as_ref().map_or(0.0, |f| f.seconds) * 1e3,
                    st.final_check.as_ref().map_or(0.0, |f| f.verify_seconds) * 1e3,
                    st.final_check.as_ref().map_or(0.0, |f| f.whole_path_seconds) * 1e3,
                    st.edges_checked,
                    edge,
                    st.path_length.unwrap_or(f64::NAN)
                );
            }
            let edge = median(&mut per_edge);
            let base = *edge_8[k].get_or_insert(edge);
            eprintln!(
                "disks-{n}, whole default plan ({pass}), medians of 8 seeds: whole / first path {:.1}x, per checked edge {:.2} us ({:.1}x that on 8 disks)",
                median(&mut ratios),
                edge,
                edge / base
            );
        }
        eprintln!(
            "disks-{n}: first plan {:.4} s, {} edges, checker {:.4} s, final check {:.4} s ({} pieces); with smoothing {:.4} s, length {:.1} → {:.1}",
            out.stats.planning_time_s,
            out.stats.edges_checked,
            out.stats.checker_time_s,
            out.stats.final_check.as_ref().map_or(0.0, |f| f.seconds),
            out.stats.final_check.as_ref().map_or(0, |f| f.pieces),
            smoothed.stats.planning_time_s,
            out.stats.path_length.unwrap_or(f64::NAN),
            smoothed.stats.path_length.unwrap_or(f64::NAN)
        );
        g.bench_function(format!("disks-{n}"), |b| b.iter(|| request.run(&kernel, None).expect("plan").1.certified));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
