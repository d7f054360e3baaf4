//! The verify path's own frame for the final check (docs/design.md §5.12).

use super::decide::Interrupted;
use super::workspace::{check_workspace, interval_hull};
use super::Status;
use crate::certify::bounds::{Level, PieceBounds};
use crate::certify::{bernstein, restrict_exact, PieceRef, Verdict};
use crate::contour::{BoundChoice, RiskLevel};
use crate::poly::{Interval, UPoly};
use crate::scene::{Obstacle, Scene};
use num_rational::BigRational;
use std::sync::OnceLock;

/// A scene's contour polynomials for the final check (docs/design.md §5.12), written in
/// the verify path's own frame `z_v = (x_v − c_v)·2^(−e_v)` (centre and power-of-two
/// scale from the workspace and the horizon) by general polynomial substitution in
/// exact arithmetic, then enclosed coefficient by coefficient. In the scene's own
/// coordinates a workspace at x ≈ 5·10⁶ (UTM) makes the monomials cancel by many orders
/// of magnitude and nearly every piece would go to the exact fallback. This is
/// deliberately not the compiled path's frame code (`certify::fast`): the final check
/// shares no code with it beyond the contour polynomials. A scene near the origin at
/// moderate scale keeps its own coordinates (`polys` is `None`): the exact substitution
/// costs about 0.25 ms per obstacle, more than the final check saves there.
#[derive(Debug)]
pub struct FramedContours {
    center: Vec<f64>,
    inv_scale: Vec<f64>,
    /// The substitution into the frame (`None`: the scene's own coordinates) and each
    /// obstacle's framed polynomials, made on first use (a pedestrian decided by its tail
    /// bound never needs them).
    polys: Option<(Vec<crate::poly::QPoly>, Vec<FramedPair>)>,
    /// With more than [`FramedContours::NEAR_MIN_OBSTACLES`] obstacles in at most
    /// [`FramedContours::NEAR_MAX_DIM`] dimensions: each obstacle's contour polynomials
    /// rewritten exactly around a point of its own, for a box test that clears distant
    /// obstacles without a composition (`None` for an obstacle whose point is not
    /// finite). Built by the first final check that needs it, asking its `stop`.
    near: OnceLock<Option<Vec<Option<Near>>>>,
}

type FramedPair = OnceLock<(crate::poly::Poly<Interval>, crate::poly::Poly<Interval>)>;

/// One obstacle's contour polynomials around a point of its own (`y = x − c`), with
/// interval coefficients: evaluated over a piece's bounding box they bound E\[P\] and
/// E\[P²\] there.
#[derive(Debug)]
pub(crate) struct Near {
    center: Vec<f64>,
    mean: crate::poly::Poly<Interval>,
    second: crate::poly::Poly<Interval>,
}

impl Near {
    /// The Cantelli polynomial g₁ = E\[P\]² − (1−Δ)·E\[P²\] around the centre, formed
    /// before any evaluation so that its leading terms cancel symbolically (evaluating
    /// E\[P\]² and E\[P²\] separately over a box cannot prove g₁ > 0 a few box-widths away).
    fn cantelli(&self, one_minus_delta: Interval) -> crate::poly::Poly<Interval> {
        self.mean.mul(&self.mean).sub(&self.second.scale(&one_minus_delta))
    }

    /// Whether both constraints of eq. (15) are proven over the box `bbox × t` by naive
    /// interval evaluation of −E\[P\] and of `cantelli` (from [`Near::cantelli`]).
    fn clears(&self, bbox: &[Interval], t: Interval, cantelli: &crate::poly::Poly<Interval>) -> bool {
        let mut vals: Vec<Interval> = bbox.iter().zip(&self.center).map(|(&b, &c)| b - Interval::point(c)).collect();
        vals.push(t - Interval::point(self.center[bbox.len()]));
        self.mean.eval(&vals).hi < 0.0 && cantelli.eval(&vals).lo > 0.0
    }
}

impl FramedContours {
    /// Largest scale exponent: `2^±1000` is a normal float.
    const MAX_EXPONENT: i32 = 1000;
    /// A centre within this many half-widths of the origin is not shifted: the
    /// monomials then cancel by at most about this factor to the power of the degree,
    /// which the interval enclosures absorb (Bernstein decides such scenes today).
    const CENTRE_KEPT: f64 = 16.0;
    /// A scale exponent of at most this magnitude is not applied (2^±16).
    const SCALE_KEPT: i32 = 16;
    /// Above this many obstacles distant ones are cleared by a box test first: below
    /// it composing with every obstacle costs less than preparing the test (a few
    /// tenths of a millisecond per obstacle, once per scene).
    const NEAR_MIN_OBSTACLES: usize = 16;
    /// The box tests' points are found on a grid of 16^dim points per obstacle
    /// (`index::obstacle_center`): beyond 3 dimensions that costs more than it saves.
    const NEAR_MAX_DIM: usize = 3;

    /// The box tests of every obstacle (`None` when the scene has too few obstacles or
    /// too many dimensions), built on first use; `Err` when `stop` says stop first
    /// (nothing is kept then).
    pub(crate) fn near(&self, scene: &Scene, stop: &dyn Fn() -> bool) -> Result<Option<&[Option<Near>]>, Interrupted> {
        if let Some(n) = self.near.get() {
            return Ok(n.as_deref());
        }
        if scene.obstacles.len() <= Self::NEAR_MIN_OBSTACLES || scene.dim > Self::NEAR_MAX_DIM {
            return Ok(self.near.get_or_init(|| None).as_deref());
        }
        let ws = &scene.workspace;
        let mut region: Vec<(f64, f64)> = ws.lower.iter().copied().zip(ws.upper.iter().copied()).collect();
        region.push(scene.horizon);
        let mut near = Vec::with_capacity(scene.obstacles.len());
        for o in &scene.obstacles {
            if stop() {
                return Err(Interrupted);
            }
            if o.pedestrian.is_some() {
                // decided by its tail bound (or, with `cantelli`, by the composition)
                near.push(None);
                continue;
            }
            let center = super::index::obstacle_center(&o.contour, &region);
            // the same exact values substituted and subtracted; a point that is not a
            // finite float gets no box test
            let Some(exact) = center.iter().map(|&c| BigRational::from_float(c)).collect::<Option<Vec<_>>>() else {
                near.push(None);
                continue;
            };
            let subs: Vec<crate::poly::QPoly> = exact
                .into_iter()
                .enumerate()
                .map(|(v, c)| crate::poly::Poly::var(v as crate::poly::Var).add(&crate::poly::Poly::constant(c)))
                .collect();
            let around = |p: &crate::poly::QPoly| {
                p.subst(&|v| subs.get(v as usize).cloned()).map_coeffs(Interval::enclose_rational)
            };
            near.push(Some(Near { mean: around(&o.contour.mean), second: around(&o.contour.second), center }));
        }
        Ok(self.near.get_or_init(|| Some(near)).as_deref())
    }

    /// The scene's contours in the verify path's frame (exact substitution, then enclosed).
    pub fn new(scene: &Scene) -> Self {
        let ws = &scene.workspace;
        let mut center = scene.center();
        let mut half: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(l, u)| 0.5 * u - 0.5 * l).collect();
        half.push(0.5 * scene.horizon.1 - 0.5 * scene.horizon.0);
        let exps: Vec<i32> = half
            .iter()
            .map(|&w| {
                let e = if w > 0.0 && w.is_finite() {
                    (w.log2().floor() as i32).clamp(-Self::MAX_EXPONENT, Self::MAX_EXPONENT)
                } else {
                    0
                };
                if e.abs() <= Self::SCALE_KEPT {
                    0
                } else {
                    e
                }
            })
            .collect();
        for (c, w) in center.iter_mut().zip(&half) {
            if c.abs() <= Self::CENTRE_KEPT * w {
                *c = 0.0;
            }
        }
        if center.iter().all(|&c| c == 0.0) && exps.iter().all(|&e| e == 0) {
            let n = center.len();
            return FramedContours { center, inv_scale: vec![1.0; n], polys: None, near: OnceLock::new() };
        }
        let two = BigRational::from_integer(2.into());
        let subs: Vec<crate::poly::QPoly> = center
            .iter()
            .zip(&exps)
            .enumerate()
            .map(|(v, (&c, &e))| {
                let scale: BigRational = num_traits::Pow::pow(&two, e);
                crate::poly::Poly::var(v as crate::poly::Var)
                    .scale(&scale)
                    .add(&crate::poly::Poly::constant(BigRational::from_float(c).unwrap_or_default()))
            })
            .collect();
        let polys = scene.obstacles.iter().map(|_| OnceLock::new()).collect();
        let inv_scale = exps.iter().map(|&e| crate::certify::fast::pow2(-e)).collect();
        FramedContours { center, inv_scale, polys: Some((subs, polys)), near: OnceLock::new() }
    }

    /// The constraints of obstacle `o` (the scene's `i`-th) restricted to a piece, in
    /// interval arithmetic: `(g1, g2)` = (Cantelli, mean) of eq. (15) in τ ∈ [0, 1].
    fn restrict(
        &self,
        i: usize,
        o: &Obstacle,
        pr: PieceRef<'_>,
        one_minus_delta: Interval,
    ) -> (UPoly<Interval>, UPoly<Interval>) {
        let t0 = Interval::point(pr.t0);
        let h = Interval::point(pr.t1) - t0;
        let n = self.center.len();
        let mut subs: Vec<UPoly<Interval>> = (0..n - 1)
            .map(|d| {
                let row = pr.coeffs.get(d).map(|r| r.as_slice()).unwrap_or(&[]);
                let x = UPoly::new(row.iter().map(|&c| Interval::point(c)).collect()).compose_affine(&t0, &h);
                x.sub(&UPoly::constant(Interval::point(self.center[d]))).scale(&Interval::point(self.inv_scale[d]))
            })
            .collect();
        subs.push(
            UPoly::linear(t0 - Interval::point(self.center[n - 1]), h).scale(&Interval::point(self.inv_scale[n - 1])),
        );
        let (m, s) = match &self.polys {
            Some((subs, p)) => {
                let frame = |p: &crate::poly::QPoly| {
                    p.subst(&|v| subs.get(v as usize).cloned()).map_coeffs(Interval::enclose_rational)
                };
                let pair = p[i].get_or_init(|| (frame(&o.contour.mean), frame(&o.contour.second)));
                (&pair.0, &pair.1)
            }
            None => o.contour.interval_polys(),
        };
        let e1 = m.compose_univariate(&subs);
        let e2 = s.compose_univariate(&subs);
        (e1.mul(&e1).sub(&e2.scale(&one_minus_delta)), e1.neg())
    }
}

/// The box tests of a final check: per obstacle its test (if any) and its Cantelli
/// polynomial at its Δᵢ, formed on first use.
pub(crate) type NearTests<'a> = (&'a [Option<Near>], &'a [std::cell::OnceCell<crate::poly::Poly<Interval>>]);

/// Whether one piece passes the verify path at one risk level per obstacle: inside the
/// workspace (exact check) and, for every obstacle, both constraints proven positive
/// on the general interval restriction in [`FramedContours`] with the exact rational
/// fallback (the `exact` method of `verify`, without the compiled contours or the
/// covers of the fast path).
pub(crate) fn piece_passes_verify_path(
    scene: &Scene,
    framed: &FramedContours,
    near: Option<NearTests<'_>>,
    pr: PieceRef<'_>,
    deltas: &[RiskLevel],
    bounds: BoundChoice,
    compiled: Option<&super::compiled::CompiledSet>,
) -> bool {
    if !pr.is_finite() || check_workspace(&scene.workspace.lower, &scene.workspace.upper, pr).status != Status::Safe {
        return false;
    }
    // the piece's bounding box (outward-rounded Bernstein hull of each coordinate), for
    // the box tests of distant obstacles
    let bbox = near.and_then(|_| interval_hull(pr));
    let parts = std::cell::OnceCell::new();
    let ped_hull = std::cell::OnceCell::new();
    scene.obstacles.iter().zip(deltas).enumerate().all(|(i, (o, d))| {
        if let (Some(p), true) = (&o.pedestrian, bounds.beyond_cantelli()) {
            // the tail bound (docs/design.md §3.11): a box test, then exact arithmetic
            let hull = ped_hull.get_or_init(|| interval_hull(pr));
            if hull.as_ref().is_some_and(|h| pedestrian_box_clear(p, d, h, pr.t0, pr.t1)) {
                return true;
            }
            return crate::certify::tail::piece_clear_exact(p, d.rational(), pr).is_safe();
        }
        let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - d.rational()));
        if let (Some((Some(n), g1)), Some(b)) = (near.map(|(n, c)| (&n[i], &c[i])), &bbox) {
            let g1 = g1.get_or_init(|| n.cantelli(omd));
            if n.clears(b, Interval::new(pr.t0, pr.t1), g1) {
                return true;
            }
            // a long or curved piece: its parts' boxes (they cover the piece)
            if let Some(parts) = parts.get_or_init(|| sub_hulls(pr, FINAL_CHECK_PARTS)) {
                if parts.iter().all(|(h, t)| n.clears(h, *t, g1)) {
                    return true;
                }
            }
        }
        let (cantelli, mean) = framed.restrict(i, o, pr, omd);
        let exact = std::cell::OnceCell::new();
        let exact = || exact.get_or_init(|| restrict_exact(&o.contour, pr, d.rational()));
        if !bernstein::check(&mean, || exact().mean.clone()).is_safe() {
            return false;
        }
        match bernstein::check(&cantelli, || exact().cantelli.clone()) {
            Verdict::Safe { .. } => true,
            // the other bounds, on sub-intervals (docs/design.md §5.13): the general
            // composition in absolute coordinates first, then (where that loses too much at
            // extreme scales) the compiled restriction in the scene's frame — either proof
            // is sound; only the general one is independent of the fast path
            v if bounds.beyond_cantelli() => {
                let hint = if let Verdict::Unsafe(w) = v { Some(w.tau) } else { None };
                let level = Level::new(d.rational());
                PieceBounds::for_piece(&o.contour, pr, level).cover(hint).is_ok()
                    || compiled.is_some_and(|set| {
                        let sub = super::super::fast::Substitution::new(pr, set.frame());
                        PieceBounds::for_piece_compiled(&o.contour, set.get(i), pr, level)
                            .with_substitution(sub.as_ref())
                            .cover(hint)
                            .is_ok()
                    })
            }
            _ => false,
        }
    })
}

/// Parts in time of a piece whose boxes the final check's box tests try when the whole
/// piece's box meets an obstacle's test region ([`sub_hulls`]).
pub const FINAL_CHECK_PARTS: usize = 8;

/// The piece's `k` parts in time ([`super::index::piece_parts`], which cover it) with each
/// part's hull ([`interval_hull`]) and time interval. `None` when a hull is not available.
fn sub_hulls(pr: PieceRef<'_>, k: usize) -> Option<Vec<(Vec<Interval>, Interval)>> {
    super::index::piece_parts(pr, k)?.into_iter().map(|p| Some((interval_hull(p)?, Interval::new(p.t0, p.t1)))).collect()
}

/// Whether a pedestrian is cleared for a piece by a box test, in the verify path's own
/// arithmetic (docs/design.md §3.11, §5.12): the piece's hull `hull` (over `[t0, t1]`) and
/// the box of the pedestrian's nominal centre over the same times are farther apart than
/// an upper bound of `reach + κ·√s(t)` there (√s is largest at an end: it is convex).
/// From the template's exact numbers, enclosed; independent of the planners' tail code.
fn pedestrian_box_clear(p: &crate::scene::Pedestrian, d: &RiskLevel, hull: &[Interval], t0: f64, t1: f64) -> bool {
    let dim = p.file.position.len();
    let Some(kappa) = crate::contour::tail::tail_kappa(dim, d.rational()) else { return false };
    if hull.len() != dim {
        return false;
    }
    // the template's numbers, enclosed once (`p.disk`: the stds and the reach rounded up)
    let t_ref = p.disk.t_ref;
    let (sp, sv) = (Interval::new(0.0, p.disk.sigma_p), Interval::new(0.0, p.disk.sigma_v));
    let reach = Interval::new(0.0, p.disk.reach);
    let radius = |t: f64| {
        let tau = Interval::point(t) - t_ref;
        let s = sp * sp + sv * sv * tau * tau;
        // sqrt is correctly rounded: the next float up bounds √s.hi from above
        let sd = s.hi.sqrt().next_up();
        reach + Interval::point(kappa) * Interval::point(sd)
    };
    let r = radius(t0).hi.max(radius(t1).hi);
    if !r.is_finite() {
        return false;
    }
    let (ta, tb) = (Interval::point(t0) - t_ref, Interval::point(t1) - t_ref);
    let mut gap2 = Interval::point(0.0);
    for (i, side) in hull.iter().enumerate() {
        let (pi, vi) = (p.disk.position[i], p.disk.velocity[i]);
        let (ca, cb) = (pi + vi * ta, pi + vi * tb);
        let (lo, hi) = (ca.lo.min(cb.lo), ca.hi.max(cb.hi));
        // a lower bound of the gap between [lo, hi] and the hull's side
        let g = if side.lo > hi {
            (Interval::point(side.lo) - Interval::point(hi)).lo.max(0.0)
        } else if lo > side.hi {
            (Interval::point(lo) - Interval::point(side.hi)).lo.max(0.0)
        } else {
            0.0
        };
        gap2 = gap2 + Interval::point(g) * Interval::point(g);
    }
    gap2.lo > (Interval::point(r) * Interval::point(r)).hi
}
