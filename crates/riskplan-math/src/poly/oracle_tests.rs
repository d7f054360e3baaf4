//! Independent oracles for [`taylor_shift`] and [`mean_and_second_moment`]: p(c + s·z)
//! evaluated at rational points, and E[P], E[P²] as finite sums over discrete atoms — no
//! moment, substitution or expectation code of the module.
//! Sparse variables, centres from 0 to ±f64::MAX and subnormal, scales 2^±1100, 0 and negative.
use super::*;
use num_rational::BigRational;
use num_traits::Pow;
use proptest::prelude::*;

fn q(n: i64, d: i64) -> BigRational {
    BigRational::new(n.into(), d.into())
}

/// Sparse variables (0, 1, 3, 5), degrees up to 6, coefficients with big denominators.
fn poly() -> impl Strategy<Value = QPoly> {
    prop::collection::vec(((0u32..7, 0u32..3, 0u32..4, 0u32..3), (-100000i64..100000, 1i64..1_000_000_007)), 0..10)
        .prop_map(|terms| {
            let mut p = QPoly::zero();
            for ((a, b, c, d), (n, den)) in terms {
                p.add_term(Monomial::from_pairs([(5, d), (0, a), (3, c), (1, b)]), q(n, den));
            }
            p
        })
}

fn centre() -> impl Strategy<Value = BigRational> {
    (0u8..6, -1e6f64..1e6, -1000i64..1000, 1i64..10007).prop_map(|(k, f, n, d)| match k {
        0 => BigRational::zero(),
        1 => BigRational::from_float(f).unwrap(),
        2 => BigRational::from_float(f * 1e300).unwrap(),
        3 => BigRational::from_float(f * 4.9e-318).unwrap_or_default(),
        4 => q(n, d),
        _ => BigRational::from_float(if n < 0 { -f64::MAX } else { f64::MAX }).unwrap(),
    })
}

fn scale() -> impl Strategy<Value = BigRational> {
    (0u8..4, -1100i32..1100, -50i64..50, 1i64..50).prop_map(|(k, e, n, d)| match k {
        0 | 1 => Pow::pow(&q(2, 1), e),
        2 => q(n, d), // includes 0 and negatives
        _ => -Pow::pow(&q(2, 1), e),
    })
}

fn maps() -> impl Strategy<Value = Vec<Option<(BigRational, BigRational)>>> {
    prop::collection::vec(prop::option::of((centre(), scale())), 0..8)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// taylor_shift(p, maps)(z) == p(c + s z) at a random rational point, and == subst.
    #[test]
    fn taylor_shift_pointwise(p in poly(), m in maps(), z in prop::collection::vec((-50i64..50, 1i64..30), 6)) {
        let fast = taylor_shift(&p, &m);
        let zs: Vec<BigRational> = z.iter().map(|&(n, d)| q(n, d)).collect();
        let xs: Vec<BigRational> = (0..6).map(|v| match m.get(v).cloned().flatten() {
            Some((c, s)) => c + s * &zs[v],
            None => zs[v].clone(),
        }).collect();
        prop_assert_eq!(fast.eval(&zs), p.eval(&xs));
        let slow = p.subst(&|v| m.get(v as usize).cloned().flatten().map(|(c, s)| Poly::var(v).scale(&s).add(&Poly::constant(c))));
        prop_assert_eq!(&fast, &slow);
        // canonical: no zero exponents, sorted
        for (mono, _) in fast.terms() {
            prop_assert!(mono.pairs().iter().all(|&(_, e)| e > 0));
            prop_assert!(mono.pairs().windows(2).all(|w| w[0].0 < w[1].0));
        }
    }

    /// E[P] and E[P^2] against the finite weighted sum over discrete atoms (an oracle that
    /// uses no moment at all), params a random subset of {0,1,3,5}.
    #[test]
    fn mean_and_second_against_atoms(
        p in poly(),
        mask in 0u8..16,
        atoms in prop::collection::vec(prop::collection::vec((-30i64..30, 1i64..20, 0i64..5), 1..4), 4),
        x in prop::collection::vec((-20i64..20, 1i64..9), 6),
    ) {
        let vars = [0u16, 1, 3, 5];
        let is_param = |v: Var| vars.iter().position(|&w| w == v).is_some_and(|i| mask & (1 << i) != 0);
        // atoms per param: (value, weight) weights normalised (zero weights allowed, not all zero)
        let laws: Vec<Vec<(BigRational, BigRational)>> = atoms.iter().map(|a| {
            let mut tot: i64 = a.iter().map(|t| t.2).sum();
            let a: Vec<(i64, i64, i64)> = if tot == 0 { tot = 1; a.iter().enumerate().map(|(i, t)| (t.0, t.1, (i == 0) as i64)).collect() } else { a.clone() };
            a.iter().map(|&(n, d, w)| (q(n, d), q(w, tot))).collect()
        }).collect();
        let law_of = |v: Var| &laws[vars.iter().position(|&w| w == v).unwrap()];
        let moment = |v: Var, k: u32| Some(law_of(v).iter().map(|(a, w)| w * Pow::pow(a, k)).sum::<BigRational>());
        let (m, s) = mean_and_second_moment(&p, is_param, moment).unwrap();
        for (mono, _) in m.terms().chain(s.terms()) {
            prop_assert!(mono.pairs().iter().all(|&(v, _)| !is_param(v)));
        }
        let xs: Vec<BigRational> = x.iter().map(|&(n, d)| q(n, d)).collect();
        // enumerate atom combinations of the params
        let params: Vec<Var> = vars.iter().copied().filter(|&v| is_param(v)).collect();
        let mut want_m = BigRational::zero();
        let mut want_s = BigRational::zero();
        let mut idx = vec![0usize; params.len()];
        loop {
            let mut pt = xs.clone();
            let mut w = BigRational::one();
            for (i, &v) in params.iter().enumerate() {
                let (a, wt) = &law_of(v)[idx[i]];
                pt[v as usize] = a.clone();
                w *= wt;
            }
            let val = p.eval(&pt);
            want_m += &w * &val;
            want_s += &w * &val * &val;
            // next
            let mut i = 0;
            while i < params.len() {
                idx[i] += 1;
                if idx[i] < law_of(params[i]).len() { break; }
                idx[i] = 0;
                i += 1;
            }
            if i == params.len() { break; }
        }
        prop_assert_eq!(m.eval(&xs), want_m);
        prop_assert_eq!(s.eval(&xs), want_s);
    }
}

#[test]
fn taylor_shift_exact_cases() {
    let zero = QPoly::zero();
    let m = vec![Some((q(3, 7), q(-2, 5)))];
    assert_eq!(taylor_shift(&zero, &m), zero);
    let c = QPoly::constant(q(-5, 3));
    assert_eq!(taylor_shift(&c, &m), c);
    // x0^3 with c = 0, s = 0: zero polynomial
    let p = QPoly::monomial(Monomial::var_pow(0, 3), q(1, 1));
    assert_eq!(taylor_shift(&p, &[Some((q(0, 1), q(0, 1)))]), QPoly::zero());
    // (x1)^2 with map only on var 0: unchanged
    let p1 = QPoly::monomial(Monomial::var_pow(1, 2), q(4, 9));
    assert_eq!(taylor_shift(&p1, &m), p1);
    // (x0 - 1/2)^2 at c = 1/2, s = 2^-1074: 2^-2148 z^2
    let p2 = Poly::var(0).add(&Poly::constant(q(-1, 2))).pow(2);
    let s = Pow::pow(&q(2, 1), -1074i32);
    let mut want = QPoly::zero();
    want.add_term(Monomial::var_pow(0, 2), &s * &s);
    assert_eq!(taylor_shift(&p2, &[Some((q(1, 2), s))]), want);
}

#[test]
fn mean_second_exact_cases() {
    // P = x*w + y*u + x*u - y*w (x=0,y=1 state, w=3,u=5 params): cross terms cancel
    let mut p = QPoly::zero();
    p.add_term(Monomial::from_pairs([(0, 1), (3, 1)]), q(1, 1));
    p.add_term(Monomial::from_pairs([(1, 1), (5, 1)]), q(1, 1));
    p.add_term(Monomial::from_pairs([(0, 1), (5, 1)]), q(1, 1));
    p.add_term(Monomial::from_pairs([(1, 1), (3, 1)]), q(-1, 1));
    let is_param = |v: Var| v >= 3;
    let moment = |v: Var, k: u32| Some(q(v as i64 + k as i64, 7));
    let (m, s) = mean_and_second_moment(&p, is_param, moment).unwrap();
    assert_eq!(m, p.expect(is_param, moment).unwrap());
    assert_eq!(s, p.mul(&p).expect(is_param, moment).unwrap());
    // zero and constant
    let (m, s) = mean_and_second_moment(&QPoly::zero(), is_param, moment).unwrap();
    assert!(m.is_zero() && s.is_zero());
    let c = QPoly::constant(q(-3, 4));
    let (m, s) = mean_and_second_moment(&c, is_param, moment).unwrap();
    assert_eq!((m, s), (c.clone(), QPoly::constant(q(9, 16))));
    // only params: E[w^2 - 2w] with moment zero values
    let mut p = QPoly::zero();
    p.add_term(Monomial::var_pow(3, 2), q(1, 1));
    p.add_term(Monomial::var_pow(3, 1), q(-2, 1));
    let moment0 = |_: Var, k: u32| Some(if k % 2 == 1 { q(0, 1) } else { q(1, 3) });
    let (m, s) = mean_and_second_moment(&p, is_param, moment0).unwrap();
    assert_eq!(m, QPoly::constant(q(1, 3)));
    // E[w^4 - 4w^3 + 4w^2] = 1/3 + 4/3
    assert_eq!(s, QPoly::constant(q(5, 3)));
}
