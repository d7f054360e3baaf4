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

mod recurrences {
    //! The moment recurrences of `raw_moments` against the formulas they rearrange,
    //! evaluated term by term with each power formed anew (exact rationals: equal, not
    //! close), and the uniform law against its closed form (b^(n+1) − a^(n+1))/((n+1)(b − a)).
    use super::*;
    use proptest::prelude::*;

    fn pw(v: &BigRational, k: usize) -> BigRational {
        num_traits::pow(v.clone(), k)
    }

    fn ratio() -> impl Strategy<Value = BigRational> {
        (-2000i64..2000, 1i64..400).prop_map(|(n, d)| q(n, d))
    }

    const ORDER: u32 = 24;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        #[test]
        fn uniform_moments_are_the_closed_form(a in ratio(), w in (1i64..3000, 1i64..300)) {
            let b = &a + q(w.0, w.1);
            let m = Distribution::Uniform { low: a.clone(), high: b.clone() }.raw_moments(ORDER).unwrap();
            for (n, mn) in m.iter().enumerate() {
                let closed = (pw(&b, n + 1) - pw(&a, n + 1)) / (q(n as i64 + 1, 1) * (&b - &a));
                prop_assert_eq!(mn, &closed, "order {}", n);
            }
        }

        #[test]
        fn normal_moments_follow_their_recurrence(mu in ratio(), s in (0i64..3000, 1i64..300)) {
            let std = q(s.0, s.1);
            let m = Distribution::Normal { mean: mu.clone(), std: std.clone() }.raw_moments(ORDER).unwrap();
            // m_n = μ·m_(n-1) + (n−1)·σ²·m_(n-2), in rationals
            let var = &std * &std;
            let mut want = vec![q(1, 1)];
            for n in 1..=ORDER as usize {
                let prev2 = if n >= 2 { want[n - 2].clone() } else { q(0, 1) };
                let next = &mu * &want[n - 1] + q(n as i64 - 1, 1) * &var * prev2;
                want.push(next);
            }
            prop_assert_eq!(&m, &want);
            // centred: m_2k = σ^2k·(2k − 1)!!, the odd ones 0
            let c = Distribution::Normal { mean: q(0, 1), std: std.clone() }.raw_moments(ORDER).unwrap();
            for (n, cn) in c.iter().enumerate() {
                let closed = if n % 2 == 1 { q(0, 1) } else { pw(&std, n) * (1..n).step_by(2).fold(q(1, 1), |a, i| a * q(i as i64, 1)) };
                prop_assert_eq!(cn, &closed, "centred, order {}", n);
            }
        }

        #[test]
        fn beta_laplace_and_discrete_moments_are_their_sums(
            lo in ratio(), w in (1i64..3000, 1i64..300), al in (1i64..40, 1i64..8), be in (1i64..40, 1i64..8),
            mu in ratio(), sc in (1i64..500, 1i64..300),
            atoms in proptest::collection::vec((ratio(), 1i64..50), 1..6),
        ) {
            let k = ORDER as usize;
            let (alpha, beta, width) = (q(al.0, al.1), q(be.0, be.1), q(w.0, w.1));
            let high = &lo + &width;
            let m = Distribution::Beta { alpha: alpha.clone(), beta: beta.clone(), low: lo.clone(), high }
                .raw_moments(ORDER).unwrap();
            // b_j = E[u^j] of beta(α, β) on [0, 1] = Π_(i<j) (α + i)/(α + β + i)
            let bj = |j: usize| (0..j).fold(q(1, 1), |acc, i| acc * (&alpha + q(i as i64, 1)) / (&alpha + &beta + q(i as i64, 1)));
            for (n, mn) in m.iter().enumerate().take(k + 1).skip(1) {
                let sum: BigRational = (0..=n)
                    .map(|j| binomial(n as u32, j as u32) * pw(&lo, n - j) * pw(&width, j) * bj(j))
                    .sum();
                prop_assert_eq!(mn, &sum, "beta, order {}", n);
            }
            let scale = q(sc.0, sc.1);
            let m = Distribution::Laplace { mean: mu.clone(), scale: scale.clone() }.raw_moments(ORDER).unwrap();
            for (n, mn) in m.iter().enumerate().skip(1) {
                let sum: BigRational = (0..=n)
                    .step_by(2)
                    .map(|j| binomial(n as u32, j as u32) * pw(&mu, n - j) * factorial(j as u32) * pw(&scale, j))
                    .sum();
                prop_assert_eq!(mn, &sum, "laplace, order {}", n);
            }
            let total: i64 = atoms.iter().map(|a| a.1).sum();
            let values: Vec<BigRational> = atoms.iter().map(|a| a.0.clone()).collect();
            let weights: Vec<BigRational> = atoms.iter().map(|a| q(a.1, total)).collect();
            let m = Distribution::Discrete { values: values.clone(), weights: weights.clone() }.raw_moments(ORDER).unwrap();
            for (n, mn) in m.iter().enumerate() {
                let sum: BigRational = values.iter().zip(&weights).map(|(v, w)| w * pw(v, n)).sum();
                prop_assert_eq!(mn, &sum, "discrete, order {}", n);
            }
        }
    }
}
