//! Speed of the eq. (15) SOS certifier (`riskplan_certify::positivity::sos`) on realistic
//! positive constraints: the disk `w² − x1² − x2²`, `w ~ U[0.3, 0.4]`, Δ = 0.1
//! (Example 3), restricted to trajectory pieces passing ≈ 0.5 from the disk.
//!
//! * degree 2: `g2 = −E[P] = ρ − 37/300` on the segment (−1, 0.85) → (1, 0.85);
//! * degree 4: `g1 = E[P]² − 0.9·E[P²]` on the same segment;
//! * degree 8: `g1` on the quadratic piece `(−1 + 2τ, 0.85 + 0.3τ(1−τ))`.
//!
//! Run with `OPENBLAS_NUM_THREADS=1 cargo bench --no-default-features --bench certify_sos`.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use num_rational::BigRational;
use riskplan_certify::positivity::sos::{certify, recheck, SosSettings};
use riskplan_math::poly::{Interval, UPoly};

fn q(n: i64, d: i64) -> BigRational {
    BigRational::new(n.into(), d.into())
}

/// (g1, g2) restricted to the path `(x1(τ), x2(τ))`, enclosed in intervals.
fn constraints(x1: UPoly<BigRational>, x2: UPoly<BigRational>) -> (UPoly<Interval>, UPoly<Interval>) {
    let rho = x1.mul(&x1).add(&x2.mul(&x2));
    let ep = UPoly::constant(q(37, 300)).sub(&rho);
    let ep2 = UPoly::constant(q(781, 50000)).sub(&rho.scale(&q(37, 150))).add(&rho.mul(&rho));
    let g1 = ep.mul(&ep).sub(&ep2.scale(&q(9, 10)));
    let g2 = ep.neg();
    (g1.map(Interval::enclose_rational), g2.map(Interval::enclose_rational))
}

fn bench(c: &mut Criterion) {
    let seg_x1 = UPoly::new(vec![q(-1, 1), q(2, 1)]);
    let seg_x2 = UPoly::constant(q(85, 100));
    let (g1_seg, g2_seg) = constraints(seg_x1.clone(), seg_x2);
    let quad_x2 = UPoly::new(vec![q(85, 100), q(3, 10), q(-3, 10)]);
    let (g1_quad, _) = constraints(seg_x1, quad_x2);
    // the interior-point path (what every certificate cost before the construction)
    let settings = SosSettings { construct: false, ..SosSettings::default() };
    let cases = [("deg2", &g2_seg), ("deg4", &g1_seg), ("deg8", &g1_quad)];
    for (name, p) in cases {
        let out = certify(p, &settings);
        assert_eq!(p.degree(), name[3..].parse::<usize>().unwrap());
        assert!(out.verdict.is_safe(), "{name}: {:?}", out.verdict);
        let cert = out.certificate.expect("certificate");
        eprintln!("{name}: {:?}, {} iterations", out.verdict, cert.iterations);
    }
    let mut g = c.benchmark_group("certify_sos");
    for (name, p) in cases {
        g.bench_function(name, |b| b.iter(|| certify(black_box(p), &settings)));
    }
    // opt-in solver reuse (skips Clarabel's setup; see SosSettings::reuse_solver)
    let reuse = SosSettings { reuse_solver: true, ..settings.clone() };
    g.bench_function("deg4_reuse", |b| b.iter(|| certify(black_box(&g1_seg), &reuse)));
    // one illustrative-3 piece = both constraints (g1 degree 4, g2 degree 2), the unit the
    // Python peers are timed on (scripts/sos_peers.py): the default (constructed
    // certificate, SDP only as a fallback), the SDP alone, and the prepared SDP
    let default = SosSettings::default();
    for (label, s) in [("piece_default", &default), ("piece_sdp", &settings), ("piece_sdp_reuse", &reuse)] {
        let (a, b) = (certify(&g1_seg, s), certify(&g2_seg, s));
        assert!(a.verdict.is_safe() && b.verdict.is_safe(), "{label}");
        if label == "piece_default" {
            let built = |o: &riskplan_certify::positivity::sos::SosOutcome| {
                o.certificate.as_ref().is_some_and(|c| c.constructed)
            };
            assert!(built(&a) && built(&b), "the default path constructs both certificates");
        }
        g.bench_function(label, |bch| bch.iter(|| (certify(black_box(&g1_seg), s), certify(black_box(&g2_seg), s))));
    }
    for (name, p) in cases {
        g.bench_function(format!("{name}_default"), |b| b.iter(|| certify(black_box(p), &default)));
    }
    let cert = certify(&g1_seg, &settings).certificate.expect("certificate");
    g.bench_function("recheck_deg4", |b| b.iter(|| recheck(black_box(&g1_seg), black_box(&cert))));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
