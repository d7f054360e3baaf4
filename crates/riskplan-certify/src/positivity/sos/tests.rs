use super::*;
use num_rational::BigRational;
use proptest::prelude::*;
use riskplan_math::poly::{f64_shortest_decimal, f64_to_rational, Ring};

fn q(n: i64, d: i64) -> BigRational {
    BigRational::new(n.into(), d.into())
}

/// Exact rational coefficients → outward enclosures.
fn enclose(c: &[BigRational]) -> UPoly<Interval> {
    UPoly::new(c.iter().map(Interval::enclose_rational).collect())
}

/// Float coefficients taken as exact.
fn points(c: &[f64]) -> UPoly<Interval> {
    UPoly::new(c.iter().map(|&x| Interval::point(x)).collect())
}

fn horner_f(c: &[f64], t: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &a| acc * t + a)
}

/// Test oracle: min of `p` on [0, 1] from endpoints, a dense grid and the bisected
/// roots of `p'` (f64; accurate to ~1e-12 for the well-scaled polynomials used).
fn oracle_min(c: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = c.iter().enumerate().skip(1).map(|(k, a)| k as f64 * a).collect();
    let n = 4000;
    let mut best = (horner_f(c, 0.0), 0.0);
    let mut consider = |t: f64| {
        let v = horner_f(c, t);
        if v < best.0 {
            best = (v, t);
        }
    };
    consider(1.0);
    for j in 0..n {
        let (a, b) = (j as f64 / n as f64, (j + 1) as f64 / n as f64);
        consider(a);
        let (fa, fb) = (horner_f(&d, a), horner_f(&d, b));
        if fa <= 0.0 && fb >= 0.0 {
            let (mut lo, mut hi) = (a, b);
            for _ in 0..80 {
                let m = 0.5 * (lo + hi);
                if horner_f(&d, m) <= 0.0 {
                    lo = m;
                } else {
                    hi = m;
                }
            }
            consider(lo);
            consider(hi);
        }
    }
    best
}

/// The interior-point path alone (what most tests here exercise).
fn sdp_only() -> SosSettings {
    SosSettings { construct: false, ..SosSettings::default() }
}

fn run(p: &UPoly<Interval>) -> SosOutcome {
    certify(p, &sdp_only())
}

/// The default: the constructed certificate first, the SDP when it cannot be built.
fn run_default(p: &UPoly<Interval>) -> SosOutcome {
    certify(p, &SosSettings::default())
}

#[test]
fn bernstein_scale_examples() {
    // τ(1−τ): Bernstein (0, 1/2, 0)
    assert!((bernstein_scale(&[0.0, 1.0, -1.0]) - 0.5).abs() < 1e-15);
    // 1 − 2τ: (1, −1)
    assert!((bernstein_scale(&[1.0, -2.0]) - 1.0).abs() < 1e-15);
    assert_eq!(bernstein_scale(&[]), 0.0);
    assert_eq!(bernstein_scale(&[-3.0]), 3.0);
}

/// The double root (τ − 3/10)²: min p = 0, touching counts as unsafe, so never Safe.
#[test]
fn double_root_is_never_safe() {
    let p = enclose(&[q(9, 100), q(-6, 10), q(1, 1)]);
    assert!(!run_default(&p).verdict.is_safe());
    let out = run(&p);
    assert!(!out.verdict.is_safe(), "{:?}", out.verdict);
    if let Some(c) = &out.certificate {
        assert!(!recheck(&p, c).is_safe());
        assert!(c.gamma.abs() < 1e-6, "γ̂ = {}", c.gamma);
    }
    // the same shape, scaled up and at odd degree (times (2 + τ)), never Safe either
    let p3 = enclose(&[q(18, 100), q(-111, 100), q(14, 10), q(1, 1)]);
    assert!(!run(&p3).verdict.is_safe());
    // a coefficient interval that contains a tangent member: never Safe
    let wide =
        UPoly::new(vec![Interval::new(0.09, 0.0901), Interval::enclose_rational(&q(-6, 10)), Interval::point(1.0)]);
    assert!(!run(&wide).verdict.is_safe());
}

#[test]
fn lifted_double_root_is_safe() {
    let p = enclose(&[q(9, 100) + q(1, 1000), q(-6, 10), q(1, 1)]);
    let out = run(&p);
    match out.verdict {
        Verdict::Safe { margin } => {
            assert!(margin > 0.0 && margin <= 1e-3, "{margin}");
            assert!(margin > 0.9e-3, "margin {margin} should be close to 1e-3");
        }
        v => panic!("expected Safe, got {v:?}"),
    }
    let cert = out.certificate.expect("certificate");
    assert!(recheck(&p, &cert).is_safe());
    // serde round trip, then an independent re-check
    let json = serde_json::to_string(&cert).unwrap();
    let back: Certificate = serde_json::from_str(&json).unwrap();
    assert_eq!(recheck(&p, &back), recheck(&p, &cert));
}

#[test]
fn negative_is_unsafe_or_undecided() {
    // −τ(1−τ): zero at both ends, negative inside
    let p = points(&[0.0, -1.0, 1.0]);
    let out = run(&p);
    assert!(!out.verdict.is_safe());
    match out.verdict {
        Verdict::Unsafe(w) => {
            assert!((0.0..=1.0).contains(&w.tau) && w.value <= 0.0);
            assert!(p.eval(&Interval::point(w.tau)).hi <= 0.0);
        }
        Verdict::Undecided(_) => {}
        Verdict::Safe { .. } => unreachable!(),
    }
    // clearly negative somewhere: a witness must be found
    let p = points(&[0.1, -1.0, 1.0]); // min −0.15 at 1/2
    assert!(run(&p).verdict.is_unsafe(), "{:?}", run(&p).verdict);
}

#[test]
fn degree_zero_and_one() {
    assert_eq!(run(&points(&[2.0])).verdict, Verdict::Safe { margin: 2.0 });
    assert!(run(&points(&[-2.0])).verdict.is_unsafe());
    assert!(run(&UPoly::zero()).verdict.is_unsafe());
    assert!(matches!(
        run(&UPoly::constant(Interval::new(-1e-9, 1e-9))).verdict,
        Verdict::Undecided(Undecided::MarginTooSmall(_))
    ));
    match run(&points(&[1.0, -0.5])).verdict {
        Verdict::Safe { margin } => assert!(margin <= 0.5 && margin > 0.5 - 1e-15),
        v => panic!("{v:?}"),
    }
    // touching at τ = 1 (interval sum straddles 0): never Safe
    assert!(!run(&points(&[1.0, -1.0])).verdict.is_safe());
    assert!(run(&points(&[-0.5, 1.0])).verdict.is_unsafe());
    assert!(run(&points(&[1.0, -1.0])).certificate.is_none());
}

#[test]
fn non_finite_is_undecided() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let p = UPoly::new(vec![Interval::point(1.0), Interval::point(bad), Interval::point(1.0)]);
        assert_eq!(run(&p).verdict, Verdict::Undecided(Undecided::NonFinite), "{bad}");
        let cert = Certificate {
            scale: 1.0,
            gamma: 0.5,
            q0: vec![vec![0.0; 2]; 2],
            q1: vec![vec![0.0]],
            solver_status: SdpStatus::Solved,
            iterations: 0,
            constructed: false,
        };
        assert_eq!(recheck(&p, &cert), Verdict::Undecided(Undecided::NonFinite));
    }
    // huge and tiny coefficients: no panic, no false Safe, and positive polynomials
    // (c·(1 − τ + τ²), c·(1 + τ + τ²), c·(1 + τ²) with c > 0) never called unsafe
    assert!(!run(&points(&[-f64::MAX, f64::MAX, -f64::MAX])).verdict.is_safe());
    for c in [
        [f64::MAX, -f64::MAX, f64::MAX],
        [f64::MAX, f64::MAX, f64::MAX],
        [5e-324, -5e-324, 5e-324],
        [1e-300, 0.0, 1e-300],
    ] {
        let v = run(&points(&c)).verdict;
        assert!(!v.is_unsafe(), "{c:?} is positive on [0, 1], got {v:?}");
    }
}

#[test]
fn degree_limit_and_odd_degrees() {
    let s = SosSettings { max_degree: 3, ..SosSettings::default() };
    let p = points(&[1.0, 0.0, 0.0, 0.0, 1.0]);
    assert!(matches!(certify(&p, &s).verdict, Verdict::Undecided(Undecided::Solver(_))));
    // odd degree 3 and 5, positive: τ³ + 0.2, (τ − 0.5)⁴·τ + 0.01
    let p = points(&[0.2, 0.0, 0.0, 1.0]);
    assert!(run(&p).verdict.is_safe(), "{:?}", run(&p).verdict);
    let p = points(&[0.01, 0.0625, -0.5, 1.5, -2.0, 1.0]);
    assert!(run(&p).verdict.is_safe(), "{:?}", run(&p).verdict);
    // odd degree, negative inside: τ³ − τ/2
    let p = points(&[0.0, -0.5, 0.0, 1.0]);
    assert!(run(&p).verdict.is_unsafe());
}

/// Malformed or tampered certificates are rejected, never accepted.
#[test]
fn recheck_rejects_bad_certificates() {
    let p = enclose(&[q(9, 100) + q(1, 1000), q(-6, 10), q(1, 1)]);
    let cert = run(&p).certificate.expect("certificate");
    let mut c = cert.clone();
    c.gamma += 0.05; // claims a larger margin: the residual r_0 absorbs the lie
    match recheck(&p, &c) {
        Verdict::Safe { margin } => assert!(margin <= 1e-3, "{margin}"),
        v => panic!("{v:?}"),
    }
    c.gamma += 0.01; // now beyond what the residual bound can hide: never a larger margin
    if let Verdict::Safe { margin } = recheck(&p, &c) {
        assert!(margin <= 1e-3, "a tampered γ raised the margin to {margin}");
    }
    let mut c = cert.clone();
    c.q0.iter_mut().flatten().for_each(|v| *v *= 3.0);
    assert!(!recheck(&p, &c).is_safe());
    let mut c = cert.clone();
    c.q0[0][1] += 1e-3; // not symmetric
    assert!(matches!(recheck(&p, &c), Verdict::Undecided(Undecided::CertificateRejected(_))));
    let mut c = cert.clone();
    c.q0.pop(); // not square
    assert!(!recheck(&p, &c).is_safe());
    let mut c = cert.clone();
    c.scale = 0.0;
    assert!(!recheck(&p, &c).is_safe());
    let mut c = cert.clone();
    c.scale = f64::NAN;
    assert!(!recheck(&p, &c).is_safe());
    // a certificate for another polynomial
    let other = enclose(&[q(9, 100), q(-6, 10), q(1, 1)]);
    assert!(!recheck(&other, &cert).is_safe());
    // empty Gram matrices: LB = γ − |p_0 − γ| ≤ p_0, so exactly the positive constants
    let c = Certificate {
        scale: 1.0,
        gamma: 0.5,
        q0: vec![],
        q1: vec![],
        solver_status: SdpStatus::Solved,
        iterations: 0,
        constructed: false,
    };
    assert!(recheck(&points(&[0.5]), &c).is_safe());
    assert!(recheck(&points(&[0.4]), &c).is_safe());
    assert!(!recheck(&points(&[0.0]), &c).is_safe());
    assert!(!recheck(&points(&[-0.4]), &c).is_safe());
    assert!(!recheck(&points(&[0.5, -0.5]), &c).is_safe());
    // an indefinite Q0 costs min(λ0, 0)·s0: p = 1 + 0·τ², γ = 1, Q0 = diag(0, −0.1)
    // then residual r_2 = 0.1 and λ0 = −0.1: LB = 1 − 0.2 − 0.1 = 0.7 > 0
    let c = Certificate {
        scale: 1.0,
        gamma: 1.0,
        q0: vec![vec![0.0, 0.0], vec![0.0, -0.1]],
        q1: vec![vec![0.0]],
        solver_status: SdpStatus::Solved,
        iterations: 0,
        constructed: false,
    };
    match recheck(&points(&[1.0]), &c) {
        Verdict::Safe { margin } => assert!(margin <= 0.7 && margin > 0.69, "{margin}"),
        v => panic!("{v:?}"),
    }
}

#[test]
fn eigenvalue_bounds_are_sound() {
    assert!(ldl_positive_definite(&[vec![1.0, 0.0], vec![0.0, 1.0]], 0.0));
    assert!(!ldl_positive_definite(&[vec![1.0, 1.0], vec![1.0, 1.0]], 0.0));
    assert!(ldl_positive_definite(&[vec![1.0, 1.0], vec![1.0, 1.0]], -1e-9));
    assert!(!ldl_positive_definite(&[vec![1.0, 2.0], vec![2.0, 1.0]], 0.0));
    let l = eig_lower_bound_nonpos(&[vec![1.0, 2.0], vec![2.0, 1.0]]);
    assert!(l <= -1.0 && l > -1.0 - 1e-9, "{l}");
    assert!(gershgorin_lower(&[vec![1.0, 2.0], vec![2.0, 1.0]]) <= -1.0);
}

proptest! {
    /// The certified eigenvalue bound never exceeds the true smallest eigenvalue.
    #[test]
    fn eig_bound_below_min_eigenvalue(n in 1usize..6, vals in proptest::collection::vec(-2.0f64..2.0, 36), shift in -1.0f64..1.0) {
        let mut m = vec![vec![0.0; n]; n];
        for i in 0..n { for j in i..n { let v = vals[i * 6 + j]; m[i][j] = v; m[j][i] = v; } m[i][i] += shift; }
        let l = eig_lower_bound_nonpos(&m);
        let lam = DMatrix::from_fn(n, n, |i, j| m[i][j]).symmetric_eigen().eigenvalues.min();
        prop_assert!(l <= 0.0);
        prop_assert!(l <= lam + 1e-12 * (1.0 + lam.abs()), "bound {} above λmin {}", l, lam);
    }

    /// Soundness: Safe ⇒ no sampled point has a proven non-positive value, and the
    /// margin is below every sampled value; Safe ⇒ the certificate re-checks.
    #[test]
    fn safe_implies_no_sampled_refutation(c in proptest::collection::vec(-1.0f64..1.0, 3..7), shift in -0.2f64..0.3) {
        let mut c = c;
        c[0] += shift;
        let p = points(&c);
        for out in [run(&p), run_default(&p)] {
        if let Verdict::Safe { margin } = out.verdict {
            for j in 0..=1000 {
                let t = j as f64 / 1000.0;
                let v = p.eval(&Interval::point(t));
                prop_assert!(v.hi > 0.0, "Safe but p({}) ≤ 0", t);
                prop_assert!(margin <= v.hi, "margin {} above p({}) = {:?}", margin, t, v);
            }
            let cert = out.certificate.clone().expect("certificate for degree ≥ 2");
            prop_assert!(recheck(&p, &cert).is_safe());
        }
        if let Verdict::Unsafe(w) = out.verdict {
            prop_assert!(p.eval(&Interval::point(w.tau)).hi <= 0.0);
        }
        // γ̂ matches the true minimum when the solver converged fully
        if let Some(cert) = &out.certificate {
            if cert.solver_status == SdpStatus::Solved {
                let (m, _) = oracle_min(&c);
                prop_assert!((cert.gamma - m / cert.scale).abs() <= 1e-6, "γ̂ {} vs min {}", cert.gamma, m / cert.scale);
            }
            // a constructed certificate's γ is half its smallest Bernstein coefficient: below the minimum
            if cert.constructed {
                let (m, _) = oracle_min(&c);
                prop_assert!(cert.gamma > 0.0 && cert.gamma <= m / cert.scale, "γ {} vs min {}", cert.gamma, m / cert.scale);
            }
        }
        }
    }
}

/// Random positive polynomials (product of shifted squares and positive factors,
/// plus a positive lift) are (almost always) Safe, and γ̂ is accurate.
#[test]
fn random_positive_polynomials_are_safe() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let (mut safe, mut total, mut safe_default, mut built) = (0, 0, 0, 0);
    for _ in 0..200 {
        let deg: usize = rng.random_range(2..=8);
        let mut c: Vec<f64> = (0..=deg).map(|_| rng.random_range(-1.0..1.0)).collect();
        let (m, _) = oracle_min(&c);
        let lift = 10f64.powf(rng.random_range(-3.0..0.0));
        c[0] += lift - m;
        let p = points(&c);
        let constructed = run_default(&p);
        assert!(!constructed.verdict.is_unsafe(), "positive polynomial refuted: {c:?}");
        if constructed.verdict.is_safe() {
            built += usize::from(constructed.certificate.as_ref().is_some_and(|c| c.constructed));
            safe_default += 1;
        }
        let out = run(&p);
        total += 1;
        if out.verdict.is_safe() {
            safe += 1;
        }
        assert!(!out.verdict.is_unsafe(), "positive polynomial refuted: {c:?}");
        let cert = out.certificate.expect("certificate");
        if cert.solver_status == SdpStatus::Solved {
            let (m, _) = oracle_min(&c);
            assert!((cert.gamma - m / cert.scale).abs() <= 1e-6, "γ̂ {} vs {}", cert.gamma, m / cert.scale);
        }
    }
    assert!(safe * 100 >= total * 97, "only {safe}/{total} Safe");
    assert!(safe_default * 100 >= total * 97, "default: only {safe_default}/{total} Safe");
    eprintln!("constructed certificates: {built} of {safe_default} Safe");
    assert!(built > 0, "the construction never succeeded");
}

/// The authors' tangent case (docs/design.md §5.6, §8.5): Example 3, piece 2 of the
/// time-varying SOS output against g1 = E\[P\]² − 0.9·E\[P²\] of the disk w² − x1² − x2²,
/// w ~ U[0.3, 0.4]. Exactly, min g1 ≈ −1.5e-9 < 0 on the piece: never Safe.
#[test]
fn example3_piece2_tangent_is_not_safe() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes");
    let text = std::fs::read_to_string(format!("{dir}/illustrative-3.json"))
        .unwrap_or_else(|e| panic!("the reference scenes are required ({dir}/illustrative-3.json: {e})"));
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let piece = &v["expected"]["trajectories"]["time_varying_sos"]["global"][1];
    let f = |x: &serde_json::Value| x.as_f64().unwrap();
    let (t0, t1) = (f(&piece["interval"][0]), f(&piece["interval"][1]));
    // Both readings of the printed numbers: exact binary floats and decimal digits.
    for exact_of in [f64_to_rational as fn(f64) -> Option<BigRational>, f64_shortest_decimal] {
        let r = |x: f64| exact_of(x).unwrap();
        let (t0, t1) = (r(t0), r(t1));
        // absolute time t = t0 + (t1 − t0)τ; x_c = offset_c + slope_c·t
        let coord = |c: usize| {
            let (o, s) = (r(f(&piece["offset"][c])), r(f(&piece["slope"][c])));
            UPoly::new(vec![&o + &s * &t0, &s * (&t1 - &t0)])
        };
        let (x1, x2) = (coord(0), coord(1));
        let rho = x1.mul(&x1).add(&x2.mul(&x2));
        let ep = UPoly::constant(q(37, 300)).sub(&rho);
        let ep2 = UPoly::constant(q(781, 50000)).sub(&rho.scale(&q(37, 150))).add(&rho.mul(&rho));
        let g1 = ep.mul(&ep).sub(&ep2.scale(&q(9, 10)));
        assert_eq!(g1.degree(), 4);
        // the fixture really is (slightly) negative, exactly
        let fc: Vec<f64> = g1.coeffs().iter().map(f64::from_rational).collect();
        let (m, tmin) = oracle_min(&fc);
        let exact_at = g1.eval(&f64_to_rational(tmin).unwrap());
        assert!(exact_at < BigRational::from_integer(0.into()), "fixture min {m} at {tmin}");
        assert!(m > -1e-7 && (0.25..0.4).contains(&tmin), "min {m} at {tmin}");

        let p = enclose(g1.coeffs());
        assert!(!run_default(&p).verdict.is_safe(), "tangent piece certified (constructed)");
        let out = run(&p);
        assert!(!out.verdict.is_safe(), "tangent piece certified: {:?}", out.verdict);
        if let Some(c) = &out.certificate {
            assert!(!recheck(&p, c).is_safe());
        }
        if let Verdict::Unsafe(w) = out.verdict {
            assert!(p.eval(&Interval::point(w.tau)).hi <= 0.0);
        }
        eprintln!("Example 3 piece 2: min {m:e} at τ = {tmin:.4}: {:?}", out.verdict);
    }
}

/// The per-thread prepared solver (opt-in) agrees with a fresh solve to solver
/// tolerance, for a sequence of polynomials of mixed degrees (only `b` changes
/// between them). It is not bit-identical: Clarabel carries some internal state
/// from one solve to the next.
#[test]
fn solver_reuse_matches_fresh_solves() {
    let fresh = sdp_only();
    let reuse = SosSettings { reuse_solver: true, ..sdp_only() };
    let polys = [
        points(&[0.5, -1.0, 1.0]),
        points(&[0.3, -0.5, 0.2, 0.1, 0.4]),
        points(&[0.1, -1.0, 1.0]),
        points(&[0.01, 0.0625, -0.5, 1.5, -2.0, 1.0]),
        points(&[1.0, -0.8, 0.9, -0.5, 0.3]),
        points(&[0.3, -0.5, 0.2, 0.1, 0.4]),
    ];
    for p in &polys {
        for _ in 0..2 {
            let (a, b) = (certify(p, &fresh), certify(p, &reuse));
            assert_eq!(a.verdict.is_safe(), b.verdict.is_safe());
            let (ca, cb) = (a.certificate.unwrap(), b.certificate.unwrap());
            assert!((ca.gamma - cb.gamma).abs() < 1e-6, "{} vs {}", ca.gamma, cb.gamma);
        }
    }
}

/// The duals of the matching rows are moments of a measure on the minimisers (§5.5):
/// y1/y0 ≈ argmin p.
#[test]
fn dual_moments_locate_the_minimiser() {
    for (t0, lift) in [(0.7, 1e-4), (0.25, -1e-4), (0.5, 0.0)] {
        // (τ − t0)² (1 + τ²) + lift, degree 4
        let sq = [t0 * t0, -2.0 * t0, 1.0];
        let mut c = [0.0; 5];
        for (i, a) in sq.iter().enumerate() {
            c[i] += a;
            c[i + 2] += a;
        }
        c[0] += lift;
        let (sol, lay) = solve_margin_sdp(&c, 2, &SosSettings::default()).unwrap();
        let y = sol.duals(lay.eq_rows);
        let t = y[1] / y[0];
        assert!((t - t0).abs() < 1e-3, "τ* = {t}, expected {t0}");
        assert!((sol.value(lay.gamma) - lift).abs() < 1e-6);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]
    /// Near-tangent generator (§5.8, generator 1): p = a·(τ − r1)²·((τ − r2)² + d) ± 10^-k
    /// in exact rationals, r1 ∈ [0, 1]. With −10^-k, p(r1) < 0 exactly: never Safe;
    /// with +10^-k, p > 0: never Unsafe, and a Safe margin is at most p(r1) = 10^-k.
    #[test]
    fn near_tangent_never_misjudged(r1 in 0.0f64..=1.0, r2 in -1.0f64..2.0, d in 0.01f64..1.0,
                                    a in 0.1f64..10.0, k in 1i32..=12, neg in proptest::bool::ANY) {
        let r = |x: f64| f64_to_rational(x).unwrap();
        let lin = |root: f64| UPoly::new(vec![-r(root), q(1, 1)]);
        let eps = BigRational::new(1.into(), num_traits::pow(num_bigint::BigInt::from(10), k as usize));
        let eps = if neg { -eps } else { eps };
        let base = lin(r1).mul(&lin(r1)).mul(&lin(r2).mul(&lin(r2)).add(&UPoly::constant(r(d)))).scale(&r(a));
        let exact = base.add(&UPoly::constant(eps.clone()));
        let p = enclose(exact.coeffs());
        let out = run(&p);
        if neg {
            prop_assert!(!out.verdict.is_safe(), "p(r1) = {} < 0 but Safe", eps);
        } else {
            prop_assert!(!out.verdict.is_unsafe(), "p > 0 but {:?}", out.verdict);
        }
        match out.verdict {
            Verdict::Safe { margin } => {
                prop_assert!(r(margin) <= exact.eval(&r(r1)), "margin {} above p(r1)", margin);
            }
            Verdict::Unsafe(w) => {
                prop_assert!(exact.eval(&r(w.tau)) <= BigRational::from_integer(0.into()));
            }
            Verdict::Undecided(_) => {}
        }
    }
}

/// A solver status is never a verdict: an iteration or time limit gives
/// `Undecided(Solver(..))`, even for a clearly positive polynomial.
#[test]
fn solver_failures_are_undecided() {
    let p = points(&[1.0, -1.0, 1.0]);
    let mut s = sdp_only();
    s.sdp.max_iter = 1;
    let out = certify(&p, &s);
    assert_eq!(out.verdict, Verdict::Undecided(Undecided::Solver("MaxIterations".into())));
    assert!(out.certificate.is_none());
    let mut s = sdp_only();
    s.sdp.time_limit = 1e-12;
    assert!(matches!(certify(&p, &s).verdict, Verdict::Undecided(Undecided::Solver(_))));
    let mut s = sdp_only();
    s.sdp.tol_feas = f64::NAN; // rejected settings
    assert!(matches!(certify(&p, &s).verdict, Verdict::Undecided(Undecided::Solver(_))));
    // a NaN acceptance threshold never certifies
    let s = SosSettings { eps_acc: f64::NAN, ..SosSettings::default() };
    assert!(!certify(&p, &s).verdict.is_safe());
}
