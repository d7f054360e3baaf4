//! Proven covers of one obstacle (docs/design.md §5.10): per time slab, boxes outside which the obstacle's Δ-unsafe set never is, for polynomial obstacles and pedestrians, and an obstacle's centre.

use super::*;

/// One time slab of an obstacle and its proven cover.
#[derive(Clone, Debug)]
pub(super) struct Slab {
    pub(super) t: (f64, f64),
    /// Spatial part of the cover; `None`: proven safe everywhere in the slab.
    pub(super) cover: Option<Vec<(f64, f64)>>,
}

/// An obstacle's covers: per slab (static obstacles: one slab for all time), or none
/// (always checked). A moving obstacle's slabs are equal in length, from `slabs[0].t.0`,
/// so that the slabs a piece spans are found by division.
#[derive(Clone, Debug)]
pub(super) struct ObstacleCovers {
    /// Shared: the next revision of the scene takes over an unchanged obstacle's covers
    /// without copying them, and dropping an old index frees only what changed.
    pub(super) slabs: Option<Arc<Vec<Slab>>>,
    /// Whether the slabs cover all time (static obstacle).
    pub(super) timeless: bool,
}

/// Most time slabs of a pedestrian's covers over the horizon (docs/design.md §3.11):
/// its slabs are as long as it takes to walk its own reach (so that a slab's box is a
/// few times the disk), at least [`TIME_SLABS`], at most this many.
pub const PEDESTRIAN_MAX_SLABS: usize = 4096;

/// A pedestrian's covers from its tail bound at threshold `kappa`: per slab, the box of
/// [`GaussianDisk::slab_box`](riskplan_math::contour::tail::GaussianDisk::slab_box) — microseconds,
/// no search.
fn pedestrian_covers(p: &riskplan_scene::Pedestrian, kappa: f64, horizon: (f64, f64)) -> ObstacleCovers {
    let d = &p.disk;
    let (h0, h1) = horizon;
    let speed = d.velocity.iter().map(|v| v.lo.abs().max(v.hi.abs())).fold(0.0, f64::max);
    let len = h1 - h0;
    let wanted = if speed > 0.0 && d.reach > 0.0 { (len * speed / d.reach).ceil() } else { TIME_SLABS as f64 };
    let n = if wanted.is_finite() {
        (wanted as usize).clamp(TIME_SLABS, PEDESTRIAN_MAX_SLABS)
    } else {
        PEDESTRIAN_MAX_SLABS
    };
    let slabs = (0..n)
        .map(|k| {
            let a = if k == 0 { h0 } else { h0 + len * k as f64 / n as f64 };
            let b = if k + 1 == n { h1 } else { h0 + len * (k + 1) as f64 / n as f64 };
            let cover = d.slab_box(a, b, kappa);
            let finite = cover.iter().all(|c| c.0.is_finite() && c.1.is_finite());
            // a box that is not finite covers everything
            let cover = if finite { cover } else { vec![(f64::NEG_INFINITY, f64::INFINITY); d.dim()] };
            Slab { t: (a, b), cover: Some(cover) }
        })
        .collect();
    ObstacleCovers { slabs: Some(Arc::new(slabs)), timeless: false }
}

/// Obstacle `i`'s covers at risk level `delta` and the cells its search evaluated:
/// a pedestrian's from its tail bound (§3.11), a static obstacle's one cover for all
/// time, a moving obstacle's per time slab ([`TIME_SLABS`], `stop` asked between
/// slabs; cut short, no slabs: always checked).
pub(super) fn obstacle_covers(
    scene: &Scene,
    i: usize,
    delta: &num_rational::BigRational,
    stop: &dyn Fn() -> bool,
) -> (ObstacleCovers, usize) {
    let o = &scene.obstacles[i];
    let ws = &scene.workspace;
    let (h0, h1) = scene.horizon;
    if let Some(p) = &o.pedestrian {
        return match tail_kappa(p.disk.dim(), delta) {
            Some(k) => (pedestrian_covers(p, k, scene.horizon), 0),
            None => (ObstacleCovers { slabs: None, timeless: false }, 0),
        };
    }
    let center = scene.center();
    let dynamic = o.is_dynamic();
    let mut split: Vec<bool> = vec![true; scene.dim];
    split.push(dynamic);
    let slab_times: Vec<(f64, f64)> = if dynamic {
        (0..TIME_SLABS)
            .map(|k| {
                let a = if k == 0 { h0 } else { h0 + (h1 - h0) * k as f64 / TIME_SLABS as f64 };
                let b = if k + 1 == TIME_SLABS { h1 } else { h0 + (h1 - h0) * (k + 1) as f64 / TIME_SLABS as f64 };
                (a, b)
            })
            .collect()
    } else {
        vec![(center[scene.dim], center[scene.dim])]
    };
    let mut slabs = Vec::with_capacity(slab_times.len());
    let mut cells = 0;
    for t in slab_times {
        // a moving obstacle's slabs are the largest step between two questions
        if dynamic && stop() {
            return (ObstacleCovers { slabs: None, timeless: false }, cells);
        }
        let mut region: Vec<(f64, f64)> = ws.lower.iter().copied().zip(ws.upper.iter().copied()).collect();
        region.push(t);
        // centre the bounds near the obstacle: interval bounds of a polynomial expanded
        // around a far point lose to cancellation
        let c = obstacle_center(&o.contour, &region);
        let bounds = ConstraintBounds::new(&o.contour, delta, &c);
        let (cover, st) = unsafe_cover(&bounds, &region, &split);
        cells += st.cells;
        let cover = match cover {
            Cover::Empty => None,
            Cover::Box(mut b) => {
                b.truncate(scene.dim);
                Some(b)
            }
        };
        slabs.push(Slab { t, cover });
    }
    (ObstacleCovers { slabs: Some(Arc::new(slabs)), timeless: !dynamic }, cells)
}

/// Points per dimension of the grid on which [`obstacle_center`] looks for the largest
/// E\[P\] (a centre for the bounds, not a decision: any point works, a near one is better).
pub const CENTER_GRID: usize = 16;

/// A point of `region` (space, then a time interval) near the obstacle: the grid point
/// of largest E\[P\] at the middle time, in floats.
pub fn obstacle_center(contour: &riskplan_math::contour::RiskContour, region: &[(f64, f64)]) -> Vec<f64> {
    let dim = region.len() - 1;
    let t = 0.5 * region[dim].0 + 0.5 * region[dim].1;
    let mut best = (f64::NEG_INFINITY, region.iter().map(|(a, b)| 0.5 * a + 0.5 * b).collect::<Vec<f64>>());
    let n = CENTER_GRID;
    let total = n.pow(dim as u32);
    let mut x = vec![0.0; dim + 1];
    x[dim] = t;
    for k in 0..total {
        let mut r = k;
        for (d, xd) in x.iter_mut().enumerate().take(dim) {
            let i = r % n;
            r /= n;
            *xd = region[d].0 + (region[d].1 - region[d].0) * (i as f64 + 0.5) / n as f64;
        }
        let (m, _) = contour.moments_f64(&x);
        if m > best.0 {
            best = (m, x.clone());
        }
    }
    best.1
}

/// Most evaluations of E\[P\] [`refine_center`] spends on one obstacle (about 40 halvings
/// of its step over 2·dim directions: the step shrinks from a grid cell to ~10⁻¹² of it).
pub const CENTER_REFINE_EVALS: usize = 400;

/// [`obstacle_center`] refined by a compass search on E\[P\] at the point's time, inside
/// `region`: from `start`, a step of half a grid cell per axis is tried both ways, taken
/// when E\[P\] grows, halved when no direction helps, within [`CENTER_REFINE_EVALS`]. The
/// grid point may lie half a cell (a sixteenth of the workspace) from the obstacle; the
/// whole-path partition writes P about this point, and its interval ranges widen with the
/// distance from it (docs/design.md §5.14). Any point is sound; a near one is tighter.
pub fn refine_center(contour: &riskplan_math::contour::RiskContour, start: &[f64], region: &[(f64, f64)]) -> Vec<f64> {
    let dim = region.len() - 1;
    let mut x = start.to_vec();
    let value = |x: &[f64]| {
        let m = contour.moments_f64(x).0;
        if m.is_nan() {
            f64::NEG_INFINITY
        } else {
            m
        }
    };
    let mut best = value(&x);
    let mut step: Vec<f64> = (0..dim).map(|d| 0.5 * (region[d].1 - region[d].0) / CENTER_GRID as f64).collect();
    let mut evals = 1;
    while evals + 2 * dim <= CENTER_REFINE_EVALS {
        let mut moved = false;
        for d in 0..dim {
            for sign in [1.0, -1.0] {
                let mut y = x.clone();
                y[d] = (x[d] + sign * step[d]).clamp(region[d].0, region[d].1);
                let v = value(&y);
                evals += 1;
                if v > best {
                    (best, x, moved) = (v, y, true);
                    break;
                }
            }
        }
        if !moved {
            step.iter_mut().for_each(|s| *s *= 0.5);
            if step.iter().zip(region).all(|(s, r)| *s <= 1e-12 * (r.1 - r.0)) {
                break;
            }
        }
    }
    x
}
