use super::*;
use rand::SeedableRng;

fn q(n: i64, d: i64) -> BigRational {
    BigRational::new(n.into(), d.into())
}

fn dec(s: &str) -> BigRational {
    crate::poly::parse_decimal(s).unwrap()
}

/// Test vectors of docs/design.md §2.4.
#[test]
fn closed_form_test_vectors() {
    let u = Distribution::Uniform { low: dec("0.3"), high: dec("0.4") };
    let m = u.raw_moments(4).unwrap();
    assert_eq!(m[2], q(37, 300));
    assert_eq!(m[4], q(781, 50000));
    let b = Distribution::Beta { alpha: q(3, 1), beta: q(3, 1), low: q(0, 1), high: q(1, 1) };
    let m = b.raw_moments(2).unwrap();
    assert_eq!((m[1].clone(), m[2].clone()), (q(1, 2), q(2, 7)));
    let n = Distribution::Normal { mean: q(0, 1), std: dec("0.1") };
    let m = n.raw_moments(4).unwrap();
    assert_eq!((m[1].clone(), m[2].clone(), m[3].clone(), m[4].clone()), (q(0, 1), q(1, 100), q(0, 1), q(3, 10000)));
}

/// Each family against an independent closed form.
#[test]
fn families_against_closed_forms() {
    // normal(μ, σ): m3 = μ³ + 3μσ², m4 = μ⁴ + 6μ²σ² + 3σ⁴
    let (mu, s) = (q(2, 1), q(1, 2));
    let m = Distribution::Normal { mean: mu.clone(), std: s.clone() }.raw_moments(4).unwrap();
    let s2 = &s * &s;
    assert_eq!(m[3], &mu * &mu * &mu + q(3, 1) * &mu * &s2);
    assert_eq!(m[4], num_traits::pow(mu.clone(), 4) + q(6, 1) * &mu * &mu * &s2 + q(3, 1) * &s2 * &s2);
    // gamma: θ^k Γ(κ+k)/Γ(κ); κ = 2, θ = 3: m2 = 9·2·3 = 54
    let m = Distribution::Gamma { shape: q(2, 1), scale: q(3, 1) }.raw_moments(2).unwrap();
    assert_eq!(m[2], q(54, 1));
    // exponential: k!/λ^k
    let m = Distribution::Exponential { rate: q(2, 1) }.raw_moments(3).unwrap();
    assert_eq!(m[3], q(6, 8));
    // laplace(μ, b): m2 = μ² + 2b², m4 = μ⁴ + 12μ²b² + 24b⁴
    let (mu, b) = (q(1, 1), q(1, 2));
    let m = Distribution::Laplace { mean: mu, scale: b }.raw_moments(4).unwrap();
    assert_eq!(m[2], q(3, 2));
    assert_eq!(m[4], q(1, 1) + q(3, 1) + q(24, 16));
    // scaled beta(1,1) on [2, 4] is uniform on [2, 4]
    let sb = Distribution::Beta { alpha: q(1, 1), beta: q(1, 1), low: q(2, 1), high: q(4, 1) };
    let un = Distribution::Uniform { low: q(2, 1), high: q(4, 1) };
    assert_eq!(sb.raw_moments(6).unwrap(), un.raw_moments(6).unwrap());
    // discrete
    let d = Distribution::Discrete { values: vec![q(-1, 1), q(2, 1)], weights: vec![q(1, 3), q(2, 3)] };
    assert_eq!(d.raw_moments(2).unwrap()[2], q(1, 3) + q(8, 3));
    // moments given directly
    let r = Distribution::Moments { raw: vec![q(0, 1), q(1, 1), q(0, 1), q(3, 1)] };
    assert_eq!(r.raw_moments(4).unwrap()[4], q(3, 1));
}

#[test]
fn validation_rejects_bad_parameters() {
    let err = |d: Distribution| d.validated().unwrap_err();
    assert!(matches!(
        err(Distribution::Uniform { low: q(1, 1), high: q(1, 1) }),
        MomentError::InvalidParameter { field: "high", .. }
    ));
    assert!(matches!(
        err(Distribution::Normal { mean: q(0, 1), std: q(-1, 1) }),
        MomentError::InvalidParameter { field: "std", .. }
    ));
    let beta = Distribution::Beta { alpha: q(0, 1), beta: q(1, 1), low: q(0, 1), high: q(1, 1) };
    assert!(matches!(err(beta), MomentError::InvalidParameter { field: "alpha", .. }));
    assert!(matches!(
        err(Distribution::Gamma { shape: q(1, 1), scale: q(-1, 1) }),
        MomentError::InvalidParameter { field: "scale", .. }
    ));
    assert!(matches!(
        err(Distribution::Exponential { rate: q(0, 1) }),
        MomentError::InvalidParameter { field: "rate", .. }
    ));
    assert!(matches!(
        err(Distribution::Laplace { mean: q(0, 1), scale: q(0, 1) }),
        MomentError::InvalidParameter { field: "scale", .. }
    ));
    let d = Distribution::Discrete { values: vec![q(1, 1), q(2, 1)], weights: vec![q(1, 2), q(1, 3)] };
    assert!(matches!(err(d), MomentError::InvalidParameter { field: "weights", .. }));
    let d = Distribution::Discrete { values: vec![q(1, 1)], weights: vec![q(1, 2), q(1, 2)] };
    assert!(matches!(err(d), MomentError::InvalidParameter { field: "weights", .. }));
    // near-1 sums are renormalised exactly
    let third = dec("0.3333333333333333");
    let d = Distribution::Discrete {
        values: vec![q(0, 1), q(1, 1), q(2, 1)],
        weights: vec![third.clone(), third.clone(), third],
    };
    let Distribution::Discrete { weights, .. } = d.validated().unwrap() else { panic!() };
    assert_eq!(weights.iter().sum::<BigRational>(), q(1, 1));
    // too few raw moments; non-moment sequence (E[w²] < E[w]²)
    let r = Distribution::Moments { raw: vec![q(0, 1), q(1, 1)] };
    assert_eq!(r.raw_moments(4), Err(MomentError::TooFewMoments { needed: 4, given: 2 }));
    let r = Distribution::Moments { raw: vec![q(1, 1), q(1, 2)] };
    assert!(matches!(r.raw_moments(2), Err(MomentError::NotMomentSequence { .. })));
    assert_eq!(r.sampler().unwrap_err(), MomentError::NotSampleable);
}

/// Sample moments agree with the exact ones (a loose 6-sigma check with 200k draws).
#[test]
fn moments_against_sampling() {
    let dists = [
        Distribution::Uniform { low: dec("0.3"), high: dec("0.4") },
        Distribution::Normal { mean: dec("0.1"), std: dec("0.2") },
        Distribution::Beta { alpha: q(9, 1), beta: q(1, 2), low: q(-1, 1), high: q(1, 1) },
        Distribution::Gamma { shape: q(3, 2), scale: q(1, 2) },
        Distribution::Exponential { rate: q(3, 1) },
        Distribution::Laplace { mean: q(1, 2), scale: q(1, 4) },
        Distribution::Discrete { values: vec![q(-1, 1), q(0, 1), q(3, 1)], weights: vec![q(1, 5), q(1, 2), q(3, 10)] },
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let n = 200_000;
    for d in dists {
        let exact = d.raw_moments(4).unwrap();
        let s = d.sampler().unwrap();
        let xs: Vec<f64> = (0..n).map(|_| s.sample(&mut rng)).collect();
        for k in 1..=2usize {
            let est = xs.iter().map(|x| x.powi(k as i32)).sum::<f64>() / n as f64;
            let m = crate::poly::rational_to_f64(&exact[k]);
            let var = crate::poly::rational_to_f64(&exact[2 * k]) - m * m;
            let se = (var / n as f64).sqrt();
            assert!((est - m).abs() <= 6.0 * se + 1e-12, "{} m{k}: sampled {est}, exact {m}, se {se}", d.kind());
        }
    }
}
