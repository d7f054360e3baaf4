//! `raw_moments` against oracles not derived from its recurrences: the uniform's closed
//! form, the normal's binomial sum, the Laplace and beta laws' mean, variance and fourth
//! central moment, discrete laws with zero-weight atoms; values from 0 and subnormal to
//! 10³⁰³.
use super::*;
use num_traits::Zero;
use proptest::prelude::*;

fn r(n: i64, d: i64) -> BigRational {
    BigRational::new(n.into(), d.into())
}
fn pw(v: &BigRational, k: usize) -> BigRational {
    num_traits::pow(v.clone(), k)
}
fn choose(n: usize, k: usize) -> BigRational {
    (0..k).fold(r(1, 1), |a, i| a * r((n - i) as i64, (i + 1) as i64))
}

fn val() -> impl Strategy<Value = BigRational> {
    (0u8..5, -2000i64..2000, 1i64..1_000_003, -1e3f64..1e3).prop_map(|(k, n, d, f)| match k {
        0 => BigRational::zero(),
        1 => r(n, d),
        2 => BigRational::from_float(f * 1e300).unwrap(),
        3 => BigRational::from_float(f * 1e-310).unwrap_or_default(),
        _ => r(n, 1),
    })
}

const K: u32 = 20;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn uniform_closed_form_or_point(a in val(), b in val()) {
        let m = Distribution::Uniform { low: a.clone(), high: b.clone() }.raw_moments(K).unwrap();
        prop_assert_eq!(m.len(), K as usize + 1);
        for (n, mn) in m.iter().enumerate() {
            let want = if a == b { pw(&a, n) } else { (pw(&b, n + 1) - pw(&a, n + 1)) / (r(n as i64 + 1, 1) * (&b - &a)) };
            prop_assert_eq!(mn, &want, "order {}", n);
        }
    }

    /// Normal: m_n = Σ_(j even) C(n,j) μ^(n−j) σ^j (j−1)!!, not the recurrence.
    #[test]
    fn normal_binomial_form(mu in val(), s in val()) {
        let m = Distribution::Normal { mean: mu.clone(), std: s.clone() }.raw_moments(K).unwrap();
        for (n, mn) in m.iter().enumerate() {
            let want: BigRational = (0..=n).step_by(2).map(|j| {
                let dfact = (1..j).step_by(2).fold(r(1, 1), |a, i| a * r(i as i64, 1));
                choose(n, j) * pw(&mu, n - j) * pw(&s, j) * dfact
            }).sum();
            prop_assert_eq!(mn, &want, "order {}", n);
        }
    }

    /// Laplace and beta: the first two moments against mean and variance.
    #[test]
    fn laplace_beta_mean_variance(mu in val(), b in (1i64..500, 1i64..300), lo in val(), w in (1i64..3000, 1i64..300), al in (1i64..40, 1i64..8), be in (1i64..40, 1i64..8)) {
        let sc = r(b.0, b.1);
        let m = Distribution::Laplace { mean: mu.clone(), scale: sc.clone() }.raw_moments(4).unwrap();
        prop_assert_eq!(&m[1], &mu);
        prop_assert_eq!(&m[2], &(&mu * &mu + r(2, 1) * &sc * &sc));
        // E[(X-μ)^4] = 24 b^4
        let c4 = &m[4] - r(4, 1) * &mu * &m[3] + r(6, 1) * &mu * &mu * &m[2] - r(4, 1) * pw(&mu, 3) * &m[1] + pw(&mu, 4);
        prop_assert_eq!(c4, r(24, 1) * pw(&sc, 4));
        let (a, bb, wd) = (r(al.0, al.1), r(be.0, be.1), r(w.0, w.1));
        let hi = &lo + &wd;
        let m = Distribution::Beta { alpha: a.clone(), beta: bb.clone(), low: lo.clone(), high: hi }.raw_moments(2).unwrap();
        let mean = &lo + &wd * &a / (&a + &bb);
        let var = &wd * &wd * &a * &bb / ((&a + &bb) * (&a + &bb) * (&a + &bb + r(1, 1)));
        prop_assert_eq!(&m[1], &mean);
        prop_assert_eq!(&m[2], &(&var + &mean * &mean));
    }

    /// Discrete: zero-weight atoms, repeated values, a single atom.
    #[test]
    fn discrete_with_zero_weights(atoms in prop::collection::vec((val(), 0i64..4), 1..6)) {
        let tot: i64 = atoms.iter().map(|a| a.1).sum::<i64>().max(1);
        let values: Vec<BigRational> = atoms.iter().map(|a| a.0.clone()).collect();
        let weights: Vec<BigRational> = atoms.iter().map(|a| r(a.1, tot)).collect();
        let m = Distribution::Discrete { values: values.clone(), weights: weights.clone() }.raw_moments(K).unwrap();
        for (n, mn) in m.iter().enumerate().skip(1) {
            let want: BigRational = values.iter().zip(&weights).map(|(v, w)| w * pw(v, n)).sum();
            prop_assert_eq!(mn, &want, "order {}", n);
        }
    }
}

#[test]
fn orders_zero_and_one() {
    for d in [
        Distribution::Uniform { low: r(-3, 7), high: r(5, 11) },
        Distribution::Normal { mean: r(-3, 7), std: r(0, 1) },
        Distribution::Discrete { values: vec![r(2, 3)], weights: vec![r(1, 1)] },
        Distribution::Laplace { mean: r(1, 3), scale: r(2, 5) },
    ] {
        assert_eq!(d.raw_moments(0).unwrap(), vec![r(1, 1)]);
        assert_eq!(d.raw_moments(1).unwrap().len(), 2);
    }
    let m = Distribution::Uniform { low: r(-3, 7), high: r(5, 11) }.raw_moments(1).unwrap();
    assert_eq!(m[1], (r(-3, 7) + r(5, 11)) / r(2, 1));
}
