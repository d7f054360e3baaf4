//! The verify path's decision of one piece against every obstacle (`piece_passes_verify_path`): box tests first, then the exact proof on sub-intervals.

use super::*;

/// The box tests of a final check: per obstacle its test (if any) and its Cantelli
/// polynomial at its Δᵢ, formed on first use.
pub(crate) type NearTests<'a> = (&'a [Option<Near>], &'a [OnceLock<NearBound>]);

/// 1 − Δ, enclosed (from the exact Δ).
pub(super) fn one_minus_enclosed(d: &RiskLevel) -> Interval {
    Interval::enclose_rational(&(BigRational::from_integer(1.into()) - d.rational()))
}

/// Whether one piece passes the verify path at one risk level per obstacle: inside the
/// workspace (exact check) and, for every obstacle, both constraints proven positive
/// on the general interval restriction in [`FramedContours`] with the exact rational
/// fallback (the `exact` method of `verify`, without the compiled contours or the
/// covers of the fast path). `only`: the obstacles to examine, when the others are
/// proven clear of the piece already (the final check's [`NearGrid`]); `None`: every one.
#[allow(clippy::too_many_arguments)]
pub fn piece_passes_verify_path(
    scene: &Scene,
    framed: &FramedContours,
    near: Option<NearTests<'_>>,
    pr: PieceRef<'_>,
    deltas: &[RiskLevel],
    bounds: BoundChoice,
    compiled: Option<&crate::checker::compiled_set::CompiledSet>,
    only: Option<&[usize]>,
) -> bool {
    if !pr.is_finite() || check_workspace(&scene.workspace.lower, &scene.workspace.upper, pr).status != Status::Safe {
        return false;
    }
    // the piece's bounding box (outward-rounded Bernstein hull of each coordinate), for
    // the box tests of distant obstacles
    let bbox = near.and_then(|_| interval_hull(pr));
    let parts = std::cell::OnceCell::new();
    let ped_hull = std::cell::OnceCell::new();
    // 1 − Δᵢ enclosed (exact arithmetic), again only when the level differs from the last
    // obstacle's (scenes mostly share one Δ)
    let last: std::cell::Cell<Option<(usize, Interval)>> = std::cell::Cell::new(None);
    let one_minus = |i: usize, d: &RiskLevel| match last.get() {
        Some((prev, om)) if deltas.get(prev) == Some(d) => om,
        _ => {
            let om = one_minus_enclosed(d);
            last.set(Some((i, om)));
            om
        }
    };
    let obstacle_passes = |i: usize| {
        let (Some(o), Some(d)) = (scene.obstacles.get(i), deltas.get(i)) else { return false };
        if let (Some(p), true) = (&o.pedestrian, bounds.beyond_cantelli()) {
            // the tail bound (docs/design.md §3.11): a box test, then exact arithmetic
            let hull = ped_hull.get_or_init(|| interval_hull(pr));
            if hull.as_ref().is_some_and(|h| pedestrian_box_clear(p, d, h, pr.t0, pr.t1)) {
                return true;
            }
            return crate::gaussian_tail::piece_clear_exact(p, d.rational(), pr).is_safe();
        }
        let omd = one_minus(i, d);
        if let (Some((Some(n), g1)), Some(b)) = (near.map(|(n, c)| (&n[i], &c[i])), &bbox) {
            let g1 = g1.get_or_init(|| n.cantelli(omd));
            if box_tests_clear(n, g1, b, pr, &parts) {
                return true;
            }
        }
        proven_on_piece(framed, i, o, pr, d, omd, bounds, compiled)
    };
    match only {
        Some(examined) => examined.iter().all(|&i| obstacle_passes(i)),
        None => (0..scene.obstacles.len()).all(obstacle_passes),
    }
}

/// Whether obstacle `n`'s box test (its Cantelli polynomial `g1` bounded over a box)
/// clears the piece: over the piece's whole box `bbox`, else over each of its parts' boxes
/// (`parts`, formed on first use; they cover the piece).
fn box_tests_clear(
    n: &Near,
    g1: &NearBound,
    bbox: &[Interval],
    pr: PieceRef<'_>,
    parts: &std::cell::OnceCell<Option<Vec<PartHull>>>,
) -> bool {
    if n.clears(bbox, Interval::new(pr.t0, pr.t1), g1) {
        return true;
    }
    // a long or curved piece: its parts' boxes (they cover the piece)
    let Some(parts) = parts.get_or_init(|| sub_hulls(pr, FINAL_CHECK_PARTS)) else { return false };
    // every part must be cleared; the nearest to the obstacle's point first, as the one
    // most likely not to be (most obstacles that reach this test are decided by the
    // restriction: their test ends at its first part)
    let gap =
        |h: &[Interval]| h.iter().zip(n.center()).map(|(s, &c)| (s.lo - c).max(c - s.hi).max(0.0).powi(2)).sum::<f64>();
    let mut order: [(f64, usize); FINAL_CHECK_PARTS] = [(0.0, 0); FINAL_CHECK_PARTS];
    for (k, slot) in order.iter_mut().enumerate().take(parts.len()) {
        *slot = (gap(&parts[k].0), k);
    }
    let order = &mut order[..parts.len().min(FINAL_CHECK_PARTS)];
    order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    parts.len() <= FINAL_CHECK_PARTS && order.iter().all(|&(_, k)| n.clears(&parts[k].0, parts[k].1, g1))
}

/// Whether obstacle `i` (`o`, at risk level `d`, `omd` = 1 − Δᵢ enclosed) is proven safe
/// on the piece by the verify path's own restriction ([`FramedContours::restrict`]) with
/// the exact rational fallback, and where Cantelli's g₁ fails by the other bounds on
/// sub-intervals (docs/design.md §5.13).
#[allow(clippy::too_many_arguments)]
fn proven_on_piece(
    framed: &FramedContours,
    i: usize,
    o: &Obstacle,
    pr: PieceRef<'_>,
    d: &RiskLevel,
    omd: Interval,
    bounds: BoundChoice,
    compiled: Option<&crate::checker::compiled_set::CompiledSet>,
) -> bool {
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
                    let sub = crate::compiled::Substitution::new(pr, set.frame());
                    PieceBounds::for_piece_compiled(&o.contour, set.get(i), pr, level)
                        .with_substitution(sub.as_ref())
                        .cover(hint)
                        .is_ok()
                })
        }
        _ => false,
    }
}

/// A part of a piece in time: its hull (per coordinate) and its time interval.
type PartHull = (Vec<Interval>, Interval);

/// Parts in time of a piece whose boxes the final check's box tests try when the whole
/// piece's box meets an obstacle's test region ([`sub_hulls`]).
pub const FINAL_CHECK_PARTS: usize = 8;

/// The piece's `k` parts in time ([`crate::checker::cover_index::piece_parts`], which cover it) with each
/// part's hull ([`interval_hull`]) and time interval. `None` when a hull is not available.
fn sub_hulls(pr: PieceRef<'_>, k: usize) -> Option<Vec<PartHull>> {
    crate::checker::cover_index::piece_parts(pr, k)?
        .into_iter()
        .map(|p| Some((interval_hull(p)?, Interval::new(p.t0, p.t1))))
        .collect()
}

/// Whether a pedestrian is cleared for a piece by a box test, in the verify path's own
/// arithmetic (docs/design.md §3.11, §5.12): the piece's hull `hull` (over `[t0, t1]`) and
/// the box of the pedestrian's nominal centre over the same times are farther apart than
/// an upper bound of `reach + κ·√s(t)` there (√s is largest at an end: it is convex).
/// From the template's exact numbers, enclosed; independent of the planners' tail code.
fn pedestrian_box_clear(p: &riskplan_scene::Pedestrian, d: &RiskLevel, hull: &[Interval], t0: f64, t1: f64) -> bool {
    let dim = p.file.position.len();
    let Some(kappa) = riskplan_math::contour::tail::tail_kappa(dim, d.rational()) else { return false };
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
