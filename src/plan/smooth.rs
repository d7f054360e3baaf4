//! Certified path post-processing (docs/design.md §6.8): shortcutting and C¹ corner
//! blends, after OMPL's `PathSimplifier`.
//!
//! A plan arrives as waypoints with times, straight at constant velocity in between.
//! 1. **Shortcut** (`shortcut`): random pairs of points on the path are joined by a
//!    straight piece when the certifier accepts it; then each interior waypoint is
//!    dropped when its neighbours can be joined ("reduce vertices"). Static scenes
//!    shortcut the geometric path and re-time it at constant speed; with moving
//!    obstacles the times stay attached to the points.
//! 2. **Blend** (`blend`): each corner at time `tᵢ` between velocities `v⁻` and `v⁺`
//!    is replaced on `[tᵢ − δ, tᵢ + δ]` by the parabola
//!    `x(t) = xᵢ + v⁻(t − tᵢ) + (v⁺ − v⁻)(t − tᵢ + δ)²/(4δ)`, which meets both
//!    straight pieces with their position and velocity: the trajectory becomes C¹
//!    with pieces of degree ≤ 2, its timing unchanged. `δ` is at most a third of each
//!    neighbouring piece, at least `|v⁺ − v⁻|/(2·max_accel)` when an acceleration limit
//!    is given, and halved until the blend is certified; a corner whose blend is never
//!    certified is instead stopped at (`v = 0` at the corner, both neighbours re-timed
//!    with a cubic ease, still on the same segments), and if even that is rejected the
//!    corner is left sharp and counted.
//!
//! Every returned piece is certified by the same motion checker as the plan's edges.

use super::{dist, CheckCounter, Motion, MotionChecker, Termination};
use crate::scene::Piece;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Shortcut attempts per waypoint of the path (OMPL uses a fixed count; proportional
/// keeps long paths improving).
pub const SHORTCUT_ATTEMPTS_PER_WAYPOINT: usize = 12;

/// Fewest shortcut attempts.
pub const MIN_SHORTCUT_ATTEMPTS: usize = 60;

/// Halvings of a blend's half-duration before the corner is stopped at instead.
pub const BLEND_HALVINGS: usize = 6;

/// Largest share of a neighbouring piece's duration a blend may take (a third, so two
/// blends never overlap and a straight part remains between them).
pub const BLEND_SHARE: f64 = 1.0 / 3.0;

/// A waypoint: time and position.
pub type Waypoint = (f64, Vec<f64>);

/// What post-processing did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SmoothStats {
    /// Waypoints before and after shortcutting.
    pub waypoints_before: usize,
    /// Waypoints after.
    pub waypoints_after: usize,
    /// Corners blended (C¹).
    pub corners_blended: usize,
    /// Corners stopped at (C¹ with zero velocity).
    pub corners_stopped: usize,
    /// Corners left sharp (velocity jumps), because no blend or stop was certified.
    pub corners_sharp: usize,
    /// Blends narrower than `max_accel` asks for (the limit is then exceeded there).
    pub accel_violations: usize,
}

fn lerp(a: &[f64], b: &[f64], s: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect()
}

fn path_length(w: &[Waypoint]) -> f64 {
    w.windows(2).map(|p| dist(&p[0].1, &p[1].1)).sum()
}

/// Constant speed over `[t0, tf]` through `points`.
pub fn time_at_constant_speed(points: &[Vec<f64>], horizon: (f64, f64)) -> Vec<Waypoint> {
    let pieces = super::constant_speed(points, horizon);
    let mut out: Vec<Waypoint> = pieces.iter().map(|p| (p.t0, p.at(p.t0))).collect();
    out[0].1 = points[0].clone();
    out.push((horizon.1, points[points.len() - 1].clone()));
    for (w, p) in out.iter_mut().zip(points) {
        w.1 = p.clone();
    }
    out
}

/// Straight pieces through the waypoints, kept in the box `[lower, upper]` at their ends.
pub fn straight(w: &[Waypoint], lower: &[f64], upper: &[f64]) -> Vec<Piece> {
    w.windows(2).map(|p| inside(Piece::segment(&p[0].1, &p[1].1, p[0].0, p[1].0), lower, upper)).collect()
}

/// Ulps a straight piece's constant coefficient may move to keep its ends in the box.
pub const MAX_NUDGE_ULPS: usize = 16;

/// A straight piece whose end lies on the workspace boundary can overshoot it by a
/// rounding of its coefficients (`c0 + c1·t1` need not be the end point exactly), and
/// the exact workspace check then rightly rejects it. This moves each coordinate's
/// constant coefficient by a few ulps towards the inside until both ends are in the box,
/// exactly; positions change by ulps, far below the trajectory format's continuity
/// tolerance.
pub fn inside(mut piece: Piece, lower: &[f64], upper: &[f64]) -> Piece {
    use num_rational::BigRational;
    let q = |v: f64| BigRational::from_float(v);
    let (Some(t0), Some(t1)) = (q(piece.t0), q(piece.t1)) else { return piece };
    for (d, c) in piece.coeffs.iter_mut().enumerate() {
        if c.len() != 2 {
            continue;
        }
        let (Some(lo), Some(hi)) = (q(lower[d]), q(upper[d])) else { continue };
        for _ in 0..MAX_NUDGE_ULPS {
            let (Some(c0), Some(c1)) = (q(c[0]), q(c[1])) else { break };
            let ends = [&c0 + &c1 * &t0, &c0 + &c1 * &t1];
            if ends.iter().any(|e| *e > hi) {
                c[0] = c[0].next_down();
            } else if ends.iter().any(|e| *e < lo) {
                c[0] = c[0].next_up();
            } else {
                break;
            }
        }
    }
    piece
}

/// Shortcuts a path. `timed = false` (static obstacles): the path is geometric, pieces
/// are judged over the whole horizon and the result is re-timed at constant speed.
/// `timed = true` (moving obstacles): a shortcut between the points at times `ta < tb`
/// is the straight piece on `[ta, tb]`, and must respect `max_speed`.
#[allow(clippy::too_many_arguments)]
pub fn shortcut(
    path: Vec<Waypoint>,
    horizon: (f64, f64),
    timed: bool,
    max_speed: Option<f64>,
    checker: &dyn MotionChecker,
    counter: &CheckCounter,
    rng: &mut ChaCha8Rng,
    term: &Termination,
) -> Vec<Waypoint> {
    let mut w = path;
    let judge = |a: &Waypoint, b: &Waypoint| {
        let piece = if timed {
            if max_speed.is_some_and(|v| dist(&a.1, &b.1) > v * (b.0 - a.0)) {
                return false;
            }
            Piece::segment(&a.1, &b.1, a.0, b.0)
        } else {
            Piece::segment(&a.1, &b.1, horizon.0, horizon.1)
        };
        counter.check(checker, &piece) == Motion::Accepted
    };
    let attempts = (w.len() * SHORTCUT_ATTEMPTS_PER_WAYPOINT).max(MIN_SHORTCUT_ATTEMPTS);
    for _ in 0..attempts {
        if w.len() < 3 || term.expired() {
            break;
        }
        // two points on two different pieces (or at waypoints)
        let n = w.len() - 1;
        let (mut i, mut j) = (rng.random_range(0..n), rng.random_range(0..n));
        if i == j {
            continue;
        }
        if i > j {
            std::mem::swap(&mut i, &mut j);
        }
        let (si, sj): (f64, f64) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
        let a: Waypoint = (w[i].0 + (w[i + 1].0 - w[i].0) * si, lerp(&w[i].1, &w[i + 1].1, si));
        let b: Waypoint = (w[j].0 + (w[j + 1].0 - w[j].0) * sj, lerp(&w[j].1, &w[j + 1].1, sj));
        let old = dist(&a.1, &w[i + 1].1) + path_length(&w[i + 1..=j]) + dist(&w[j].1, &b.1);
        if dist(&a.1, &b.1) >= old * (1.0 - 1e-9) || a.0 >= b.0 {
            continue;
        }
        // the new pieces w[i] → a → b → w[j+1] must themselves be certified
        let ok = judge(&w[i], &a) && judge(&a, &b) && judge(&b, &w[j + 1]);
        if !ok {
            continue;
        }
        let mut next: Vec<Waypoint> = w[..=i].to_vec();
        for p in [a, b] {
            if dist(&p.1, &next[next.len() - 1].1) > 0.0 {
                next.push(p);
            }
        }
        next.extend_from_slice(&w[j + 1..]);
        w = next;
    }
    // reduce vertices: drop each interior waypoint whose neighbours can be joined
    let mut k = 1;
    while k + 1 < w.len() && !term.expired() {
        if judge(&w[k - 1], &w[k + 1]) {
            w.remove(k);
        } else {
            k += 1;
        }
    }
    if timed {
        w
    } else {
        let pts: Vec<Vec<f64>> = w.into_iter().map(|p| p.1).collect();
        time_at_constant_speed(&pts, horizon)
    }
}

/// The parabolic blend on `[tc − δ, tc + δ]` at corner `x` between velocities `vin`
/// and `vout`, as a piece in absolute time.
pub fn blend_piece(tc: f64, x: &[f64], vin: &[f64], vout: &[f64], delta: f64) -> Piece {
    // x(t) = x + vin (t − tc) + (vout − vin)(t − tc + δ)²/(4δ), expanded in t
    let a = tc - delta; // (t − a)² with a = tc − δ
    let coeffs = x
        .iter()
        .zip(vin.iter().zip(vout))
        .map(|(&xc, (&vi, &vo))| {
            let k = (vo - vi) / (4.0 * delta);
            // xc − vi·tc + k·a²  +  (vi − 2k·a)·t  +  k·t²
            vec![xc - vi * tc + k * a * a, vi - 2.0 * k * a, k]
        })
        .collect();
    Piece { t0: tc - delta, t1: tc + delta, coeffs }
}

/// A straight move from `a` at `t0` to `b` at `t1` along the segment with start and
/// end speeds scaled by `s0`, `s1` (1: the constant speed of the segment, 0: at rest),
/// as a cubic Hermite in time; stays on the segment for `s0, s1 ∈ [0, 1]`.
pub fn eased_segment(a: &[f64], b: &[f64], t0: f64, t1: f64, s0: f64, s1: f64) -> Piece {
    // x(t) = a + (b − a)·σ(u), u = (t − t0)/h, σ(u) = s0 u + (3 − 2s0 − s1) u² + (s0 + s1 − 2) u³
    let h = t1 - t0;
    let (c1, c2, c3) = (s0, 3.0 - 2.0 * s0 - s1, s0 + s1 - 2.0);
    // expand σ((t − t0)/h) in t
    let p = [-t0 / h, 1.0 / h]; // u = p0 + p1 t
    let u2 = [p[0] * p[0], 2.0 * p[0] * p[1], p[1] * p[1]];
    let u3 = [u2[0] * p[0], u2[0] * p[1] + u2[1] * p[0], u2[1] * p[1] + u2[2] * p[0], u2[2] * p[1]];
    let sigma =
        [c1 * p[0] + c2 * u2[0] + c3 * u3[0], c1 * p[1] + c2 * u2[1] + c3 * u3[1], c2 * u2[2] + c3 * u3[2], c3 * u3[3]];
    let coeffs = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = y - x;
            vec![x + d * sigma[0], d * sigma[1], d * sigma[2], d * sigma[3]]
        })
        .collect();
    Piece { t0, t1, coeffs }
}

/// Turns waypoints into C¹ pieces (see the module doc); every piece is certified.
/// Returns `None` when a straight piece of the input itself is rejected.
pub fn blend(
    w: &[Waypoint],
    workspace: (&[f64], &[f64]),
    max_accel: Option<f64>,
    checker: &dyn MotionChecker,
    counter: &CheckCounter,
    stats: &mut SmoothStats,
    term: &Termination,
) -> Option<Vec<Piece>> {
    let n = w.len();
    let (lower, upper) = workspace;
    if n < 3 {
        let pieces = straight(w, lower, upper);
        return pieces.iter().all(|p| counter.check(checker, p) == Motion::Accepted).then_some(pieces);
    }
    let vel = |i: usize| -> Vec<f64> {
        let h = w[i + 1].0 - w[i].0;
        w[i].1.iter().zip(&w[i + 1].1).map(|(a, b)| (b - a) / h).collect()
    };
    // per interior corner: Some(δ) blended, None stopped or sharp (decided below)
    #[derive(Clone, Copy, PartialEq)]
    enum Corner {
        Blend(f64),
        Stop,
        Sharp,
    }
    let mut corners = vec![Corner::Sharp; n];
    let mut blends: Vec<Option<Piece>> = vec![None; n];
    for i in 1..n - 1 {
        let (vin, vout) = (vel(i - 1), vel(i));
        let jump = dist(&vin, &vout);
        if jump == 0.0 {
            corners[i] = Corner::Blend(0.0);
            continue;
        }
        if term.expired() {
            // past the deadline: no more blend attempts, the corner stays sharp
            continue;
        }
        let max_delta = BLEND_SHARE * (w[i].0 - w[i - 1].0).min(w[i + 1].0 - w[i].0);
        let need = max_accel.map(|a| jump / (2.0 * a));
        let mut delta = max_delta;
        if need.is_some_and(|d| d > max_delta) {
            stats.accel_violations += 1;
        }
        for _ in 0..=BLEND_HALVINGS {
            let piece = blend_piece(w[i].0, &w[i].1, &vin, &vout, delta);
            if counter.check(checker, &piece) == Motion::Accepted {
                corners[i] = Corner::Blend(delta);
                blends[i] = Some(piece);
                break;
            }
            delta *= 0.5;
            if need.is_some_and(|d| delta < d) {
                break;
            }
        }
        if blends[i].is_none() {
            corners[i] = Corner::Stop;
        }
    }
    // the straight parts between blends (eased at stopped corners), certified
    let mut out = Vec::with_capacity(2 * n);
    for i in 0..n - 1 {
        let d0 = match corners[i] {
            Corner::Blend(d) if i > 0 => d,
            _ => 0.0,
        };
        let d1 = match corners[i + 1] {
            Corner::Blend(d) if i + 1 < n - 1 => d,
            _ => 0.0,
        };
        let (ta, tb) = (w[i].0 + d0, w[i + 1].0 - d1);
        let (a, b) = (
            lerp(&w[i].1, &w[i + 1].1, d0 / (w[i + 1].0 - w[i].0)),
            lerp(&w[i].1, &w[i + 1].1, 1.0 - d1 / (w[i + 1].0 - w[i].0)),
        );
        let stop0 = i > 0 && corners[i] == Corner::Stop;
        let stop1 = i + 1 < n - 1 && corners[i + 1] == Corner::Stop;
        let mut piece = if stop0 || stop1 {
            // keep the segment's geometry, scale the end speeds (σ' = 1 is the segment's own speed)
            eased_segment(&a, &b, ta, tb, if stop0 { 0.0 } else { 1.0 }, if stop1 { 0.0 } else { 1.0 })
        } else {
            inside(Piece::segment(&a, &b, ta, tb), lower, upper)
        };
        if (stop0 || stop1) && counter.check(checker, &piece) != Motion::Accepted {
            // the eased timing is rejected (a moving obstacle): leave the corners sharp
            for (flag, idx) in [(stop0, i), (stop1, i + 1)] {
                if flag {
                    corners[idx] = Corner::Sharp;
                }
            }
            piece = inside(Piece::segment(&a, &b, ta, tb), lower, upper);
        }
        if tb > ta || stop0 || stop1 {
            if counter.check(checker, &piece) != Motion::Accepted {
                return None;
            }
            out.push(piece);
        }
        if let Some(b) = blends[i + 1].take() {
            if i + 1 < n - 1 {
                out.push(b);
            }
        }
    }
    for c in &corners[1..n - 1] {
        match c {
            Corner::Blend(_) => stats.corners_blended += 1,
            Corner::Stop => stats.corners_stopped += 1,
            Corner::Sharp => stats.corners_sharp += 1,
        }
    }
    // make the pieces exactly contiguous in time (a blend ends where the next starts)
    for k in 1..out.len() {
        if out[k].t0 != out[k - 1].t1 {
            return None;
        }
    }
    Some(out)
}

/// The velocity of a piece at absolute time `t` (floating point, for tests and reports).
pub fn velocity(p: &Piece, t: f64) -> Vec<f64> {
    p.coeffs
        .iter()
        .map(|c| c.iter().enumerate().skip(1).rev().fold(0.0, |acc, (k, &v)| acc * t + k as f64 * v))
        .collect()
}

/// The largest velocity jump at a joint of a trajectory, relative to the largest speed.
pub fn max_velocity_jump(pieces: &[Piece]) -> f64 {
    let mut jump: f64 = 0.0;
    let mut top: f64 = 0.0;
    for w in pieces.windows(2) {
        let (a, b) = (velocity(&w[0], w[0].t1), velocity(&w[1], w[1].t0));
        jump = jump.max(dist(&a, &b));
        top = top.max(a.iter().map(|v| v * v).sum::<f64>().sqrt());
    }
    if top > 0.0 {
        jump / top
    } else {
        jump
    }
}
