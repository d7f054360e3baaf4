use super::*;
use crate::poly::{Monomial, Poly};
use crate::sdp::{SdpSettings, SdpStatus};

fn binom(n: usize, k: usize) -> usize {
    (0..k).fold(1, |acc, i| acc * (n - i) / (i + 1))
}

#[test]
fn monomials_are_graded_and_indexed() {
    for nv in 1..=4 {
        for d in 0..=5u32 {
            let m = Monomials::new(nv, d);
            assert_eq!(m.len(), binom(nv + d as usize, d as usize), "ν({nv}, {d})");
            for k in 0..=d {
                assert_eq!(m.count_up_to(k), binom(nv + k as usize, k as usize));
            }
            let mut last = 0;
            for i in 0..m.len() {
                let deg: u32 = m.exps(i).iter().map(|&e| e as u32).sum();
                assert!(deg >= last, "graded order");
                last = deg;
                assert_eq!(m.index(m.exps(i)), Some(i));
            }
            assert_eq!(m.exps(0), vec![0u8; nv].as_slice());
        }
    }
    let m = Monomials::new(2, 4);
    let (a, b) = (m.power(0, 1).unwrap(), m.power(1, 3).unwrap());
    assert_eq!(m.exps(m.product(a, b).unwrap()), &[1, 3]);
    assert_eq!(m.product(m.power(0, 3).unwrap(), m.power(1, 2).unwrap()), None, "degree 5 > 4");
}

fn solve(model: &Model) -> crate::sdp::SdpSolution {
    let sol = model.solve(&SdpSettings::default()).unwrap();
    assert!(matches!(sol.status, SdpStatus::Solved | SdpStatus::AlmostSolved), "{:?}", sol.status);
    sol
}

/// Side 1: `max γ  s.t.  p(t) − γ ≥ 0 on [0, 1]` gives `min_[0,1] p`, for even and odd
/// degrees (the odd one has its minimum at an end, the even one inside).
#[test]
fn scalar_lukacs_gives_the_minimum_on_the_interval() {
    // p = 1 − 3t + 2.5t² − 0.2t³ ; and p = (t − 0.3)² (t − 0.8)² + 0.05
    let cases: Vec<(Vec<f64>, f64)> = vec![(vec![1.0, -3.0, 2.5, -0.2], f64::NAN), {
        let a = [0.3, 0.8];
        // (t² − 1.1t + 0.24)² + 0.05
        let q = [0.24, -(a[0] + a[1]), 1.0];
        let mut c = vec![0.0; 5];
        for i in 0..3 {
            for j in 0..3 {
                c[i + j] += q[i] * q[j];
            }
        }
        c[0] += 0.05;
        (c, 0.05)
    }];
    for (p, expected) in cases {
        let mut model = Model::new();
        let g = model.add_var();
        let entries = vec![p
            .iter()
            .enumerate()
            .map(|(l, &c)| AffineExpr { constant: c, terms: if l == 0 { vec![(g, -1.0)] } else { vec![] } })
            .collect::<Vec<_>>()];
        let sizes = add_matrix_lukacs(&mut model, 1, &entries).unwrap();
        assert_eq!(sizes.degree, p.len() - 1);
        model.set_objective(&[(g, -1.0)]).unwrap();
        let sol = solve(&model);
        let grid_min = (0..=20000)
            .map(|i| i as f64 / 20000.0)
            .map(|t| p.iter().rev().fold(0.0, |a, &c| a * t + c))
            .fold(f64::INFINITY, f64::min);
        let want = if expected.is_nan() { grid_min } else { expected };
        assert!((sol.x[g.index()] - want).abs() < 1e-6, "γ = {} vs {want}", sol.x[g.index()]);
    }
}

/// Side 2 with `t` everywhere: `[[1+t, y·t], [y·t, 1]] ⪰ 0 ∀t ∈ [0,1]` iff
/// `y²t² ≤ 1 + t`, i.e. `|y| ≤ √2` (binding at t = 1).
#[test]
fn matrix_lukacs_is_exact_on_a_two_by_two() {
    let mut model = Model::new();
    let y = model.add_var();
    let c = |v: f64| AffineExpr::constant(v);
    // svec order: (0,0), (0,1), (1,1)
    let entries = vec![vec![c(1.0), c(1.0)], vec![c(0.0), AffineExpr::var(y)], vec![c(1.0)]];
    let sizes = add_matrix_lukacs(&mut model, 2, &entries).unwrap();
    assert_eq!((sizes.q0, sizes.q1), (4, 2));
    model.set_objective(&[(y, -1.0)]).unwrap();
    let sol = solve(&model);
    assert!((sol.x[y.index()] - 2f64.sqrt()).abs() < 1e-6, "y = {}", sol.x[y.index()]);
}

/// A moment relaxation: `min E[z1]` over measures on the unit disk (`K = 2`) is −1,
/// attained by the Dirac at (−1, 0): the first moments read it out and the moment
/// matrix has rank one.
#[test]
fn moment_relaxation_on_the_disk() {
    let mut model = Model::new();
    let y = MomentVars::new(&mut model, 2, 2);
    y.moment_matrix(&mut model).unwrap();
    let mut g = Poly::<f64>::constant(1.0);
    g.add_term(Monomial::var_pow(0, 2), -1.0);
    g.add_term(Monomial::var_pow(1, 2), -1.0);
    let gz = ZtPoly::from_poly(&g, 2).unwrap();
    let (side, entries) = y.localizing(&gz).unwrap();
    assert_eq!(side, 1);
    add_matrix_lukacs(&mut model, side, &entries).unwrap();
    let e1 = y.monomials().power(0, 1).unwrap();
    model.set_objective(&[(y.var(e1).unwrap(), 1.0)]).unwrap();
    let sol = solve(&model);
    assert!((y.mean(&sol.x, 0) + 1.0).abs() < 1e-6);
    assert!(y.mean(&sol.x, 1).abs() < 1e-5);
    let e11 = y.monomials().power(0, 2).unwrap();
    assert!((y.value(&sol.x, e11) - 1.0).abs() < 1e-5, "E[z1²] = 1 at a Dirac");
    // a constraint of degree above K is refused, not dropped
    let mut big = Poly::<f64>::constant(1.0);
    big.add_term(Monomial::var_pow(0, 4), -1.0);
    assert!(y.localizing(&ZtPoly::from_poly(&big, 2).unwrap()).is_none());
}

/// A time-dependent localizing constraint: the measure on `z` must satisfy
/// `z − t ≥ 0` for every `t ∈ [0, 1]`, so `min E[z]` is 1.
#[test]
fn time_dependent_localizing_holds_for_every_t() {
    let mut model = Model::new();
    let y = MomentVars::new(&mut model, 1, 2);
    y.moment_matrix(&mut model).unwrap();
    let g = ZtPoly { terms: vec![(vec![0], vec![0.0, -1.0]), (vec![1], vec![1.0])] };
    let (side, entries) = y.localizing(&g).unwrap();
    assert_eq!(side, 1);
    add_matrix_lukacs(&mut model, side, &entries).unwrap();
    // and z ≤ 3 (bounded)
    let ub = ZtPoly { terms: vec![(vec![0], vec![3.0]), (vec![1], vec![-1.0])] };
    let (s2, e2) = y.localizing(&ub).unwrap();
    add_matrix_lukacs(&mut model, s2, &e2).unwrap();
    model.set_objective(&[(y.var(1).unwrap(), 1.0)]).unwrap();
    let sol = solve(&model);
    assert!((y.mean(&sol.x, 0) - 1.0).abs() < 1e-6, "E[z] = {}", y.mean(&sol.x, 0));
}
