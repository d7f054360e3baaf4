//! Certified path post-processing (docs/design.md §6.8): shortcutting and C¹ corner
//! blends, after OMPL's `PathSimplifier`.
//!
//! A plan arrives as waypoints with times, straight at constant velocity in between.
//! 1. **Shortcut** (`shortcut`): random pairs of points on the path are joined by a
//!    straight piece when the certifier accepts it, within a [`WorkBudget`]; then each
//!    interior waypoint is dropped when its neighbours can be joined ("reduce vertices").
//!    Static scenes shortcut the geometric path and re-time it at constant speed; with
//!    moving obstacles the times stay attached to the points.
//! 2. **Blend** (`blend`): each corner at time `tᵢ` between velocities `v⁻` and `v⁺`
//!    is replaced on `[tᵢ − δ, tᵢ + δ]` by the parabola
//!    `x(t) = xᵢ + v⁻(t − tᵢ) + (v⁺ − v⁻)(t − tᵢ + δ)²/(4δ)`, which meets both
//!    straight pieces with their position and velocity: the trajectory becomes C¹
//!    with pieces of degree ≤ 2, its timing unchanged. `δ` is at most a third of each
//!    neighbouring piece, at least `|v⁺ − v⁻|/(2·max_accel)` when an acceleration limit
//!    is given, and halved until the blend is accepted; a corner whose blend is never
//!    accepted is instead stopped at (`v = 0` at the corner, the neighbouring parts eased
//!    by a cubic, still on the same segments), and if even that is rejected the corner is
//!    left sharp and counted.
//! 3. **Limits** ([`Limits`]): with a speed limit every returned piece — straight part,
//!    blend or eased part — passes [`within_speed`], and a piece that does not is treated
//!    like an uncertified one. An eased part on its segment's own time span peaks at 4/3
//!    (one end stopped) or 3/2 (both) of the segment's speed; on static scenes, when that
//!    breaks the limit, the path is re-timed over the same horizon so that every piece peaks
//!    at one speed `u` (eased parts take longer, the rest goes faster: see [`blend`]);
//!    stops that even this cannot afford are refused (the corner stays sharp). The
//!    acceleration limit is a target: blends are made wide enough where the corner allows,
//!    and every returned piece above it is counted in [`SmoothStats::accel_violations`].
//!
//! Every returned piece is accepted by the same motion checker as the plan's edges.

use crate::{dist, taylor_shift, within_speed, CheckCounter, Kinematics, Motion, MotionChecker, Termination};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
pub(crate) use riskplan_certify::whole_path::add_up;
use riskplan_scene::{Piece, CONTINUITY_TOLERANCE};
use std::time::Instant;

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

/// A straight part between two blends that the checker refuses whole is tried again as
/// 2, 4 and 8 equal pieces (`straight_part`): measured on example-d1 (seed 3), a part
/// starting beside a corner in a contour's Cantelli ring was refused whole and proven in
/// two halves. Three levels bound the extra checks of a part that is truly refused at 14.
pub const STRAIGHT_SPLITS: u32 = 3;

/// A deterministic budget of checking work for post-processing (docs/design.md §6.8): the
/// checker's work ([`CheckCounter::work`]) at which shortcutting stops. Work, not time, so
/// that a plan stays reproducible by seed on a busy machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WorkBudget {
    until: Option<u64>,
}

impl WorkBudget {
    /// No limit.
    pub const UNLIMITED: WorkBudget = WorkBudget { until: None };

    /// Ends when the checker's work reaches `work`.
    pub fn until(work: u64) -> Self {
        WorkBudget { until: Some(work) }
    }

    /// Whether work is left.
    pub fn left(&self, counter: &CheckCounter, checker: &dyn MotionChecker) -> bool {
        self.until.is_none_or(|u| counter.work(checker) < u)
    }
}

/// A waypoint: time and position.
pub type Waypoint = (f64, Vec<f64>);

/// What post-processing did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct SmoothStats {
    /// Waypoints before and after shortcutting.
    pub waypoints_before: usize,
    /// Waypoints after.
    pub waypoints_after: usize,
    /// Corners blended (C¹).
    pub corners_blended: usize,
    /// Corners stopped at (C¹ with zero velocity).
    pub corners_stopped: usize,
    /// Corners left sharp (velocity jumps), because no blend or stop was accepted (certified
    /// and, with a speed limit, within it).
    pub corners_sharp: usize,
    /// Returned blends and eased parts whose peak acceleration is above `max_accel` (a
    /// target, not refused: docs/design.md §6.8).
    pub accel_violations: usize,
    /// Wall time of the random shortcuts ([`shortcut`], of every candidate path's too),
    /// seconds. Of the plan's `improve_time_s`, what these three times leave is the
    /// candidate paths' own searches and the fallbacks to straight pieces.
    #[serde(default)]
    pub shortcut_seconds: f64,
    /// Wall time of the vertex reduction after the random shortcuts, seconds.
    #[serde(default)]
    pub reduction_seconds: f64,
    /// Wall time of the corner blends and the checks of the pieces between them
    /// ([`blend`]), seconds.
    #[serde(default)]
    pub blend_seconds: f64,
}

fn lerp(a: &[f64], b: &[f64], s: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect()
}

fn path_length(w: &[Waypoint]) -> f64 {
    w.windows(2).map(|p| dist(&p[0].1, &p[1].1)).sum()
}

/// Constant speed over `[t0, tf]` through `points`.
pub fn time_at_constant_speed(points: &[Vec<f64>], horizon: (f64, f64)) -> Vec<Waypoint> {
    let pieces = crate::constant_speed(points, horizon);
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
    // exactly, in dyadic rationals (what floats' sums and products are)
    let q = riskplan_math::poly::dyadic::Dyadic::from_f64;
    let (Some(t0), Some(t1)) = (q(piece.t0), q(piece.t1)) else { return piece };
    for (d, c) in piece.coeffs.iter_mut().enumerate() {
        if c.len() != 2 {
            continue;
        }
        let (Some(lo), Some(hi)) = (q(lower[d]), q(upper[d])) else { continue };
        for _ in 0..MAX_NUDGE_ULPS {
            let (Some(c0), Some(c1)) = (q(c[0]), q(c[1])) else { break };
            let ends = [c0.add(&c1.mul(&t0)), c0.add(&c1.mul(&t1))];
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

/// A random shortcut's end closer to an end of its piece than this share of the piece is
/// moved onto that waypoint (docs/design.md §6.8): without it a shortcut could leave a
/// piece of any shortness beside a waypoint — a segment of 10⁻⁶ of the path, timed over a
/// horizon of length 1, lasts 5·10⁻⁷ — whose corner no blend can take and whose eased parts
/// have coefficients of order 10¹³ in absolute time. The shortcut gives up at most this
/// share of one piece's length.
pub const SHORTCUT_SNAP_SHARE: f64 = 1e-3;

/// `s ∈ [0, 1)` moved to 0 or 1 within [`SHORTCUT_SNAP_SHARE`] of either.
fn snapped(s: f64) -> f64 {
    if s < SHORTCUT_SNAP_SHARE {
        0.0
    } else if s > 1.0 - SHORTCUT_SNAP_SHARE {
        1.0
    } else {
        s
    }
}

/// The point at share `s` of piece `i` of the path (its waypoints themselves, exactly, at
/// `s = 0` and `s = 1`).
fn point_on(w: &[Waypoint], i: usize, s: f64) -> Waypoint {
    if s == 0.0 {
        w[i].clone()
    } else if s == 1.0 {
        w[i + 1].clone()
    } else {
        (w[i].0 + (w[i + 1].0 - w[i].0) * s, lerp(&w[i].1, &w[i + 1].1, s))
    }
}

/// Shortcuts a path. `timed = false` (static obstacles): the path is geometric, pieces
/// are judged over the whole horizon and the result is re-timed at constant speed.
/// `timed = true` (moving obstacles): a shortcut between the points at times `ta < tb`
/// is the straight piece on `[ta, tb]`, and must pass [`within_speed`] under `max_speed`.
/// The times of its two steps are added to `stats`.
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
    budget: WorkBudget,
    path_budget: Option<f64>,
    stats: &mut SmoothStats,
) -> Vec<Waypoint> {
    let began = Instant::now();
    let mut w = path;
    // Some(the piece's whole-path bound, 0 without a budget) when the piece is accepted
    // (`guess`: a piece the checker guesses refused is not checked)
    let judge_with = |a: &Waypoint, b: &Waypoint, guess: bool| -> Option<f64> {
        let piece = if timed {
            let piece = Piece::segment(&a.1, &b.1, a.0, b.0);
            if max_speed.is_some_and(|v| !within_speed(&piece, v)) {
                return None;
            }
            piece
        } else {
            Piece::segment(&a.1, &b.1, horizon.0, horizon.1)
        };
        if (guess && checker.likely_rejected(&piece)) || counter.check(checker, &piece) != Motion::Accepted {
            return None;
        }
        Some(if path_budget.is_some() { checker.path_risk(&piece, &|| term.should_stop()).unwrap_or(1.0) } else { 0.0 })
    };
    let judge = |a: &Waypoint, b: &Waypoint| judge_with(a, b, true);
    // each piece's whole-path bound, and their sum (docs/design.md §5.14): a shortcut is
    // kept only when the path's new sum stays within the budget
    let mut risks: Vec<f64> = if path_budget.is_some() {
        // (the path's own pieces, accepted already: checked, never guessed — a guess
        // that misfired would count one as 1 and leave the path unshortened)
        w.windows(2).map(|p| judge_with(&p[0], &p[1], false).unwrap_or(1.0)).collect()
    } else {
        vec![0.0; w.len().saturating_sub(1)]
    };
    let total = |r: &[f64]| r.iter().fold(0.0, |acc, &x| add_up(acc, x));
    let within = |r: &[f64]| path_budget.is_none_or(|d| total(r) <= d);
    let left = || !term.expired() && budget.left(counter, checker);
    let attempts = (w.len() * SHORTCUT_ATTEMPTS_PER_WAYPOINT).max(MIN_SHORTCUT_ATTEMPTS);
    for _ in 0..attempts {
        if w.len() < 3 || !left() {
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
        let (si, sj) = (snapped(rng.random_range(0.0..1.0)), snapped(rng.random_range(0.0..1.0)));
        let (a, b) = (point_on(&w, i, si), point_on(&w, j, sj));
        let old = dist(&a.1, &w[i + 1].1) + path_length(&w[i + 1..=j]) + dist(&w[j].1, &b.1);
        if dist(&a.1, &b.1) >= old * (1.0 - 1e-9) || a.0 >= b.0 {
            continue;
        }
        // the new pieces w[i] → a → b → w[j+1] must themselves be certified; the shortcut
        // a → b first, as it is the one most likely refused (the other two lie along
        // pieces already certified, up to the rounding of a and b)
        let Some(rab) = judge(&a, &b) else { continue };
        // (not guessed: they lie along certified pieces, where E[P] < 0 for every obstacle
        // — the mean constraint of eq. (15) — so the guess, which looks for E[P] ≥ 0 at
        // samples, would only spend its samples on them, a large share of its calls on
        // crowded scenes. Untimed, a sub-segment is retimed over the horizon, and an
        // obstacle whose P depends on t may differ there: the check decides it all the
        // same, the guess only ever spared work)
        // (an end snapped onto its waypoint has no piece there to check)
        let (a_new, b_new) = (dist(&w[i].1, &a.1) > 0.0, dist(&b.1, &w[j + 1].1) > 0.0);
        let Some(ria) = (if a_new { judge_with(&w[i], &a, false) } else { Some(0.0) }) else { continue };
        let Some(rbj) = (if b_new { judge_with(&b, &w[j + 1], false) } else { Some(0.0) }) else { continue };
        let mut next: Vec<Waypoint> = w[..=i].to_vec();
        let mut next_r: Vec<f64> = risks[..i].to_vec();
        let mut pending = ria;
        for (p, r, new) in [(a, rab, true), (b, rbj, b_new)] {
            if !new {
                // b is w[j + 1]: the piece up to it is the pending one
                continue;
            }
            if dist(&p.1, &next[next.len() - 1].1) > 0.0 {
                next.push(p);
                next_r.push(pending);
                pending = r;
            } else {
                // a waypoint merged with its predecessor: its piece is the next one
                pending = r;
            }
        }
        next_r.push(pending);
        next.extend_from_slice(&w[j + 1..]);
        next_r.extend_from_slice(&risks[j + 1..]);
        if next_r.len() + 1 != next.len() || !within(&next_r) {
            continue;
        }
        w = next;
        risks = next_r;
    }
    // reduce vertices: drop each interior waypoint whose neighbours can be joined, after
    // the random attempts (on the search's many short steps they find the corners a greedy
    // reduction misses: one corner at a neck where the reduction leaves two); at most one
    // check per waypoint, so outside the budget (a path left with dozens of waypoints would
    // cost more in blends than the reduction)
    let reducing = Instant::now();
    stats.shortcut_seconds += (reducing - began).as_secs_f64();
    let mut k = 1;
    while k + 1 < w.len() && !term.expired() {
        let joined = judge(&w[k - 1], &w[k + 1]).filter(|&r| {
            let mut next_r = risks.clone();
            next_r.splice(k - 1..=k, [r]);
            within(&next_r)
        });
        if let Some(r) = joined {
            w.remove(k);
            risks.splice(k - 1..=k, [r]);
        } else {
            k += 1;
        }
    }
    stats.reduction_seconds += reducing.elapsed().as_secs_f64();
    if timed {
        w
    } else {
        let pts: Vec<Vec<f64>> = w.into_iter().map(|p| p.1).collect();
        time_at_constant_speed(&pts, horizon)
    }
}

/// Whether a blend's ends, evaluated from its expanded coefficients, are within `tol` of the
/// straight parts it joins (`x − vin·δ` and `x + vout·δ`).
fn blend_meets(piece: &Piece, x: &[f64], vin: &[f64], vout: &[f64], delta: f64, tol: f64) -> bool {
    let a: Vec<f64> = x.iter().zip(vin).map(|(xc, v)| xc - v * delta).collect();
    let b: Vec<f64> = x.iter().zip(vout).map(|(xc, v)| xc + v * delta).collect();
    meets(piece, &a, &b, tol)
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
/// end speeds `s0`, `s1` relative to the move's mean speed `|b − a|/(t1 − t0)` (1: the
/// mean speed, 0: at rest), as a cubic Hermite in time:
/// `x(t) = a + (b − a)·σ(u)`, `u = (t − t0)/(t1 − t0)`, `σ(0) = 0`, `σ(1) = 1`,
/// `σ'(0) = s0`, `σ'(1) = s1`. It stays on the segment when σ is monotone (`σ' ≥ 0` on
/// [0, 1]), which holds for every profile in [`EASE_PROFILES`]; the peak of `σ'` (the
/// peak speed over the mean speed) is given there.
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

/// The eased parts `blend` makes, as `(s0, s1, peak)`: end speeds relative to the part's
/// mean speed (see [`eased_segment`]) and the peak of its speed over its mean speed, exact
/// (docs/design.md §6.8):
/// - `(1, 0)`: `σ' = 1 + 2u − 3u²`, peak 4/3 at u = 1/3 (and `(0, 1)` mirrored);
/// - `(0, 0)`: `σ' = 6u(1 − u)`, peak 3/2 at u = 1/2;
/// - `(3/2, 0)`: `σ' = 3/2·(1 − u²)`, peak 3/2 at u = 0, its moving end (and `(0, 3/2)`
///   mirrored).
///
/// All five have `σ' ≥ 0` on [0, 1], so they stay on their segment.
pub const EASE_PROFILES: [(f64, f64, f64); 5] =
    [(1.0, 0.0, 4.0 / 3.0), (0.0, 1.0, 4.0 / 3.0), (0.0, 0.0, 1.5), (1.5, 0.0, 1.5), (0.0, 1.5, 1.5)];

/// The limits smoothing keeps (docs/design.md §6.8).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Limits {
    /// Speed limit, kept by every returned piece: each passes [`within_speed`], and a
    /// blend, eased part or straight part that does not is treated like an uncertified one.
    pub max_speed: Option<f64>,
    /// Acceleration target: blends are made at least `|v⁺ − v⁻|/(2·max_accel)` wide where
    /// the corner allows it, and every returned blend or eased part whose peak acceleration
    /// is above it is counted in [`SmoothStats::accel_violations`] (it is not refused: a
    /// corner that cannot take a wide enough blend would otherwise stay sharp, which is
    /// worse).
    pub max_accel: Option<f64>,
}

impl Limits {
    /// The limits of a plan's [`Kinematics`].
    pub fn of(k: &Kinematics) -> Limits {
        Limits { max_speed: k.max_speed, max_accel: k.max_accel }
    }
}

/// How a corner is joined.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Corner {
    /// A parabolic blend of this half-duration (0: the segments are collinear, no blend).
    Blend(f64),
    /// Stopped at: zero velocity, the neighbouring parts eased.
    Stop,
    /// Left sharp: the velocity jumps.
    Sharp,
}

/// A timing of the waypoints the pieces are assembled in.
struct Timing {
    /// Waypoint times; the first and the last are the input's, exactly.
    times: Vec<f64>,
    /// Velocity of each segment's straight part, which the blends at its ends meet.
    vel: Vec<Vec<f64>>,
    /// Half-duration of each corner's blend in this timing (0 without one).
    delta: Vec<f64>,
    /// Share of each segment taken by the blends at its start and at its end.
    cut: Vec<(f64, f64)>,
    /// The static re-timing (else the input's own timing, whose blends are checked already).
    retimed: bool,
}

/// `(s0, s1, stretch)` of segment `j`'s middle part in a re-timed static path (§6.8): a
/// part with a stopped end is eased, its moving end matching the speed `u` of the rest of
/// the path where it meets a blend or a collinear continuation (profile `(3/2, 0)`) and free
/// at a sharp corner or at the path's ends (`(1, 0)`, the least peak for a free end), with
/// both ends stopped `(0, 0)`; `stretch` = the profile's peak, so that the part, taking
/// `stretch` times its duration at speed `u`, peaks at exactly `u`.
fn retimed_profile(corners: &[Corner], j: usize) -> (f64, f64, f64) {
    let n = corners.len();
    let stop = |i: usize| 0 < i && i < n - 1 && corners[i] == Corner::Stop;
    let joined = |i: usize| 0 < i && i < n - 1 && matches!(corners[i], Corner::Blend(_));
    let pick = |k: usize| (EASE_PROFILES[k].0, EASE_PROFILES[k].1, EASE_PROFILES[k].2);
    match (stop(j), stop(j + 1)) {
        (false, false) => (1.0, 1.0, 1.0),
        (true, true) => pick(2),
        (false, true) if joined(j) => pick(3),
        (false, true) => pick(0),
        (true, false) if joined(j + 1) => pick(4),
        (true, false) => pick(1),
    }
}

/// The input's own timing.
fn given_timing(w: &[Waypoint], corners: &[Corner]) -> Timing {
    let n = w.len();
    let delta: Vec<f64> = corners
        .iter()
        .enumerate()
        .map(|(i, c)| match c {
            Corner::Blend(d) if 0 < i && i < n - 1 => *d,
            _ => 0.0,
        })
        .collect();
    let h = |j: usize| w[j + 1].0 - w[j].0;
    Timing {
        times: w.iter().map(|p| p.0).collect(),
        vel: (0..n - 1).map(|j| w[j].1.iter().zip(&w[j + 1].1).map(|(a, b)| (b - a) / h(j)).collect()).collect(),
        cut: (0..n - 1).map(|j| (delta[j] / h(j), delta[j + 1] / h(j))).collect(),
        delta,
        retimed: false,
    }
}

/// The static re-timing (docs/design.md §6.8) of a path timed at constant speed `u₀ = L/T`:
/// the geometry is kept — segments, and each blend's reach `λ = δ·u₀` along its two
/// segments — while straight parts and blends move at one speed `u` and each eased part
/// takes `stretch` times its duration at `u` ([`retimed_profile`]), so that every piece
/// peaks at `u`, and the horizon's ends stay where they are:
/// `u = Σⱼ (λⱼ + λⱼ₊₁ + stretchⱼ·mⱼ)/T` with `mⱼ = ℓⱼ − λⱼ − λⱼ₊₁`. Returns the timing and
/// `u`; `None` when rounding leaves two waypoint times out of order.
fn retimed(w: &[Waypoint], corners: &[Corner]) -> Option<(Timing, f64)> {
    let n = w.len();
    let (t0, tf) = (w[0].0, w[n - 1].0);
    let lens: Vec<f64> = w.windows(2).map(|p| dist(&p[0].1, &p[1].1)).collect();
    let u0 = lens.iter().sum::<f64>() / (tf - t0);
    let reach: Vec<f64> = corners
        .iter()
        .enumerate()
        .map(|(i, c)| match c {
            Corner::Blend(d) if 0 < i && i < n - 1 => d * u0,
            _ => 0.0,
        })
        .collect();
    let weights: Vec<f64> = (0..n - 1)
        .map(|j| {
            let mid = lens[j] - reach[j] - reach[j + 1];
            reach[j] + reach[j + 1] + retimed_profile(corners, j).2 * mid
        })
        .collect();
    let total: f64 = weights.iter().sum();
    let u = total / (tf - t0);
    let mut times = vec![t0];
    let mut acc = 0.0;
    for (j, wt) in weights.iter().enumerate() {
        acc += wt;
        times.push(if j + 2 == n { tf } else { t0 + (tf - t0) * (acc / total) });
    }
    if times.windows(2).any(|p| p[1] <= p[0]) || lens.iter().any(|&l| l <= 0.0) || !u.is_finite() {
        return None;
    }
    let timing = Timing {
        times,
        vel: (0..n - 1)
            .map(|j| w[j].1.iter().zip(&w[j + 1].1).map(|(a, b)| (b - a) * (u / lens[j])).collect())
            .collect(),
        delta: reach.iter().map(|r| r / u).collect(),
        cut: (0..n - 1).map(|j| (reach[j] / lens[j], reach[j + 1] / lens[j])).collect(),
        retimed: true,
    };
    Some((timing, u))
}

/// The straight part from `a` at `ta` to `b` at `tb` as accepted pieces: one piece, or
/// when the checker refuses it, the same motion split into 2, 4, … 2^[`STRAIGHT_SPLITS`]
/// pieces of equal duration (collinear, at one velocity: the path stays C¹). A straight
/// part is a sub-segment of a segment the shortcut step certified, but a proof by the
/// higher-moment bounds (docs/design.md §5.13) subdivides each piece's own time
/// dyadically within a depth and node budget, so a part that starts in the middle of a
/// grazing stretch can miss the covers its parent had; shorter pieces give the search
/// new subdivisions and budgets. Every returned piece is accepted on its own.
fn straight_part(
    a: &[f64],
    b: &[f64],
    ta: f64,
    tb: f64,
    workspace: (&[f64], &[f64]),
    accept: &dyn Fn(&Piece) -> bool,
) -> Option<Vec<Piece>> {
    let whole = inside(Piece::segment(a, b, ta, tb), workspace.0, workspace.1);
    if accept(&whole) {
        return Some(vec![whole]);
    }
    for level in 1..=STRAIGHT_SPLITS {
        let k = 1usize << level;
        let at = |j: usize| -> (f64, Vec<f64>) {
            if j == k {
                (tb, b.to_vec())
            } else {
                let s = j as f64 / k as f64;
                (ta + (tb - ta) * s, lerp(a, b, s))
            }
        };
        let pieces: Option<Vec<Piece>> = (0..k)
            .map(|j| {
                let ((t0, p0), (t1, p1)) = (at(j), at(j + 1));
                let pc = inside(Piece::segment(&p0, &p1, t0, t1), workspace.0, workspace.1);
                (t1 > t0 && accept(&pc)).then_some(pc)
            })
            .collect();
        if pieces.is_some() {
            return pieces;
        }
    }
    None
}

/// The share of [`CONTINUITY_TOLERANCE`] (times the workspace diagonal, at least 1: the
/// trajectory format's own test) within which every piece smoothing makes must meet the
/// straight parts it joins, evaluated from its expanded coefficients. Pieces are
/// polynomials in absolute time, so a short blend or eased part far from `t = 0` has
/// coefficients of order `(t/h)^degree` and its ends round away from the points they were
/// built through; a tenth of the format's tolerance leaves the rest of it to the straight
/// parts' own rounding.
pub const JOIN_SHARE: f64 = 0.1;

/// Whether `piece`, evaluated from its coefficients, starts within `tol` of `a` and ends
/// within `tol` of `b`, in every coordinate.
fn meets(piece: &Piece, a: &[f64], b: &[f64], tol: f64) -> bool {
    let (pa, pb) = (piece.at(piece.t0), piece.at(piece.t1));
    pa.iter().zip(a).chain(pb.iter().zip(b)).all(|(x, y)| (x - y).abs() <= tol)
}

/// How an assembly ended.
enum Assembly {
    /// Every piece accepted.
    Done(Vec<Piece>),
    /// An eased part was rejected: its stopped corners.
    EaseRejected(Vec<usize>),
    /// A straight part or a blend was rejected, or the pieces are not contiguous.
    Rejected,
}

/// The pieces of the path in `timing`: straight parts, blends, eased parts at stopped
/// corners; each must be accepted (`accept`: the speed limit and the motion checker).
fn assemble(
    w: &[Waypoint],
    corners: &[Corner],
    timing: &Timing,
    blends: &[Option<Piece>],
    workspace: (&[f64], &[f64]),
    accept: &dyn Fn(&Piece) -> bool,
) -> Assembly {
    let n = w.len();
    let join_tol = JOIN_SHARE * CONTINUITY_TOLERANCE * dist(workspace.0, workspace.1).max(1.0);
    let mut out = Vec::with_capacity(2 * n);
    for i in 0..n - 1 {
        let (d0, d1) = (timing.delta[i], timing.delta[i + 1]);
        let (ta, tb) = (timing.times[i] + d0, timing.times[i + 1] - d1);
        let (c0, c1) = timing.cut[i];
        let (a, b) = (lerp(&w[i].1, &w[i + 1].1, c0), lerp(&w[i].1, &w[i + 1].1, 1.0 - c1));
        let stop0 = i > 0 && corners[i] == Corner::Stop;
        let stop1 = i + 1 < n - 1 && corners[i + 1] == Corner::Stop;
        if stop0 || stop1 {
            // on the input's timing the moving end keeps the segment's speed (σ' = 1)
            let (s0, s1, _) = if timing.retimed {
                retimed_profile(corners, i)
            } else {
                (if stop0 { 0.0 } else { 1.0 }, if stop1 { 0.0 } else { 1.0 }, 1.0)
            };
            let piece = eased_segment(&a, &b, ta, tb, s0, s1);
            if !meets(&piece, &a, &b, join_tol) || !accept(&piece) {
                return Assembly::EaseRejected(
                    [(stop0, i), (stop1, i + 1)].iter().filter(|e| e.0).map(|e| e.1).collect(),
                );
            }
            out.push(piece);
        } else if tb > ta {
            match straight_part(&a, &b, ta, tb, workspace, accept) {
                Some(pieces) => out.extend(pieces),
                None => return Assembly::Rejected,
            }
        }
        if i + 1 < n - 1 && timing.delta[i + 1] > 0.0 {
            let piece = if timing.retimed {
                let (x, vin, vout, d) = (&w[i + 1].1, &timing.vel[i], &timing.vel[i + 1], timing.delta[i + 1]);
                let pc = blend_piece(timing.times[i + 1], x, vin, vout, d);
                if !blend_meets(&pc, x, vin, vout, d, join_tol) || !accept(&pc) {
                    return Assembly::Rejected;
                }
                pc
            } else {
                match &blends[i + 1] {
                    Some(pc) => pc.clone(),
                    None => return Assembly::Rejected,
                }
            };
            out.push(piece);
        }
    }
    // the pieces must be exactly contiguous in time (a blend ends where the next starts),
    // and meet in space as the trajectory format demands
    let gap =
        |p: &[Piece]| p[0].at(p[0].t1).iter().zip(p[1].at(p[1].t0)).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    if out.windows(2).any(|p| p[1].t0 != p[0].t1 || gap(p) > join_tol / JOIN_SHARE) {
        return Assembly::Rejected;
    }
    Assembly::Done(out)
}

/// Turns waypoints into C¹ pieces (see the module doc and docs/design.md §6.8); every
/// returned piece is accepted by `checker` and, with a speed limit, passes
/// [`within_speed`]. `timed = false` (static obstacles): the waypoints are timed at
/// constant speed over the horizon (as [`shortcut`] returns them) and only their geometry
/// matters, so a path with stopped corners may be re-timed: first the input's timing is
/// tried (eased parts peak at 4/3 or 3/2 of the path's speed), then the re-timing in which
/// every piece peaks at one speed `u` (docs/design.md §6.8), and if `u` breaks the limit
/// the stop whose refusal lowers `u` most is refused (the corner stays sharp), until the
/// pieces keep it. `timed = true` (moving obstacles): times stay attached to the points, and a stop
/// whose eased parts break the limit is refused. Returns `None` when a straight part is
/// rejected (or, at a path without corners, any piece). Its time is added to
/// `stats.blend_seconds`.
#[allow(clippy::too_many_arguments)]
pub fn blend(
    w: &[Waypoint],
    workspace: (&[f64], &[f64]),
    limits: Limits,
    timed: bool,
    checker: &dyn MotionChecker,
    counter: &CheckCounter,
    stats: &mut SmoothStats,
    term: &Termination,
) -> Option<Vec<Piece>> {
    let began = Instant::now();
    let out = blend_corners(w, workspace, limits, timed, checker, counter, stats, term);
    stats.blend_seconds += began.elapsed().as_secs_f64();
    out
}

/// [`blend`] without its timing.
#[allow(clippy::too_many_arguments)]
fn blend_corners(
    w: &[Waypoint],
    workspace: (&[f64], &[f64]),
    limits: Limits,
    timed: bool,
    checker: &dyn MotionChecker,
    counter: &CheckCounter,
    stats: &mut SmoothStats,
    term: &Termination,
) -> Option<Vec<Piece>> {
    let n = w.len();
    let (lower, upper) = workspace;
    let diag = dist(lower, upper);
    let accept = |pc: &Piece| {
        limits.max_speed.is_none_or(|v| within_speed(pc, v)) && counter.check(checker, pc) == Motion::Accepted
    };
    if n < 3 {
        let pieces = straight(w, lower, upper);
        return pieces.iter().all(accept).then_some(pieces);
    }
    let vel = |i: usize| -> Vec<f64> {
        let h = w[i + 1].0 - w[i].0;
        w[i].1.iter().zip(&w[i + 1].1).map(|(a, b)| (b - a) / h).collect()
    };
    // 1. each corner: the widest accepted blend (on the input's timing), else a stop
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
        let need = limits.max_accel.map(|a| jump / (2.0 * a));
        let mut delta = max_delta;
        for _ in 0..=BLEND_HALVINGS {
            let piece = blend_piece(w[i].0, &w[i].1, &vin, &vout, delta);
            // the expanded coefficients grow like 1/δ: a blend so narrow that its ends no
            // longer meet the straight parts within a tenth of the continuity tolerance
            // (rounding) is not tried, and narrower ones would be worse
            if !blend_meets(&piece, &w[i].1, &vin, &vout, delta, JOIN_SHARE * CONTINUITY_TOLERANCE * diag.max(1.0)) {
                break;
            }
            if accept(&piece) {
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
    // 2. the pieces; a stop whose eased parts are rejected (or, on a static path, that the
    // speed limit cannot afford) is refused and the path assembled again
    let refuse = |corners: &mut Vec<Corner>, ends: &[usize]| {
        for &i in ends {
            corners[i] = Corner::Sharp;
        }
    };
    let out = loop {
        let stops: Vec<usize> = (1..n - 1).filter(|&i| corners[i] == Corner::Stop).collect();
        let failed = match assemble(w, &corners, &given_timing(w, &corners), &blends, workspace, &accept) {
            Assembly::Done(out) => break out,
            Assembly::Rejected if stops.is_empty() => return None,
            f => f,
        };
        if timed {
            match failed {
                Assembly::EaseRejected(ends) => refuse(&mut corners, &ends),
                _ => refuse(&mut corners, &stops),
            }
            continue;
        }
        // static: re-timed so that every piece peaks at one speed u
        let speed = |c: &[Corner]| retimed(w, c).map_or(f64::INFINITY, |(_, u)| u);
        if let Some((timing, _)) = retimed(w, &corners).filter(|(_, u)| limits.max_speed.is_none_or(|v| *u <= v)) {
            match assemble(w, &corners, &timing, &blends, workspace, &accept) {
                Assembly::Done(out) => break out,
                Assembly::EaseRejected(ends) => {
                    refuse(&mut corners, &ends);
                    continue;
                }
                Assembly::Rejected => {}
            }
        }
        // refuse the stop whose refusal lowers the re-timed speed most (the first of equals)
        let mut best: Option<(f64, usize)> = None;
        for &i in &stops {
            let mut c = corners.clone();
            c[i] = Corner::Sharp;
            let u = speed(&c);
            if best.is_none_or(|(b, _)| u < b) {
                best = Some((u, i));
            }
        }
        match best {
            Some((_, i)) => refuse(&mut corners, &[i]),
            None => refuse(&mut corners, &stops),
        }
    };
    for c in &corners[1..n - 1] {
        match c {
            Corner::Blend(_) => stats.corners_blended += 1,
            Corner::Stop => stats.corners_stopped += 1,
            Corner::Sharp => stats.corners_sharp += 1,
        }
    }
    if let Some(a) = limits.max_accel {
        stats.accel_violations += out.iter().filter(|pc| pc.degree() >= 2 && peak_accel(pc) > a).count();
    }
    Some(out)
}

/// The largest acceleration of a piece of degree ≤ 3 (every piece smoothing makes): its
/// acceleration is affine in t, so its norm is convex and largest at an end; evaluated
/// about each end in floating point (for [`SmoothStats::accel_violations`], a count, not a
/// guarantee). A piece of higher degree gets `+∞`.
pub fn peak_accel(pc: &Piece) -> f64 {
    if pc.degree() > 3 {
        return f64::INFINITY;
    }
    [pc.t0, pc.t1]
        .iter()
        .map(|&t| {
            pc.coeffs
                .iter()
                .map(|row| {
                    let a = 2.0 * taylor_shift(row, t).get(2).copied().unwrap_or(0.0);
                    a * a
                })
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::within_speed;

    /// A test checker that accepts the pieces `accepts` says yes to (and every point).
    struct Accepts<F: Fn(&Piece) -> bool + Send + Sync>(F);

    impl<F: Fn(&Piece) -> bool + Send + Sync> MotionChecker for Accepts<F> {
        fn name(&self) -> &str {
            "test"
        }
        fn sound(&self) -> bool {
            true
        }
        fn check(&self, piece: &Piece) -> Motion {
            if (self.0)(piece) {
                Motion::Accepted
            } else {
                Motion::Rejected
            }
        }
        fn check_point(&self, _x: &[f64], _t: f64) -> Motion {
            Motion::Accepted
        }
    }

    /// Rejects every parabolic blend (degree 2) that starts or ends within `radius` of
    /// `point`, and accepts every other piece: a corner there whose blend is never
    /// certified (an obstacle inside the turn), so `blend` has to stop at it.
    fn no_blend_near(point: Vec<f64>, radius: f64) -> Accepts<impl Fn(&Piece) -> bool + Send + Sync> {
        Accepts(move |piece: &Piece| {
            let near = |t: f64| dist(&piece.at(t), &point) <= radius;
            !(piece.degree() == 2 && (near(piece.t0) || near(piece.t1)))
        })
    }

    /// Relative velocity jump at a joint below which the pieces are C¹ (the coefficients
    /// are rounded floats in absolute time).
    const JUMP_TOLERANCE: f64 = 1e-9;

    /// How far above a piece's sampled peak speed `within_speed` must accept an eased part:
    /// its bound on 64 sub-intervals over-estimates the cubic eases by less than this.
    const EASE_BOUND_SLACK: f64 = 1e-3;

    /// ... and a blend, whose speed is checked exactly at its ends up to the rounding
    /// allowance: 64ε times the magnitudes of its coefficients in absolute time, about
    /// 3·10⁻¹² of its speed for the blends here (at t ≈ 10, δ = 0.05).
    const BLEND_BOUND_SLACK: f64 = 1e-10;

    /// A sampled peak speed is at most the true one: `within_speed` must reject a limit this
    /// much below it (far above the rounding of the sampled speeds, about 10⁻¹⁵).
    const BELOW_PEAK: f64 = 1e-9;

    use crate::testing::sampled_peak_speed;

    /// An L-shaped corner at (1, 0), constant speed 2 over [0, 1].
    fn corner() -> Vec<Waypoint> {
        vec![(0.0, vec![0.0, 0.0]), (0.5, vec![1.0, 0.0]), (1.0, vec![1.0, 1.0])]
    }

    fn smooth(w: &[Waypoint], limits: Limits, timed: bool, checker: &dyn MotionChecker) -> (Vec<Piece>, SmoothStats) {
        let (counter, mut stats) = (CheckCounter::default(), SmoothStats::default());
        let ws: (&[f64], &[f64]) = (&[-10.0, -10.0], &[10.0, 10.0]);
        let pieces = blend(w, ws, limits, timed, checker, &counter, &mut stats, &Termination::never()).expect("pieces");
        // contiguous, over the input's horizon exactly, positions continuous
        let (t0, tf) = (w[0].0, w[w.len() - 1].0);
        assert!(pieces[0].t0 == t0 && pieces[pieces.len() - 1].t1 == tf, "horizon: {pieces:?}");
        riskplan_scene::Trajectory::new(pieces.clone()).validate(2, (t0, tf), 20.0).expect("a valid trajectory");
        (pieces, stats)
    }

    /// Asserts that every piece keeps `v`, by `within_speed` and by sampling.
    fn assert_within(pieces: &[Piece], v: f64) {
        let peak = sampled_peak_speed(pieces);
        for pc in pieces {
            assert!(within_speed(pc, v), "a piece breaks max_speed {v} (sampled peak speed {peak}): {pc:?}");
        }
        assert!(peak <= v, "sampled peak speed {peak} > max_speed {v}");
    }

    /// A corner beside a piece of 5·10⁻⁷ of the horizon at t ≈ 1 (what a shortcut ending
    /// just short of a waypoint would leave were its end not snapped onto it): no blend
    /// fits, so the corner would be stopped at, but the eased part on that piece has
    /// coefficients of order 10¹³ in absolute time and its ends round 10⁻³ away from the
    /// segment's. It is refused and the corner stays sharp: the pieces meet as the
    /// trajectory format demands (`smooth` validates them). Without the join check the
    /// eased part would be kept and the trajectory would jump at its start.
    #[test]
    fn an_eased_part_too_short_to_meet_its_segment_is_refused() {
        let (h, l) = (5e-7, 1e-6);
        let w = vec![
            (0.0, vec![0.0, 0.0]),
            (0.5, vec![1.0, 0.0]),
            (1.0 - h, vec![1.0, 1.0 - l]),
            (1.0, vec![1.0 + l, 1.0 - l]),
        ];
        // no blend is accepted near the end: the last corner must be stopped at or left sharp
        let checker = Accepts(|pc: &Piece| !(pc.degree() == 2 && pc.t1 > 0.9));
        let (pieces, stats) = smooth(&w, Limits::default(), false, &checker);
        assert!(pieces.iter().all(|pc| pc.degree() <= 3), "{pieces:?}");
        assert_eq!(stats.corners_stopped + stats.corners_sharp + stats.corners_blended, 2, "{stats:?}");
        assert!(stats.corners_sharp >= 1, "the corner beside the short piece is left sharp: {stats:?}");
    }

    /// Shortcut ends near a waypoint are that waypoint, exactly (time and position).
    #[test]
    fn shortcut_ends_snap_onto_waypoints() {
        assert_eq!(snapped(0.0), 0.0);
        assert_eq!(snapped(SHORTCUT_SNAP_SHARE / 2.0), 0.0);
        assert_eq!(snapped(1.0 - SHORTCUT_SNAP_SHARE / 2.0), 1.0);
        assert_eq!(snapped(0.5), 0.5);
        let w = vec![(0.1, vec![0.1, 0.7]), (0.3, vec![0.3, 0.9])];
        assert_eq!(point_on(&w, 0, 1.0), w[1]);
        assert_eq!(point_on(&w, 0, 0.0), w[0]);
        assert_eq!(point_on(&w, 0, 0.5).1.len(), 2);
    }

    /// A corner whose blend is never certified is stopped at, and the eased parts on the
    /// segments' own time spans reach 4/3 of the path's speed 2. With `max_speed` 10 %
    /// above the path's speed the stop is refused (re-timing would need 4/3 of it too) and
    /// the corner stays sharp; with 2.7 the stop is kept. Every returned piece keeps the
    /// limit. (Without the limit on eased parts, the first case would return a piece of
    /// peak speed 8/3 under max_speed 2.2.)
    #[test]
    fn stopped_corner_keeps_a_tight_speed_limit() {
        let no_blend = no_blend_near(vec![1.0, 0.0], 1.0);
        let (free, stats) = smooth(&corner(), Limits::default(), false, &no_blend);
        assert_eq!(stats.corners_stopped, 1, "{stats:?}");
        let peak = sampled_peak_speed(&free);
        assert!((peak - 8.0 / 3.0).abs() < 1e-6, "eased parts peak at 4/3 of the path's speed 2: {peak}");
        let (tight, stats) = smooth(&corner(), Limits { max_speed: Some(2.2), max_accel: None }, false, &no_blend);
        assert_eq!((stats.corners_stopped, stats.corners_sharp), (0, 1), "{stats:?}");
        assert_within(&tight, 2.2);
        let (loose, stats) = smooth(&corner(), Limits { max_speed: Some(2.7), max_accel: None }, false, &no_blend);
        assert_eq!(stats.corners_stopped, 1, "{stats:?}");
        assert_within(&loose, 2.7);
        assert!(max_velocity_jump(&loose) < JUMP_TOLERANCE);
    }

    /// With moving obstacles (times attached to the points) a stop whose eased parts break
    /// the limit is refused; one they keep is kept.
    #[test]
    fn stopped_corner_in_time_keeps_the_speed_limit() {
        let no_blend = no_blend_near(vec![1.0, 0.0], 1.0);
        let (tight, stats) = smooth(&corner(), Limits { max_speed: Some(2.2), max_accel: None }, true, &no_blend);
        assert_eq!((stats.corners_stopped, stats.corners_sharp), (0, 1), "{stats:?}");
        assert_within(&tight, 2.2);
        let (loose, stats) = smooth(&corner(), Limits { max_speed: Some(2.7), max_accel: None }, true, &no_blend);
        assert_eq!(stats.corners_stopped, 1, "{stats:?}");
        assert_within(&loose, 2.7);
    }

    /// A path (0,0) → (4,0) → (4,1) → (8,1) at speed 9 whose corner at (4, 1) cannot be
    /// blended: on the segments' own time spans its eased parts peak at 12; re-timed over
    /// the same horizon every piece peaks at u = 32/3 (the blend at (4, 0) reaches 1/3 along
    /// its segments; the eased parts take 3/2 and 4/3 of their time at u), so `max_speed` 11
    /// keeps the stop, C¹, while 10.5 refuses it.
    #[test]
    fn retiming_keeps_a_stop_the_segment_timing_cannot() {
        let pts = [vec![0.0, 0.0], vec![4.0, 0.0], vec![4.0, 1.0], vec![8.0, 1.0]];
        let w = time_at_constant_speed(&pts, (0.0, 1.0));
        let no_blend = no_blend_near(vec![4.0, 1.0], 0.5);
        let (free, stats) = smooth(&w, Limits::default(), false, &no_blend);
        assert_eq!((stats.corners_blended, stats.corners_stopped), (1, 1), "{stats:?}");
        let peak = sampled_peak_speed(&free);
        assert!((peak - 12.0).abs() < 1e-5, "4/3 of the path's speed 9: {peak}");
        let (pieces, stats) = smooth(&w, Limits { max_speed: Some(11.0), max_accel: None }, false, &no_blend);
        assert_eq!((stats.corners_blended, stats.corners_stopped), (1, 1), "{stats:?}");
        assert_within(&pieces, 11.0);
        let peak = sampled_peak_speed(&pieces);
        assert!((peak - 32.0 / 3.0).abs() < 1e-5, "every piece peaks at u = 32/3: {peak}");
        assert!(max_velocity_jump(&pieces) < JUMP_TOLERANCE, "C¹: {}", max_velocity_jump(&pieces));
        let (sharp, stats) = smooth(&w, Limits { max_speed: Some(10.5), max_accel: None }, false, &no_blend);
        assert_eq!((stats.corners_blended, stats.corners_stopped, stats.corners_sharp), (1, 0, 1), "{stats:?}");
        assert_within(&sharp, 10.5);
    }

    /// Accepts every piece of degree ≥ 2 and the straight ones of at most `longest`
    /// duration: a checker whose proofs only succeed on short pieces (as a higher-moment
    /// cover's depth budget does near a contour).
    fn short_straight_only(longest: f64) -> Accepts<impl Fn(&Piece) -> bool + Send + Sync> {
        Accepts(move |piece: &Piece| piece.degree() >= 2 || piece.t1 - piece.t0 <= longest)
    }

    /// A straight part refused whole is split into equal pieces the checker accepts (the
    /// example-d1 seed-3 failure: a part beside a corner in a Cantelli ring, proven in
    /// halves), and the path stays C¹ with its corner blended; parts that no split within
    /// [`STRAIGHT_SPLITS`] levels makes short enough leave the blend undone.
    #[test]
    fn a_refused_straight_part_is_split_and_stays_c1() {
        // the corner's straight parts last 0.5 − δ with δ = 1/6 (BLEND_SHARE of 0.5)
        let (pieces, stats) = smooth(&corner(), Limits::default(), false, &short_straight_only(0.2));
        assert_eq!(stats.corners_blended, 1, "{stats:?}");
        assert_eq!(pieces.len(), 5, "two halves on each side of the blend: {pieces:?}");
        assert!(max_velocity_jump(&pieces) < JUMP_TOLERANCE, "C¹: {}", max_velocity_jump(&pieces));
        let too_short = 0.34 / (1u32 << STRAIGHT_SPLITS) as f64 * 0.9;
        let (counter, mut stats) = (CheckCounter::default(), SmoothStats::default());
        let ws: (&[f64], &[f64]) = (&[-10.0, -10.0], &[10.0, 10.0]);
        let checker = short_straight_only(too_short);
        assert!(blend(&corner(), ws, Limits::default(), false, &checker, &counter, &mut stats, &Termination::never())
            .is_none());
    }

    /// `within_speed` on blends and eased parts far from t = 0 (on [10, 10.3], where the
    /// expansion in absolute time cancels by three orders of magnitude): never below the
    /// sampled peak, and within [`EASE_BOUND_SLACK`] / [`BLEND_BOUND_SLACK`] above it. The
    /// eases peak at their table's multiple of their mean speed.
    #[test]
    fn within_speed_is_tight_on_blends_and_eases() {
        let (a, b) = ([1.0, 2.0], [2.0, 2.5]);
        let mean = dist(&a, &b) / 0.3;
        for &(s0, s1, ratio) in &EASE_PROFILES {
            let pc = eased_segment(&a, &b, 10.0, 10.3, s0, s1);
            let peak = sampled_peak_speed(std::slice::from_ref(&pc));
            assert!((peak / mean - ratio).abs() < 1e-6, "({s0}, {s1}): peak {} × mean", peak / mean);
            assert!(within_speed(&pc, peak * (1.0 + EASE_BOUND_SLACK)), "({s0}, {s1}) peak {peak}");
            assert!(!within_speed(&pc, peak * (1.0 - BELOW_PEAK)), "({s0}, {s1}) peak {peak}");
        }
        for (vin, vout) in [([3.0, 0.0], [0.0, 3.0]), ([3.0, 1.0], [-2.0, 0.5]), ([1.0, 1.0], [4.0, -1.0])] {
            let pc = blend_piece(10.15, &[1.0, 1.0], &vin, &vout, 0.05);
            let peak = sampled_peak_speed(std::slice::from_ref(&pc));
            assert!(within_speed(&pc, peak * (1.0 + BLEND_BOUND_SLACK)), "{vin:?} → {vout:?}: peak {peak}");
            assert!(!within_speed(&pc, peak * (1.0 - BELOW_PEAK)), "{vin:?} → {vout:?}: peak {peak}");
        }
    }

    /// `accel_violations` counts every returned blend and eased part above `max_accel`: the
    /// corner's widest blend (δ = 1/6) accelerates at 2√2/(2δ) ≈ 8.49, an eased part
    /// (1, 0) over length 1 in time 1/2 at up to 4/(1/2)² = 16.
    #[test]
    fn accel_violations_count_blends_and_eases_over_the_target() {
        let anywhere = no_blend_near(vec![100.0, 100.0], 1.0);
        let accel = |a: f64| Limits { max_speed: None, max_accel: Some(a) };
        let (pieces, stats) = smooth(&corner(), accel(0.1), false, &anywhere);
        assert_eq!((stats.corners_blended, stats.accel_violations), (1, 1), "{stats:?}");
        assert!((peak_accel(&pieces[1]) - 6.0 * 2f64.sqrt()).abs() < 1e-9, "{}", peak_accel(&pieces[1]));
        let (_, stats) = smooth(&corner(), accel(100.0), false, &anywhere);
        assert_eq!((stats.corners_blended, stats.accel_violations), (1, 0), "{stats:?}");
        let no_blend = no_blend_near(vec![1.0, 0.0], 1.0);
        let (pieces, stats) = smooth(&corner(), accel(10.0), false, &no_blend);
        assert_eq!((stats.corners_stopped, stats.accel_violations), (1, 2), "{stats:?}");
        assert!(pieces.iter().all(|pc| (peak_accel(pc) - 16.0).abs() < 1e-9), "{pieces:?}");
    }

    /// Accepts a straight piece unless it passes within 1 of the origin; counts its work as
    /// ten per check (as a certifier counts the obstacles it decides).
    struct DiskAtOrigin {
        checks: std::sync::atomic::AtomicU64,
    }

    impl MotionChecker for DiskAtOrigin {
        fn name(&self) -> &str {
            "disk-at-origin"
        }
        fn sound(&self) -> bool {
            true
        }
        fn check(&self, piece: &Piece) -> Motion {
            self.checks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let (a, b) = (piece.at(piece.t0), piece.at(piece.t1));
            let d: Vec<f64> = b.iter().zip(&a).map(|(y, x)| y - x).collect();
            let dd: f64 = d.iter().map(|v| v * v).sum();
            let s =
                if dd > 0.0 { (-a.iter().zip(&d).map(|(x, v)| x * v).sum::<f64>() / dd).clamp(0.0, 1.0) } else { 0.0 };
            let closest: f64 = a.iter().zip(&d).map(|(x, v)| (x + s * v).powi(2)).sum::<f64>().sqrt();
            if closest < 1.0 {
                Motion::Rejected
            } else {
                Motion::Accepted
            }
        }
        fn check_point(&self, _x: &[f64], _t: f64) -> Motion {
            Motion::Accepted
        }
        fn work(&self) -> Option<u64> {
            Some(10 * self.checks.load(std::sync::atomic::Ordering::Relaxed))
        }
    }

    /// The work budget binds the random shortcuts, deterministically: with no work left only
    /// the vertex reduction runs (at most one check per waypoint), with a budget the
    /// attempts stop within one attempt (three checks) of it, and unlimited they run on; the
    /// same seed and budget give the same path.
    #[test]
    fn the_work_budget_bounds_the_random_shortcuts() {
        use rand::SeedableRng;
        // a half circle of radius 1.5 around the disk, in 24 steps
        let path: Vec<Waypoint> = (0..=24)
            .map(|k| {
                let a = std::f64::consts::PI * (1.0 - k as f64 / 24.0);
                (k as f64 / 24.0, vec![1.5 * a.cos(), 1.5 * a.sin()])
            })
            .collect();
        let run = |budget: &dyn Fn(&CheckCounter, &DiskAtOrigin) -> WorkBudget| {
            let checker = DiskAtOrigin { checks: Default::default() };
            let counter = CheckCounter::default();
            let b = budget(&counter, &checker);
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let out = shortcut(
                path.clone(),
                (0.0, 1.0),
                true,
                None,
                &checker,
                &counter,
                &mut rng,
                &Termination::never(),
                b,
                None,
                &mut SmoothStats::default(),
            );
            (out, counter.totals().0)
        };
        let (_, none) = run(&|c, k| WorkBudget::until(c.work(k)));
        assert!(none <= 2 * path.len() as u64, "{none} checks with no work left");
        let (a, some) = run(&|c, k| WorkBudget::until(c.work(k) + 10 * (2 * path.len() as u64 + 8)));
        // the budget (which the first reduction shares), one attempt's three checks past it,
        // and the last reduction's check per waypoint left
        assert!(some <= 2 * path.len() as u64 + 8 + 3 + a.len() as u64, "{some} checks, {} waypoints left", a.len());
        let (b, again) = run(&|c, k| WorkBudget::until(c.work(k) + 10 * (2 * path.len() as u64 + 8)));
        assert_eq!((a, some), (b, again), "not reproducible");
        let (_, all) = run(&|_, _| WorkBudget::UNLIMITED);
        assert!(all > some, "unlimited: {all} checks, budgeted {some}");
    }
}
