//! Every bound at one point (x, t): proven (exact) for decisions, in floating point for reports and figures.

use super::*;

/// Whether zero risk from the support is proven at the exact point `xt` (`None` without
/// bounded support).
fn support_zero_at(contour: &RiskContour, xt: &[BigRational]) -> Option<bool> {
    contour.support().map(|_| PieceBounds::for_point(contour, xt, Level::ANY).support_proves(0.0, 1.0))
}

/// Every bound at the exact point `xt` (docs/design.md §3.10): Cantelli's exactly, proven
/// upper bounds of the moment bounds, and zero risk when the support proof holds there.
pub fn point_bounds_proven(contour: &RiskContour, xt: &[BigRational]) -> riskplan_math::contour::PointBounds {
    riskplan_math::contour::bounds::point_bounds(contour, xt, support_zero_at(contour, xt))
}

/// Every bound at `xt` (x1..xn, t) in floating point, clamped to [0, 1] (for `risk`
/// and figures, never for decisions): Cantelli's, `support` (0 where zero risk is proven
/// at the point, 1 elsewhere; absent without bounded support) and each moment bound at its
/// best shift (absent where E\[P\] ≥ 0 or the order is not available).
pub fn point_bounds_f64(contour: &RiskContour, xt: &[f64]) -> Vec<(BoundKind, f64)> {
    let mut vals = xt.to_vec();
    vals.resize(contour.layout().xt_len(), 0.0);
    let (mu, second) = contour.moments_f64(&vals);
    let mut out = vec![(BoundKind::Cantelli, cantelli_bound_f64(mu, second))];
    if contour.support().is_some() {
        let exact: Option<Vec<BigRational>> = vals.iter().map(|&v| BigRational::from_float(v)).collect();
        let zero = exact.is_some_and(|x| support_zero_at(contour, &x) == Some(true));
        out.push((BoundKind::Support, if zero { 0.0 } else { 1.0 }));
    }
    if mu < 0.0 {
        let hm = contour.higher();
        let c = hm.eval_f64(&vals);
        for o in hm.orders() {
            if let Some((_, v)) = best_shift(mu, &c, o) {
                out.push((BoundKind::Moment(o), v.clamp(0.0, 1.0)));
            }
        }
    }
    out
}
