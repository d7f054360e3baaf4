//! Certifying a piece against a pedestrian by its Gaussian tail bound (docs/design.md
//! §3.11): the piece is safe at level Δ when
//!
//! ```text
//! f(τ) = ‖x(τ) − m(t(τ))‖² − r(τ)² > 0   on τ ∈ [0, 1],
//! r(τ) = (1 − τ)·r_a + τ·r_b,   r_a ≥ reach + κ·√s(t0),  r_b ≥ reach + κ·√s(t1),
//! ```
//!
//! with κ from [`tail_kappa`]: √s is convex in t (the norm of an affine function), so
//! the chord r bounds `reach + κ·√s(t)` from above on the whole piece, and `f > 0` gives
//! `‖x(t) − m(t)‖ > reach + κ·√s(t)` at every instant, hence a probability of contact at
//! most Δ (`contour::tail`). Two deciders that share no arithmetic: [`piece_clear`] in
//! outward-rounded intervals (the planners' checker), [`piece_clear_exact`] in exact
//! rationals from the template's exact numbers (the final check and `verify`).

use crate::positivity::bernstein::{self, DEFAULT_MAX_DEPTH};
use crate::{interval_substitutions, PieceRef, Undecided, Verdict};
use num_rational::BigRational;
use num_traits::{Signed, Zero};
use riskplan_math::contour::tail::{tail_kappa, GaussianDisk};
use riskplan_math::poly::{Interval, UPoly};
use riskplan_scene::Pedestrian;

/// Decides a piece against a pedestrian's tail bound at threshold `kappa`, in
/// outward-rounded interval arithmetic (module docs).
pub fn piece_clear(d: &GaussianDisk, kappa: f64, pr: PieceRef<'_>) -> Verdict {
    let dim = d.dim();
    if !pr.is_finite() || pr.coeffs.len() != dim {
        return Verdict::Undecided(Undecided::NonFinite);
    }
    let (ra, rb) = (d.radius_upper(pr.t0, kappa), d.radius_upper(pr.t1, kappa));
    if !(ra.is_finite() && rb.is_finite()) {
        return Verdict::Undecided(Undecided::NonFinite);
    }
    let subs = interval_substitutions(pr, dim);
    let t0 = Interval::point(pr.t0);
    let h = Interval::point(pr.t1) - t0;
    // t(τ) − t_ref
    let tau = UPoly::linear(t0 - d.t_ref, h);
    let mut f = UPoly::zero();
    for (i, x) in subs.iter().take(dim).enumerate() {
        let u = x.sub(&UPoly::constant(d.position[i])).sub(&tau.scale(&d.velocity[i]));
        f = f.add(&u.mul(&u));
    }
    let r = UPoly::linear(Interval::point(ra), Interval::point(rb) - Interval::point(ra));
    bernstein::check_interval(&f.sub(&r.mul(&r)), DEFAULT_MAX_DEPTH)
}

/// Whether a point is safe for a pedestrian at time `t` (`‖x − m(t)‖ > reach + κ·√s(t)`,
/// in intervals).
pub fn point_clear(d: &GaussianDisk, kappa: f64, x: &[f64], t: f64) -> bool {
    let r = d.radius_upper(t, kappa);
    if x.len() != d.dim() || !r.is_finite() || !x.iter().all(|v| v.is_finite()) {
        return false;
    }
    let m = d.centre(t);
    let mut s = Interval::point(0.0);
    for (xi, mi) in x.iter().zip(&m) {
        let u = Interval::point(*xi) - *mi;
        s = s + u * u;
    }
    s.lo > (Interval::point(r) * Interval::point(r)).hi
}

/// The same decision as [`piece_clear`] in exact rational arithmetic from the template's
/// exact numbers (its largest radius plus its body radius, exactly): the chord's ends are
/// rationals whose squares are checked exactly against `κ²·s`, so only κ (an upper bound,
/// [`tail_kappa`]) comes from floating point. `delta` is the risk level. A point is the
/// piece with `t0 = t1` and constant coordinates.
pub fn piece_clear_exact(p: &Pedestrian, delta: &BigRational, pr: PieceRef<'_>) -> Verdict {
    let dim = p.file.position.len();
    let q = |f: f64| BigRational::from_float(f);
    let (Some(kappa), Some(t0), Some(t1)) = (tail_kappa(dim, delta).and_then(q), q(pr.t0), q(pr.t1)) else {
        return Verdict::Undecided(Undecided::NonFinite);
    };
    if !pr.is_finite() || pr.coeffs.len() != dim {
        return Verdict::Undecided(Undecided::NonFinite);
    }
    let reach = &p.r_max + &p.body;
    let t_ref = &p.file.time.0;
    let zero = BigRational::zero();
    let sp = p.file.position_std.as_ref().map_or(zero.clone(), |n| n.0.clone());
    let sv = p.file.velocity_std.as_ref().map_or(zero.clone(), |n| n.0.clone());
    // an exact upper bound of reach + κ·√s(t): a float guess, checked and raised
    let radius = |t: &BigRational| -> Option<BigRational> {
        let tau = t - t_ref;
        let s = &sp * &sp + &sv * &sv * &tau * &tau;
        let need = &kappa * &kappa * &s;
        let mut g = riskplan_math::poly::rational_to_f64(&need).sqrt();
        for _ in 0..64 {
            let gq = q(g)?;
            if !gq.is_negative() && &gq * &gq >= need {
                return Some(&reach + gq);
            }
            g = if g == 0.0 { f64::MIN_POSITIVE } else { g.next_up() * (1.0 + 1e-15) };
        }
        // a guess out of the float range's reach (tiny or huge κ²·s): √(a² + b²) ≤ a + b
        Some(&reach + &kappa * (&sp + &sv * num_traits::Signed::abs(&tau)))
    };
    let (Some(ra), Some(rb)) = (radius(&t0), radius(&t1)) else {
        return Verdict::Undecided(Undecided::NonFinite);
    };
    let h = &t1 - &t0;
    // the polynomial, exactly; decided in intervals first (its coefficients enclosed),
    // exactly only where that is undecided (bernstein::check)
    let exact = || {
        let coords = crate::coordinates_exact(pr);
        let tau = UPoly::linear(&t0 - t_ref, h.clone());
        let mut f = UPoly::zero();
        for (i, x) in coords.iter().enumerate() {
            let u = x.sub(&UPoly::constant(p.file.position[i].0.clone())).sub(&tau.scale(&p.file.velocity[i].0));
            f = f.add(&u.mul(&u));
        }
        let r = UPoly::linear(ra.clone(), &rb - &ra);
        f.sub(&r.mul(&r))
    };
    // (the template's numbers enclosed once, in `p.disk`)
    let e = |q: &BigRational| Interval::enclose_rational(q);
    let (it0, ih) = (Interval::point(pr.t0), Interval::point(pr.t1) - Interval::point(pr.t0));
    let coords: Vec<UPoly<Interval>> = pr
        .coeffs
        .iter()
        .map(|row| UPoly::new(row.iter().map(|&c| Interval::point(c)).collect()).compose_affine(&it0, &ih))
        .collect();
    let tau = UPoly::linear(it0 - p.disk.t_ref, ih);
    let mut f = UPoly::zero();
    for (i, x) in coords.iter().enumerate() {
        let u = x.sub(&UPoly::constant(p.disk.position[i])).sub(&tau.scale(&p.disk.velocity[i]));
        f = f.add(&u.mul(&u));
    }
    let r = UPoly::linear(e(&ra), e(&rb) - e(&ra));
    bernstein::check(&f.sub(&r.mul(&r)), exact)
}
