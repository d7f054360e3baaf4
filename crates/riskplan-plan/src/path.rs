//! Paths and their timing, shared by the planners: the nearest vertex, constant-speed
//! timing, lengths, and the sound speed bound of a piece (docs/design.md §6.8).

use riskplan_scene::motion::dist;
use riskplan_scene::Piece;

/// Index of the point of `verts` nearest to `q` (linear scan; 0 when empty).
pub fn nearest(verts: &[Vec<f64>], q: &[f64]) -> usize {
    let mut best = (f64::INFINITY, 0);
    for (i, v) in verts.iter().enumerate() {
        let d = dist(v, q);
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// Straight pieces through `points` at constant speed over `[t0, tf]`.
pub fn constant_speed(points: &[Vec<f64>], horizon: (f64, f64)) -> Vec<Piece> {
    let lens: Vec<f64> = points.windows(2).map(|w| dist(&w[0], &w[1])).collect();
    let total: f64 = lens.iter().sum();
    let n = lens.len();
    let mut times = Vec::with_capacity(n + 1);
    times.push(horizon.0);
    let mut acc = 0.0;
    for (i, l) in lens.iter().enumerate() {
        acc += l;
        let t = if i + 1 == n {
            horizon.1
        } else if total > 0.0 {
            horizon.0 + (horizon.1 - horizon.0) * acc / total
        } else {
            horizon.0 + (horizon.1 - horizon.0) * (i + 1) as f64 / n as f64
        };
        times.push(t);
    }
    // Guard against zero-length time steps from rounding: keep times strictly increasing.
    for i in 1..times.len() {
        if times[i] <= times[i - 1] {
            times[i] = times[i - 1].next_up();
        }
    }
    points.windows(2).enumerate().map(|(i, w)| Piece::segment(&w[0], &w[1], times[i], times[i + 1])).collect()
}

/// Length of a trajectory: exact for straight pieces, from 64 chords per piece for
/// curved ones (a lower bound that converges quadratically; for reports only).
pub(crate) fn trajectory_length(pieces: &[Piece]) -> f64 {
    pieces
        .iter()
        .map(|pc| {
            if pc.degree() <= 1 {
                return dist(&pc.at(pc.t0), &pc.at(pc.t1));
            }
            const CHORDS: usize = 64;
            let at = |k: usize| pc.at(pc.t0 + (pc.t1 - pc.t0) * k as f64 / CHORDS as f64);
            (0..CHORDS).map(|k| dist(&at(k), &at(k + 1))).sum::<f64>()
        })
        .sum()
}

/// Relative rounding allowance of [`within_speed`]'s bound on a curved piece, applied to
/// the magnitudes `Σ_k k·|c_k|·(|m| + r)^(k−1)` that the piece's expansion in absolute time
/// works with (docs/design.md §6.8). Re-expanding a coordinate about `m` sums at most 9
/// terms of at most 10 roundings each; the bound's own powers, products and sums and the
/// final norm add fewer than 30 more for degree ≤ 8 and up to 20 coordinates: fewer than 60
/// roundings of relative size ε/2 in all, which `64·ε` covers with room. Without it the
/// expansion in absolute time, which cancels heavily for a short piece far from t = 0,
/// could hide speed.
pub const SPEED_BOUND_ROUNDING: f64 = 64.0 * f64::EPSILON;

/// Sub-intervals of [`within_speed`]'s bound on a piece of degree ≥ 3.
pub const SPEED_SUBINTERVALS: usize = 64;

/// The coefficients of `x(m + s)` in `s`, for `x(t) = Σ_k row[k]·t^k` (a Taylor shift in
/// floating point: `e_j = Σ_{k ≥ j} C(k, j)·row[k]·m^(k−j)`; the binomials are exact).
pub(crate) fn taylor_shift(row: &[f64], m: f64) -> Vec<f64> {
    (0..row.len())
        .map(|j| {
            let (mut binom, mut pow, mut sum) = (1.0, 1.0, 0.0);
            for (k, &c) in row.iter().enumerate().skip(j) {
                sum += binom * c * pow;
                // C(k + 1, j) = C(k, j)·(k + 1)/(k + 1 − j), an integer
                binom = binom * (k + 1) as f64 / (k + 1 - j) as f64;
                pow *= m;
            }
            sum
        })
        .collect()
}

/// An upper bound on the speed `|ẋ(t)|` of a piece for `|t − m| ≤ r`: each coordinate
/// re-expanded about `m` as `Σ_j e_j (t − m)^j` has `|ẋ| ≤ Σ_j j·|e_j|·r^(j−1)`, plus
/// [`SPEED_BOUND_ROUNDING`] times the magnitudes of the expansion; the coordinates'
/// bounds are combined by the Euclidean norm.
fn speed_bound(pc: &Piece, m: f64, r: f64) -> f64 {
    let scale = m.abs() + r;
    pc.coeffs
        .iter()
        .map(|row| {
            let e = taylor_shift(row, m);
            let tight: f64 = e.iter().enumerate().skip(1).map(|(j, c)| j as f64 * c.abs() * r.powi(j as i32 - 1)).sum();
            let magnitude: f64 =
                row.iter().enumerate().skip(1).map(|(k, c)| k as f64 * c.abs() * scale.powi(k as i32 - 1)).sum();
            let b = tight + SPEED_BOUND_ROUNDING * magnitude;
            b * b
        })
        .sum::<f64>()
        .sqrt()
}

/// Whether a piece's speed stays within `v` (docs/design.md §6.8; every planner's speed
/// check, and every piece smoothing returns under a speed limit):
/// - a straight piece by its chord, `|x(t1) − x(t0)| ≤ v·(t1 − t0)` in floating point;
/// - a piece of degree 2 (a blend) by its end velocities: its velocity is affine in t, so
///   its speed is convex and largest at an end — exact up to [`SPEED_BOUND_ROUNDING`];
/// - a piece of higher degree (an eased part) by the bound of `speed_bound` on each of
///   [`SPEED_SUBINTERVALS`] sub-intervals, expanded about its centre — conservative (by
///   less than 10⁻³ of the peak for the cubic eases smoothing makes: a piece it rejects
///   may in truth be within the limit).
pub fn within_speed(pc: &Piece, v: f64) -> bool {
    match pc.degree() {
        0 | 1 => dist(&pc.at(pc.t0), &pc.at(pc.t1)) <= v * (pc.t1 - pc.t0),
        2 => [pc.t0, pc.t1].iter().all(|&t| speed_bound(pc, t, 0.0) <= v),
        _ => {
            let h = (pc.t1 - pc.t0) / SPEED_SUBINTERVALS as f64;
            (0..SPEED_SUBINTERVALS).all(|k| {
                let (a, b) = (
                    pc.t0 + h * k as f64,
                    if k + 1 == SPEED_SUBINTERVALS { pc.t1 } else { pc.t0 + h * (k + 1) as f64 },
                );
                let m = a + (b - a) * 0.5;
                // the sub-intervals cover [t0, t1]: r reaches both computed ends
                speed_bound(pc, m, (m - a).max(b - m)) <= v
            })
        }
    }
}
