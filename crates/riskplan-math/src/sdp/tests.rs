use super::*;
use proptest::prelude::*;

fn sym_matrix(n: usize, vals: &[f64]) -> Vec<Vec<f64>> {
    let mut m = vec![vec![0.0; n]; n];
    for j in 0..n {
        for i in 0..=j {
            m[i][j] = vals[svec_index(i, j)];
            m[j][i] = m[i][j];
        }
    }
    m
}

proptest! {
    /// Raw and scaled packing are inverse to unpacking, and the scaled svec turns the
    /// Frobenius inner product into a dot product (Clarabel's convention, §4).
    #[test]
    fn pack_unpack_round_trip(n in 1usize..7, raw in proptest::collection::vec(-10.0f64..10.0, 28), raw2 in proptest::collection::vec(-10.0f64..10.0, 28)) {
        let a = sym_matrix(n, &raw);
        let b = sym_matrix(n, &raw2);
        prop_assert_eq!(unpack_upper(&pack_upper(&a)).unwrap(), a.clone());
        let back = unpack_svec(&pack_svec(&a)).unwrap();
        for i in 0..n { for j in 0..n { prop_assert!((back[i][j] - a[i][j]).abs() <= 1e-12 * (1.0 + a[i][j].abs())); } }
        let dot: f64 = pack_svec(&a).iter().zip(pack_svec(&b)).map(|(x, y)| x * y).sum();
        let tr: f64 = (0..n).flat_map(|i| (0..n).map(move |j| (i, j))).map(|(i, j)| a[i][j] * b[j][i]).sum();
        prop_assert!((dot - tr).abs() <= 1e-9 * (1.0 + tr.abs()));
        prop_assert_eq!(svec_side(svec_len(n)), Some(n));
    }

    /// The CSC assembly reproduces the triplets (duplicates summed), in a valid format.
    #[test]
    fn csc_matches_triplets(rows in proptest::collection::vec(proptest::collection::vec((0usize..5, -3.0f64..3.0), 0..6), 1..8)) {
        let mut m = Model::new();
        let v = m.add_vars(5);
        let mut dense = vec![vec![0.0; 5]; rows.len()];
        for (r, terms) in rows.iter().enumerate() {
            let t: Vec<(Var, f64)> = terms.iter().map(|&(k, c)| (v[k], c)).collect();
            for &(k, c) in terms { dense[r][k] += c; }
            m.add_le(&t, 1.0).unwrap();
        }
        let a = m.csc_a();
        prop_assert!(a.check_format().is_ok());
        let mut rebuilt = vec![vec![0.0; 5]; rows.len()];
        for (c, w) in a.colptr.windows(2).enumerate() {
            for p in w[0]..w[1] { rebuilt[a.rowval[p]][c] += a.nzval[p]; }
        }
        for r in 0..rows.len() { for c in 0..5 { prop_assert!((rebuilt[r][c] - dense[r][c]).abs() < 1e-12); } }
    }
}

#[test]
fn svec_layout_is_column_major_upper() {
    // (0,0) (0,1) (1,1) (0,2) (1,2) (2,2)
    assert_eq!(svec_index(0, 0), 0);
    assert_eq!(svec_index(0, 1), 1);
    assert_eq!(svec_index(1, 1), 2);
    assert_eq!(svec_index(0, 2), 3);
    assert_eq!(svec_index(2, 1), 4);
    assert_eq!(svec_index(2, 2), 5);
    assert_eq!(svec_side(7), None);
    assert!(unpack_upper(&[1.0, 2.0]).is_none());
}

/// min tr Q s.t. Q_01 = 1, Q ⪰ 0 (2×2): Q = [[1,1],[1,1]], optimum 2. With the √2 of
/// the cone rows forgotten the solver would see Q_01/√2 and report √2. Checked with
/// the PSD triangle and with the equivalent SOC form.
#[test]
fn gram_block_min_trace_fixed_offdiagonal() {
    for force in [false, true] {
        let mut m = Model::new();
        m.set_force_psd_triangle(force);
        let q = m.add_gram(2).unwrap();
        assert_eq!(q.psd().form(), if force { PsdForm::Triangle } else { PsdForm::Soc });
        m.add_eq(&[(q.var(0, 1), 1.0)], 1.0).unwrap();
        m.set_objective(&[(q.var(0, 0), 1.0), (q.var(1, 1), 1.0)]).unwrap();
        let s = m.solve(&SdpSettings::default()).unwrap();
        assert_eq!(s.status, SdpStatus::Solved);
        assert!((s.obj_primal - 2.0).abs() < 1e-7, "{}", s.obj_primal);
        let mat = q.matrix(&s.x).unwrap();
        for row in &mat {
            for &v in row {
                assert!((v - 1.0).abs() < 1e-6);
            }
        }
        // the slack decodes back to Q
        let sm = q.psd().slack_matrix(&s.s).unwrap();
        for i in 0..2 {
            for j in 0..2 {
                assert!((sm[i][j] - mat[i][j]).abs() < 1e-6, "{sm:?} vs {mat:?}");
            }
        }
        // the same constraint written as a full symmetric sum ⟨[[0,1],[1,0]], Q⟩ = 2
        let mut m = Model::new();
        m.set_force_psd_triangle(force);
        let q = m.add_gram(2).unwrap();
        let eq = m.add_eq(&[(q.var(1, 0), GramBlock::sym_factor(0, 1))], 2.0).unwrap();
        m.set_objective(&[(q.var(0, 0), 1.0), (q.var(1, 1), 1.0)]).unwrap();
        let s = m.solve(&SdpSettings::default()).unwrap();
        assert!((s.obj_primal - 2.0).abs() < 1e-7);
        // dual matrix: stationarity gives Z = I − y·[[0,1],[1,0]] (C − Σ y A), Z ⪰ 0,
        // and complementarity ⟨Z, Q⟩ ≈ 0
        let z = q.dual_matrix(&s.z).unwrap();
        let y = -s.duals(eq)[0];
        assert!((z[0][0] - 1.0).abs() < 1e-6 && (z[1][1] - 1.0).abs() < 1e-6, "{z:?}");
        assert!((z[0][1] + y).abs() < 1e-6, "{z:?} y = {y}");
        let qm = q.matrix(&s.x).unwrap();
        let inner: f64 = (0..2).flat_map(|i| (0..2).map(move |j| (i, j))).map(|(i, j)| z[i][j] * qm[i][j]).sum();
        assert!(inner.abs() < 1e-6, "complementarity {inner}");
    }
}

/// Side 1 is a nonnegative row: min q s.t. q ≥ 0, q + x = 1, x ≤ 0.25 gives q = 0.75.
#[test]
fn gram_block_side_one() {
    for force in [false, true] {
        let mut m = Model::new();
        m.set_force_psd_triangle(force);
        let q = m.add_gram(1).unwrap();
        let x = m.add_var();
        m.add_eq(&[(q.var(0, 0), 1.0), (x, 1.0)], 1.0).unwrap();
        m.add_le(&[(x, 1.0)], 0.25).unwrap();
        m.set_objective(&[(q.var(0, 0), 1.0)]).unwrap();
        let s = m.solve(&SdpSettings::default()).unwrap();
        assert!((s.value(q.var(0, 0)) - 0.75).abs() < 1e-7);
    }
}

/// 3×3: min tr Q s.t. Q_01 = Q_12 = 1. Optimum 2√2 (Q = v vᵀ with v = (a, b, a),
/// ab = 1, b² = ... ; checked numerically against the closed form below).
#[test]
fn gram_block_3x3_known_optimum() {
    let mut m = Model::new();
    let q = m.add_gram(3).unwrap();
    m.add_eq(&[(q.var(0, 1), 1.0)], 1.0).unwrap();
    m.add_eq(&[(q.var(1, 2), 1.0)], 1.0).unwrap();
    m.set_objective(&[(q.var(0, 0), 1.0), (q.var(1, 1), 1.0), (q.var(2, 2), 1.0)]).unwrap();
    let s = m.solve(&SdpSettings::default()).unwrap();
    assert_eq!(s.status, SdpStatus::Solved);
    // rank one v vᵀ, v = (a, b, a), ab = 1: trace 2a² + b² = 2a² + 1/a², min at a⁴ = 1/2
    // giving 2/√2 + √2 = 2√2.
    assert!((s.obj_primal - 2.0 * SQRT2).abs() < 1e-6, "{}", s.obj_primal);
}

/// max x s.t. [[1, x], [x, 4]] ⪰ 0: x = 2 (pattern 2; a forgotten √2 gives 2√2), and
/// a 3×3 affine block: max x s.t. [[1, x, 0], [x, 1, x], [0, x, 1]] ⪰ 0: x = 1/√2.
#[test]
fn affine_psd_pattern_two() {
    for force in [false, true] {
        let mut m = Model::new();
        m.set_force_psd_triangle(force);
        let x = m.add_var();
        let entries = vec![AffineExpr::constant(1.0), AffineExpr::var(x), AffineExpr::constant(4.0)];
        let blk = m.add_psd_affine(2, &entries).unwrap();
        m.set_objective(&[(x, -1.0)]).unwrap();
        let s = m.solve(&SdpSettings::default()).unwrap();
        assert_eq!(s.status, SdpStatus::Solved);
        assert!((s.value(x) - 2.0).abs() < 1e-6, "{}", s.value(x));
        let sm = blk.slack_matrix(&s.s).unwrap();
        assert!((sm[0][1] - 2.0).abs() < 1e-6 && (sm[1][1] - 4.0).abs() < 1e-9, "{sm:?}");
    }
    let mut m = Model::new();
    let x = m.add_var();
    let one = AffineExpr::constant(1.0);
    let e = vec![one.clone(), AffineExpr::var(x), one.clone(), AffineExpr::constant(0.0), AffineExpr::var(x), one];
    m.add_psd_affine(3, &e).unwrap();
    m.set_objective(&[(x, -1.0)]).unwrap();
    let s = m.solve(&SdpSettings::default()).unwrap();
    assert!((s.value(x) - 1.0 / SQRT2).abs() < 1e-6, "{}", s.value(x));
}

/// min x + y s.t. ‖(x, y)‖ ≤ 1: −√2.
#[test]
fn second_order_cone() {
    let mut m = Model::new();
    let x = m.add_var();
    let y = m.add_var();
    m.add_soc(&[AffineExpr::constant(1.0), AffineExpr::var(x), AffineExpr::var(y)]).unwrap();
    m.set_objective(&[(x, 1.0), (y, 1.0)]).unwrap();
    let s = m.solve(&SdpSettings::default()).unwrap();
    assert_eq!(s.status, SdpStatus::Solved);
    assert!((s.obj_primal + SQRT2).abs() < 1e-7);
    assert!((s.value(x) + 1.0 / SQRT2).abs() < 1e-6);
}

/// Every cone type interleaved: min x + 2y + 0·w s.t. [[x,1],[1,y]] ⪰ 0, x ≤ 1,
/// w = x + y, (3, x, y) ∈ SOC (inactive), a Gram block tied to w, y ≥ 0.
/// Optimum x = y = 1, objective 3.
#[test]
fn mixed_problem() {
    let mut m = Model::new();
    let x = m.add_var();
    let y = m.add_var();
    let w = m.add_var();
    m.add_psd_affine(2, &[AffineExpr::var(x), AffineExpr::constant(1.0), AffineExpr::var(y)]).unwrap();
    m.add_le(&[(x, 1.0)], 1.0).unwrap();
    let eq = m.add_eq(&[(w, 1.0), (x, -1.0), (y, -1.0)], 0.0).unwrap();
    m.add_soc(&[AffineExpr::constant(3.0), AffineExpr::var(x), AffineExpr::var(y)]).unwrap();
    let g = m.add_gram(2).unwrap();
    // tr G = w, G_01 = 0.5
    m.add_eq(&[(g.var(0, 0), 1.0), (g.var(1, 1), 1.0), (w, -1.0)], 0.0).unwrap();
    m.add_eq(&[(g.var(0, 1), 1.0)], 0.5).unwrap();
    m.add_nonneg(&AffineExpr::var(y)).unwrap();
    m.add_ge(&[(y, 1.0)], -5.0).unwrap();
    m.set_objective(&[(x, 1.0), (y, 2.0)]).unwrap();
    let s = m.solve(&SdpSettings::default()).unwrap();
    assert_eq!(s.status, SdpStatus::Solved);
    assert!((s.obj_primal - 3.0).abs() < 1e-6, "{}", s.obj_primal);
    assert!((s.value(w) - 2.0).abs() < 1e-6);
    assert_eq!(s.duals(eq).len(), 1);
    let gm = g.matrix(&s.x).unwrap();
    assert!((gm[0][0] + gm[1][1] - 2.0).abs() < 1e-6 && (gm[1][0] - 0.5).abs() < 1e-6);
}

/// Dual convention: `Aᵀz + q = 0`. min x s.t. x = 3 gives z = −1.
#[test]
fn dual_sign_convention() {
    let mut m = Model::new();
    let x = m.add_var();
    let r = m.add_eq(&[(x, 1.0), (x, 1.0)], 6.0).unwrap(); // duplicates add up: 2x = 6
    m.set_objective(&[(x, 1.0)]).unwrap();
    let s = m.solve(&SdpSettings::default()).unwrap();
    assert!((s.value(x) - 3.0).abs() < 1e-8);
    assert!((s.duals(r)[0] * 2.0 + 1.0).abs() < 1e-8, "{:?}", s.z);
}

#[test]
fn errors_instead_of_panics() {
    let mut m = Model::new();
    let x = m.add_var();
    assert!(matches!(m.add_eq(&[(x, f64::NAN)], 1.0), Err(SdpError::NonFinite(_))));
    assert!(matches!(m.add_eq(&[(x, 1.0)], f64::INFINITY), Err(SdpError::NonFinite(_))));
    assert!(matches!(m.add_le(&[(Var(7), 1.0)], 1.0), Err(SdpError::VarOutOfRange { var: 7, n: 1 })));
    assert!(matches!(m.add_soc(&[AffineExpr::var(x)]), Err(SdpError::BadConeSize(_))));
    assert!(matches!(m.add_gram(0), Err(SdpError::BadConeSize(_))));
    assert!(matches!(m.add_psd_affine(2, &[AffineExpr::var(x)]), Err(SdpError::BadConeSize(_))));
    assert!(matches!(m.set_objective(&[(x, f64::NEG_INFINITY)]), Err(SdpError::NonFinite(_))));
    assert_eq!(m.num_rows(), 0, "failed additions leave no rows behind");
    let bad = SdpSettings { tol_feas: -1.0, ..SdpSettings::default() };
    assert!(matches!(m.solve(&bad), Err(SdpError::BadSettings(_))));
    // infeasible and unbounded problems report a status, not an error
    m.add_le(&[(x, 1.0)], 0.0).unwrap();
    m.add_ge(&[(x, 1.0)], 1.0).unwrap();
    let s = m.solve(&SdpSettings::default()).unwrap();
    assert!(!s.status.has_solution(), "{:?}", s.status);
    let mut u = Model::new();
    let y = u.add_var();
    u.add_le(&[(y, 1.0)], 0.0).unwrap();
    u.set_objective(&[(y, 1.0)]).unwrap();
    let s = u.solve(&SdpSettings::default()).unwrap();
    assert!(!s.status.has_solution(), "{:?}", s.status);
    assert_eq!(s.status.to_string(), format!("{:?}", s.status));
}

/// A prepared solver re-solves with a new right-hand side and objective, giving the
/// same answers as a fresh solve.
#[test]
fn prepared_update_b_and_q() {
    let mut m = Model::new();
    let g = m.add_gram(2).unwrap();
    let x = m.add_var();
    let r = m.add_eq(&[(g.var(0, 1), 1.0)], 1.0).unwrap();
    m.add_eq(&[(x, 1.0), (g.var(0, 0), -1.0)], 0.0).unwrap();
    m.set_objective(&[(g.var(0, 0), 1.0), (g.var(1, 1), 1.0)]).unwrap();
    let mut prep = m.prepare(&SdpSettings::default()).unwrap();
    let s1 = prep.solve().unwrap();
    assert!((s1.obj_primal - 2.0).abs() < 1e-7);
    let mut b = m.rhs().to_vec();
    b[r.start] = 3.0; // Q_01 = 3: min trace 6
    prep.update_b(&b).unwrap();
    let s2 = prep.solve().unwrap();
    assert!((s2.obj_primal - 6.0).abs() < 1e-6, "{}", s2.obj_primal);
    // q: minimise Q00 + 4 Q11 with Q01 = 3: 2·sqrt(4)·3 = 12
    let mut q = vec![0.0; prep.num_vars()];
    q[g.var(0, 0).index()] = 1.0;
    q[g.var(1, 1).index()] = 4.0;
    prep.update_q(&q).unwrap();
    let s3 = prep.solve().unwrap();
    assert!((s3.obj_primal - 12.0).abs() < 1e-6, "{}", s3.obj_primal);
    // the same updates on a freshly prepared problem, in the other order, give the same optimum
    let mut again = m.prepare(&SdpSettings::default()).unwrap();
    again.update_q(&q).unwrap();
    again.update_b(&b).unwrap();
    let s4 = again.solve().unwrap();
    assert!((s4.obj_primal - s3.obj_primal).abs() < 1e-6, "{} vs {}", s4.obj_primal, s3.obj_primal);
    assert!(matches!(prep.update_b(&[1.0]), Err(SdpError::BadConeSize(_))));
    assert!(matches!(prep.update_q(&vec![f64::NAN; prep.num_vars()]), Err(SdpError::NonFinite(_))));
}

/// A set stop flag ends the solve inside Clarabel (its termination callback) with
/// `CallbackTerminated` and no point; the same prepared model without the flag set
/// solves to the known optimum 2√2.
#[test]
fn stop_flag_ends_a_solve_inside_the_solver() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let mut m = Model::new();
    let q = m.add_gram(3).unwrap();
    m.add_eq(&[(q.var(0, 1), 1.0)], 1.0).unwrap();
    m.add_eq(&[(q.var(1, 2), 1.0)], 1.0).unwrap();
    m.set_objective(&[(q.var(0, 0), 1.0), (q.var(1, 1), 1.0), (q.var(2, 2), 1.0)]).unwrap();
    let flag = Arc::new(AtomicBool::new(true));
    let mut prep = m.prepare(&SdpSettings::default()).unwrap();
    prep.stop_when(flag.clone());
    let s = prep.solve().unwrap();
    assert_eq!(s.status, SdpStatus::CallbackTerminated);
    assert!(!s.status.has_solution());
    flag.store(false, Ordering::Relaxed);
    let s = prep.solve().unwrap();
    assert_eq!(s.status, SdpStatus::Solved);
    assert!((s.obj_primal - 2.0 * SQRT2).abs() < 1e-6, "{}", s.obj_primal);
}
