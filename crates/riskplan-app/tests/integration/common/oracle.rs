//! An oracle for certified pieces that shares no code with the certifiers: the
//! contour constraints evaluated at many times of the piece, term by term, with
//! no composition, no Bernstein form, no interval arithmetic and no SDP.
//!
//! At each time `t` (evenly spaced over the piece, both ends included) the point
//! `x(t)` is formed from the piece's coefficients, and for every obstacle
//! `m = E[P](x, t)` and `s = E[P²](x, t)` are evaluated from the contour polynomials'
//! terms. The piece passes when `m < 0` and `g1 = m² − (1 − Δ)·s > 0` at every time —
//! the Cantelli bound `(s − m²)/s` is then below Δ. A fast floating-point evaluation
//! decides where its sign is beyond doubt (|g| above `F64_TRUST` times the sum of the
//! absolute values of the terms); everywhere else the values are computed exactly in
//! rational arithmetic.
//!
//! Pieces certified with `bound: auto` (the default) may be proven by other bounds where
//! Cantelli's fail (docs/design.md §5.13): there the times are judged by the independent
//! bound oracle of `riskplan_oracle::bounds` instead ([`check_piece_with`]).

use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use riskplan_math::contour::RiskLevel;
use riskplan_math::poly::QPoly;
use riskplan_oracle::bounds::{ObstacleBounds, SceneBounds};
use riskplan_scene::{Piece, Scene};

/// The floating-point sign of a polynomial value is trusted when the value exceeds
/// this share of the sum of its terms' absolute values. The rounding error of a
/// term-by-term evaluation of at most a few thousand terms of degree ≤ 16 (E[P²] of
/// a degree-8 contour), at a point whose own coordinates carry a relative error of
/// a few ulps, stays below 1e-12 of that sum, so 1e-6 leaves a wide margin.
pub const F64_TRUST: f64 = 1e-6;

/// Times checked per piece by [`check_trajectory`]: 1000 in the full tier, 200 in the
/// quick edit-loop tier (`RISKPLAN_ORACLE_TIMES` overrides both). At extreme scales most
/// evaluations fall back to exact rationals, which is what the oracle's time goes to.
pub fn times_per_piece() -> usize {
    super::size("ORACLE_TIMES", 200, 1000)
}

/// What the oracle saw on one piece.
#[derive(Clone, Copy, Debug, Default)]
pub struct OracleStats {
    /// Point × obstacle evaluations.
    pub evaluations: u64,
    /// Of those, decided in exact arithmetic.
    pub exact: u64,
    /// Of those, where Cantelli's constraints failed and the bound oracle's best bound was
    /// below Δ.
    pub other_bounds: u64,
}

/// Smallest magnitude of a floating-point term (and of a coefficient) that the fast
/// evaluation trusts: below it a term may have lost its relative accuracy to
/// underflow (the extreme-scale scenes reach coefficients of 10⁻³³⁶), and the point is
/// decided exactly instead.
const F64_TERM_FLOOR: f64 = 1e-250;

/// `(value, Σ|terms|)` in floating point, or `None` when a coefficient or a term
/// leaves the range where the floating-point evaluation is trusted (underflow below
/// [`F64_TERM_FLOOR`], overflow).
fn f64_terms(p: &QPoly, xt: &[f64]) -> Option<(f64, f64)> {
    let (mut v, mut a) = (0.0, 0.0);
    for (m, c) in p.terms() {
        let mut term = riskplan_math::poly::rational_to_f64(c);
        if !(term.is_finite() && term.abs() >= F64_TERM_FLOOR) {
            return None;
        }
        for &(var, e) in m.pairs() {
            term *= xt[var as usize].powi(e as i32);
        }
        if !(term.is_finite() && (term == 0.0 || term.abs() >= F64_TERM_FLOOR)) {
            return None;
        }
        v += term;
        a += term.abs();
    }
    (v.is_finite() && a.is_finite()).then_some((v, a))
}

/// `p` at `xt`, exactly, term by term: each term `c·Π xᵥ^e` as an integer fraction
/// (numerators and denominators multiplied out, not reduced), added to the running sum over
/// the least common multiple of their denominators — one gcd per term, and the sum reduced
/// once (a gcd after every product and sum made this oracle most of the time of the full
/// tier's longest tests).
fn exact_terms(p: &QPoly, xt: &[BigRational]) -> BigRational {
    use num_bigint::BigInt;
    use num_integer::Integer;
    let (mut num, mut den) = (BigInt::zero(), BigInt::one());
    for (m, c) in p.terms() {
        let (mut tn, mut td) = (c.numer().clone(), c.denom().clone());
        for &(var, e) in m.pairs() {
            let x = &xt[var as usize];
            tn *= num_traits::pow(x.numer().clone(), e as usize);
            td *= num_traits::pow(x.denom().clone(), e as usize);
        }
        // num/den + tn/td over lcm(den, td)
        if td == den {
            num += tn;
        } else {
            let g = den.gcd(&td);
            let (a, b) = (&td / &g, &den / &g);
            num = num * &a + tn * b;
            den *= a;
        }
    }
    BigRational::new(num, den)
}

/// The piece's point (x(t), t) at the exact time `tq`, in rationals.
fn exact_point(piece: &Piece, tq: &BigRational) -> Vec<BigRational> {
    let mut v: Vec<BigRational> =
        piece.coeffs.iter().map(|c| c.iter().rev().fold(BigRational::zero(), |acc, &k| acc * tq + exact(k))).collect();
    v.push(tq.clone());
    v
}

fn exact(v: f64) -> BigRational {
    BigRational::from_float(v).expect("finite")
}

/// The independent bound oracle of a scene (`riskplan_oracle::bounds`: its own parser,
/// quadrature and shift search; no code shared with the crate's moments or contours), from
/// the scene's file.
pub fn bound_oracle(scene: &Scene) -> SceneBounds {
    let json = serde_json::to_value(&scene.file).expect("scene file serializes");
    SceneBounds::from_scene_json(&json).unwrap_or_else(|e| panic!("{}: bound oracle: {e}", scene.name))
}

/// Relative slack of the bound oracle's best bound over Δ: the oracle's shift search and
/// quadrature round at ~10⁻¹², and the certifier proves its bound strictly below Δ.
const BOUND_ORACLE_SLACK: f64 = 1e-9;

/// Where Cantelli's constraints fail at a time, the risk may still be proven below Δ by
/// the other bounds of `bound: auto` (docs/design.md §5.13). The oracle's best bound at the
/// point: Cantelli's, every shifted moment bound at its best shift, and 0 where P < 0 on a
/// grid of the bounded support (evidence, not proof — this is an oracle). `Err` when the
/// oracle's E\[P\] disagrees with the contour's (a stale scene file).
fn best_bound(ob: &ObstacleBounds, x: &[f64], t: f64, crate_mean: f64) -> Result<f64, String> {
    let pm = ob.moments_at(x, t);
    if (pm.mu - crate_mean).abs() > 1e-6 * (pm.mu.abs() + crate_mean.abs()) + 1e-12 {
        return Err(format!("bound oracle's E[P] = {} but the contour's is {crate_mean}: stale scene file?", pm.mu));
    }
    if ob.max_on_support_grid(x, t, 9).is_some_and(|g| g < 0.0) {
        return Ok(0.0);
    }
    let mut best = pm.cantelli();
    let mut order = 4;
    while order <= pm.max_order() {
        best = best.min(best_shifted_fast(pm.mu, &pm.c, order));
        order += 2;
    }
    Ok(best)
}

/// Shifts tried per order by [`best_shifted_fast`], evenly over b ∈ [−4, 0.9] (the range the
/// certifier searches), then refined around the best by a finer grid.
const SHIFT_GRID: usize = 200;

/// The oracle's smallest shifted moment bound of one order over the shift, from its own
/// central moments cⱼ (quadrature): E[(P + a)^2k] = Σⱼ C(2k, j)·(bμ)^(2k−j)·cⱼ with
/// a = (1 − b)(−μ) — a few flops per shift, where the oracle's direct sum over its nodes
/// costs thousands (this runs at every sampled time where Cantelli fails).
fn best_shifted_fast(mu: f64, c: &[f64; 9], order: u32) -> f64 {
    if mu.is_nan() || mu >= 0.0 || c[..=order as usize].iter().any(|v| !v.is_finite()) {
        return 1.0;
    }
    let binom = |n: u32, k: u32| (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64);
    let at = |b: f64| {
        let a = (1.0 - b) * (-mu);
        if a.is_nan() || a <= 0.0 {
            return 1.0;
        }
        let s: f64 = (0..=order)
            .map(|j| binom(order, j) * (b * mu / a).powi((order - j) as i32) * c[j as usize] / a.powi(j as i32))
            .sum();
        if s.is_finite() {
            s.clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    let (lo, hi) = (-4.0, 0.9);
    let step = (hi - lo) / SHIFT_GRID as f64;
    let (mut bb, mut best) = (0.0, at(0.0));
    for i in 0..=SHIFT_GRID {
        let b = lo + step * i as f64;
        let v = at(b);
        if v < best {
            best = v;
            bb = b;
        }
    }
    for i in 0..=SHIFT_GRID {
        let b = bb - step + 2.0 * step * i as f64 / SHIFT_GRID as f64;
        if b < 1.0 {
            best = best.min(at(b));
        }
    }
    best
}

/// Checks `piece` against every obstacle of `scene` at `n` times; `Err` names the
/// first obstacle and time where a constraint is not strictly positive and (with
/// `bounds`, for pieces certified with `bound: auto`) the independent bound oracle's best
/// bound is above Δ.
pub fn check_piece_with(
    scene: &Scene,
    piece: &Piece,
    delta: &RiskLevel,
    n: usize,
    bounds: Option<&SceneBounds>,
) -> Result<OracleStats, String> {
    let one_minus = 1.0 - delta.to_f64();
    let one_minus_q = BigRational::one() - delta.rational();
    let mut st = OracleStats::default();
    for j in 0..n {
        let t = if j + 1 == n { piece.t1 } else { piece.t0 + (piece.t1 - piece.t0) * j as f64 / (n - 1) as f64 };
        let mut xt = piece.at(t);
        xt.push(t);
        let tq = exact(t);
        let mut xq: Option<Vec<BigRational>> = None;
        for o in &scene.obstacles {
            st.evaluations += 1;
            let floats = f64_terms(&o.contour.mean, &xt).zip(f64_terms(&o.contour.second, &xt));
            let ((m, ma), (s, sa)) = floats.unwrap_or(((f64::NAN, f64::NAN), (f64::NAN, f64::NAN)));
            let g1 = m * m - one_minus * s;
            let g1a = 2.0 * ma * ma + one_minus * sa;
            // NaN (out of range) compares false: decided exactly
            let mean_sure = m.abs() > F64_TRUST * ma;
            let g1_sure = g1.is_finite() && g1a.is_finite() && g1.abs() > F64_TRUST * g1a;
            let (mean_neg, g1_pos) = if mean_sure && g1_sure {
                (m < 0.0, g1 > 0.0)
            } else {
                st.exact += 1;
                let xq = xq.get_or_insert_with(|| exact_point(piece, &tq));
                let m = exact_terms(&o.contour.mean, xq);
                let s = exact_terms(&o.contour.second, xq);
                let g1 = &m * &m - &one_minus_q * &s;
                (m.is_negative(), g1.is_positive())
            };
            if mean_neg && !g1_pos {
                if let Some(ob) = bounds.and_then(|b| b.obstacle(&o.id)) {
                    // the contour's E[P] to compare with, exactly where the float one is
                    // not trusted (far from the origin its terms cancel)
                    let crate_mean = if mean_sure {
                        m
                    } else {
                        let xq = xq.get_or_insert_with(|| exact_point(piece, &tq));
                        riskplan_math::poly::rational_to_f64(&exact_terms(&o.contour.mean, xq))
                    };
                    let best = best_bound(ob, &xt[..xt.len() - 1], t, crate_mean)?;
                    if best <= delta.to_f64() * (1.0 + BOUND_ORACLE_SLACK) {
                        st.other_bounds += 1;
                        continue;
                    }
                    return Err(format!(
                        "{}: obstacle {} at t = {t} (x = {:?}): Cantelli fails and the bound oracle's best bound is {best:e} > Δ",
                        scene.name,
                        o.id,
                        &xt[..xt.len() - 1]
                    ));
                }
            }
            if !(mean_neg && g1_pos) {
                return Err(format!(
                    "{}: obstacle {} at t = {t} (x = {:?}): E[P] = {m:e}, E[P]² − (1−Δ)E[P²] = {g1:e} (must be < 0 and > 0)",
                    scene.name,
                    o.id,
                    &xt[..xt.len() - 1]
                ));
            }
        }
    }
    Ok(st)
}

/// [`check_piece_with`] with every bound of `bound: auto` (the default).
pub fn check_piece(scene: &Scene, piece: &Piece, delta: &RiskLevel, n: usize) -> Result<OracleStats, String> {
    check_piece_with(scene, piece, delta, n, Some(&bound_oracle(scene)))
}

/// [`check_piece_with`] with Cantelli's constraints only (pieces certified with
/// `bound: cantelli`).
pub fn check_piece_cantelli(scene: &Scene, piece: &Piece, delta: &RiskLevel, n: usize) -> Result<OracleStats, String> {
    check_piece_with(scene, piece, delta, n, None)
}

/// [`check_piece`] on every piece of a trajectory, at [`times_per_piece`] times.
pub fn check_trajectory(scene: &Scene, pieces: &[Piece], delta: &RiskLevel) -> Result<OracleStats, String> {
    let bounds = bound_oracle(scene);
    let mut total = OracleStats::default();
    for pc in pieces {
        let s = check_piece_with(scene, pc, delta, times_per_piece(), Some(&bounds))?;
        total.evaluations += s.evaluations;
        total.exact += s.exact;
        total.other_bounds += s.other_bounds;
    }
    Ok(total)
}

/// The oracle's exact sum over common denominators is the naive one (every product and sum
/// reduced): random polynomials of degree ≤ 6 in four variables at points with float,
/// decimal, negative and zero coordinates.
#[test]
fn exact_terms_is_the_reduced_sum() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(32);
    let q = |n: i64, d: i64| BigRational::new(n.into(), d.into());
    for _ in 0..300 {
        let mut p = QPoly::zero();
        for _ in 0..rng.random_range(0..12) {
            let pairs: Vec<(u16, u32)> = (0..4u16).map(|v| (v, rng.random_range(0..4u32))).collect();
            let c = q(rng.random_range(-10_000..10_000), rng.random_range(1..5_000));
            p.add_term(riskplan_math::poly::Monomial::from_pairs(pairs), c);
        }
        let xt: Vec<BigRational> = (0..4)
            .map(|_| match rng.random_range(0..4) {
                0 => exact(rng.random_range(-1e3..1e3)),
                1 => q(rng.random_range(-999..999), 1000),
                2 => q(0, 1),
                _ => exact(rng.random_range(-1e-7..1e-7)),
            })
            .collect();
        let mut naive = BigRational::zero();
        for (m, c) in p.terms() {
            let mut t = c.clone();
            for &(v, e) in m.pairs() {
                t *= num_traits::pow(xt[v as usize].clone(), e as usize);
            }
            naive += t;
        }
        assert_eq!(exact_terms(&p, &xt), naive, "{p:?} at {xt:?}");
    }
}
