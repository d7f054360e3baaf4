//! Restriction of contour constraints to a trajectory piece (docs/design.md §5.1).
//!
//! For a piece `x(t) = Σ_k c_k t^k` on `[t0, t1]`, with `τ = (t − t0)/(t1 − t0)`,
//! the restrictions `e1(τ) = E[P](x(t(τ)), t(τ))` and `e2(τ) = E[P²](…)` are
//! univariate, and the constraints of eq. (15) become
//! `g1(τ) = e1² − (1−Δ)·e2` and `g2(τ) = −e1`, to be proven positive on [0, 1].
//! Static obstacles ignore t. Both an interval version (fast, sound enclosures of
//! the exact coefficients) and an exact rational version (the fallback and the
//! reference) are provided; trajectory floats are exact dyadic rationals.

use num_rational::BigRational;
use riskplan_math::contour::RiskContour;
use riskplan_math::poly::{Interval, Poly, QPoly, Ring, UPoly};

/// A piece as certification sees it: absolute-time coefficients on `[t0, t1]`.
#[derive(Clone, Copy, Debug)]
pub struct PieceRef<'a> {
    /// Start time.
    pub t0: f64,
    /// End time.
    pub t1: f64,
    /// `coeffs[d][k]` multiplies `t^k`.
    pub coeffs: &'a [Vec<f64>],
}

impl PieceRef<'_> {
    /// Whether every number of the piece is finite. The exact conversions read a
    /// non-finite float as nothing (0), so a piece that is not finite must never be
    /// judged.
    pub fn is_finite(&self) -> bool {
        self.t0.is_finite() && self.t1.is_finite() && self.coeffs.iter().flatten().all(|c| c.is_finite())
    }
}

/// The two constraints of one obstacle restricted to one piece.
#[derive(Clone, Debug, PartialEq)]
pub struct Restricted<C> {
    /// `g1(τ) = e1² − (1−Δ)·e2` (Cantelli).
    pub cantelli: UPoly<C>,
    /// `g2(τ) = −e1` (mean).
    pub mean: UPoly<C>,
}

/// The substitutions x_d(τ) (d < `dim`, missing rows as 0) and t(τ) = t0 + h·τ of a piece,
/// its coefficients converted by `conv`.
pub(super) fn substitutions<C: Ring>(
    piece: PieceRef<'_>,
    dim: usize,
    t0: C,
    h: C,
    conv: impl Fn(f64) -> C,
) -> Vec<UPoly<C>> {
    let mut subs: Vec<UPoly<C>> = piece
        .coeffs
        .iter()
        .map(|row| UPoly::new(row.iter().map(|&c| conv(c)).collect()).compose_affine(&t0, &h))
        .collect();
    subs.resize(dim, UPoly::zero());
    subs.push(UPoly::linear(t0, h)); // t(τ) = t0 + hτ
    subs
}

/// Eq. (15)'s two constraints of E\[P\] `mean` and E\[P²\] `second` composed with the
/// piece's substitutions `subs` (their powers formed once for both).
pub(crate) fn restrict<C: Ring>(
    mean: &Poly<C>,
    second: &Poly<C>,
    subs: &[UPoly<C>],
    one_minus_delta: &C,
) -> Restricted<C> {
    let mut powers = riskplan_math::poly::substitution_powers(subs);
    let e1 = mean.compose_with_powers(&mut powers);
    let e2 = second.compose_with_powers(&mut powers);
    Restricted { cantelli: e1.mul(&e1).sub(&e2.scale(one_minus_delta)), mean: e1.neg() }
}

/// Interval restriction: coefficients enclose the exact ones.
pub fn restrict_interval(contour: &RiskContour, piece: PieceRef<'_>, delta: &BigRational) -> Restricted<Interval> {
    let t0 = Interval::point(piece.t0);
    let h = Interval::point(piece.t1) - t0;
    let subs = substitutions(piece, contour.layout().dim, t0, h, Interval::point);
    let (m, s) = contour.interval_polys();
    let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - delta));
    restrict(m, s, &subs, &omd)
}

/// The substitutions x_d(τ), t(τ) of a piece in interval arithmetic (each coefficient
/// encloses the exact one), for restricting any polynomial in (x, t).
pub fn interval_substitutions(piece: PieceRef<'_>, dim: usize) -> Vec<UPoly<Interval>> {
    let t0 = Interval::point(piece.t0);
    let h = Interval::point(piece.t1) - t0;
    substitutions(piece, dim, t0, h, Interval::point)
}

/// Exact restriction in rationals.
pub fn restrict_exact(contour: &RiskContour, piece: PieceRef<'_>, delta: &BigRational) -> Restricted<BigRational> {
    let q = |f: f64| BigRational::from_float(f).unwrap_or_default();
    let t0 = q(piece.t0);
    let h = q(piece.t1) - &t0;
    let subs = substitutions(piece, contour.layout().dim, t0, h, q);
    let omd = BigRational::from_integer(1.into()) - delta;
    restrict(&contour.mean, &contour.second, &subs, &omd)
}

/// The coordinate polynomials `x_d(τ)` of a piece, exactly (for workspace checks).
pub fn coordinates_exact(piece: PieceRef<'_>) -> Vec<UPoly<BigRational>> {
    let q = |f: f64| BigRational::from_float(f).unwrap_or_default();
    let t0 = q(piece.t0);
    let h = q(piece.t1) - &t0;
    piece.coeffs.iter().map(|row| UPoly::new(row.iter().map(|&c| q(c)).collect()).compose_affine(&t0, &h)).collect()
}

/// Restriction of an exact polynomial in (x, t) (any constraint) to a piece, exactly.
pub fn restrict_poly_exact(p: &QPoly, dim: usize, piece: PieceRef<'_>) -> UPoly<BigRational> {
    let q = |f: f64| BigRational::from_float(f).unwrap_or_default();
    let t0 = q(piece.t0);
    let h = q(piece.t1) - &t0;
    p.compose_univariate(&substitutions(piece, dim, t0, h, q))
}

#[cfg(test)]
mod tests {
    use super::*;
    use riskplan_math::contour::Layout;
    use riskplan_math::poly::{parse, VarTable};

    fn disk() -> RiskContour {
        let vars = VarTable::new(["x1", "x2", "t", "w"].map(String::from));
        let p = parse("w^2 - (x1 - t)^2 - x2^2", &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).unwrap();
        let m = [1, 0, 37, 0, 781].map(|v: i64| BigRational::from_integer(v.into()));
        let m = [
            m[0].clone(),
            m[1].clone(),
            m[2].clone() / BigRational::from_integer(300.into()),
            m[3].clone(),
            m[4].clone() / BigRational::from_integer(50000.into()),
        ];
        RiskContour::new(Layout { dim: 2 }, &p, &|_, k| m.get(k as usize).cloned(), &|v| vars.name(v)).unwrap()
    }

    /// Interval coefficients enclose the exact ones, and both agree with evaluating
    /// the constraint at the piece's position.
    #[test]
    fn interval_encloses_exact_and_matches_pointwise() {
        let c = disk();
        let coeffs = vec![vec![-1.0, 0.3, 0.2], vec![0.7, -0.9]];
        let piece = PieceRef { t0: 0.25, t1: 0.75, coeffs: &coeffs };
        let delta = BigRational::new(1.into(), 10.into());
        let ex = restrict_exact(&c, piece, &delta);
        let iv = restrict_interval(&c, piece, &delta);
        for (e, i) in [(&ex.cantelli, &iv.cantelli), (&ex.mean, &iv.mean)] {
            assert_eq!(e.degree(), i.degree());
            for k in 0..=e.degree() {
                let v = e.coeff(k);
                let b = i.coeff(k);
                assert!(BigRational::from_float(b.lo).unwrap() <= v && v <= BigRational::from_float(b.hi).unwrap());
            }
        }
        // at τ = 1/2 the absolute time is t = 1/2, so x(t) evaluates with t = 1/2
        let tau = BigRational::new(1.into(), 2.into());
        let cons = c.constraints(&delta);
        let composed = ex.cantelli.eval(&tau);
        let x1 = BigRational::from_float(-1.0).unwrap()
            + BigRational::from_float(0.3).unwrap() * &tau
            + BigRational::from_float(0.2).unwrap() * &tau * &tau;
        let x2 = BigRational::from_float(0.7).unwrap() - BigRational::from_float(0.9).unwrap() * &tau;
        let t = BigRational::new(1.into(), 2.into());
        let expect = cons.cantelli.eval(&[x1, x2, t, BigRational::from_integer(0.into())]);
        assert_eq!(composed, expect);
    }

    /// Composition at many local times τ on a piece whose interval is not [0, 1]:
    /// the restricted constraint at τ equals the constraint at the piece's position
    /// and *absolute* time t = t0 + (t1 − t0)·τ (the obstacle moves with t, so
    /// mixing up τ and t changes the value), exactly; the interval restriction
    /// encloses it.
    #[test]
    fn composition_uses_absolute_time_at_every_local_time() {
        let c = disk();
        assert!(c.is_dynamic());
        let coeffs = vec![vec![-1.0, 0.3, 0.2], vec![0.7, -0.9]];
        let (t0, t1) = (0.3, 1.7);
        let piece = PieceRef { t0, t1, coeffs: &coeffs };
        let delta = BigRational::new(1.into(), 10.into());
        let ex = restrict_exact(&c, piece, &delta);
        let iv = restrict_interval(&c, piece, &delta);
        let cons = c.constraints(&delta);
        let q = |v: f64| BigRational::from_float(v).unwrap();
        // dyadic τ, exact in f64 as well, so the interval evaluation sees the same τ
        for k in 0..=256 {
            let tau = BigRational::new(k.into(), 256.into());
            let t = q(t0) + (q(t1) - q(t0)) * &tau;
            let x: Vec<BigRational> = coeffs
                .iter()
                .map(|cs| cs.iter().rev().fold(BigRational::from_integer(0.into()), |acc, &v| acc * &t + q(v)))
                .collect();
            let point = [x[0].clone(), x[1].clone(), t.clone(), BigRational::from_integer(0.into())];
            for (name, composed, interval, g) in
                [("cantelli", &ex.cantelli, &iv.cantelli, &cons.cantelli), ("mean", &ex.mean, &iv.mean, &cons.mean)]
            {
                let want = g.eval(&point);
                assert_eq!(composed.eval(&tau), want, "{name} at τ = {tau}");
                let tf = riskplan_math::poly::rational_to_f64(&tau);
                let enclosure = interval.eval(&riskplan_math::poly::Interval::point(tf));
                assert!(
                    q(enclosure.lo) <= want && want <= q(enclosure.hi),
                    "{name} at τ = {tau}: {want} not in {enclosure:?}"
                );
            }
            // local time is not absolute time: the constraint at (x, τ) differs
            if k == 128 {
                let wrong = [x[0].clone(), x[1].clone(), tau.clone(), BigRational::from_integer(0.into())];
                assert_ne!(cons.cantelli.eval(&wrong), ex.cantelli.eval(&tau));
            }
        }
    }
}
