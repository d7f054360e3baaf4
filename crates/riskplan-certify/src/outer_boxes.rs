//! Proven outer boxes of an obstacle's unsafe set (docs/design.md §5.10): the
//! conservative pre-filter of the motion checker.
//!
//! For an obstacle and a risk level Δ, the unsafe set at time t is where either
//! constraint of eq. (15) fails, `g1 = E[P]² − (1−Δ)·E[P²] ≤ 0` or `g2 = −E[P] ≤ 0`.
//! [`unsafe_cover`] finds a box `B` inside a region `R` (workspace × time slab) such
//! that **every point of `R` outside `B` satisfies `g1 > 0` and `g2 > 0`, proven**:
//! `R` is split into cells (a k-d tree, level by level); a cell is discarded only when
//! an outward-rounded lower bound of both constraints over the whole cell is positive
//! (mean-value form: `g(c) + Σ ∂ᵢg(cell)·(cellᵢ − cᵢ)`, and the naive interval
//! extension, the larger of the two); `B` is the hull of the cells left. Stopping at
//! any point is sound (the remaining cells always cover the unproven part), so the
//! search stops as soon as the cells are fine relative to the hull, or at a budget.
//!
//! A straight (or any) piece inside the workspace whose bounding box misses `B` during
//! the slab is therefore safe for this obstacle without restricting its polynomials to
//! the piece. The polynomials are exact symbolic constraints (the cancellation in
//! `g1` is done in rationals), compiled in centred variables.

use crate::compiled::{derivative, Compiled};
use num_rational::BigRational;
use riskplan_math::contour::RiskContour;
use riskplan_math::poly::shift;
use riskplan_math::poly::{Interval, QPoly};

/// Cells evaluated per cover before giving up and returning the hull of what is left
/// (sound, only looser). A disk in a workspace 200 times its size needs about 2 000.
pub const MAX_COVER_CELLS: usize = 4_000;

/// The search stops once every remaining cell is at most `1/COVER_RESOLUTION` of the
/// hull of the remaining cells in each split dimension: the box is then within that
/// fraction of the tightest box the cells could give.
pub const COVER_RESOLUTION: f64 = 8.0;

/// Largest number of k-d levels (each halves one dimension).
pub const MAX_COVER_LEVELS: usize = 64;

/// A constraint compiled for lower bounds over boxes: the polynomial and its gradient.
#[derive(Clone, Debug)]
pub struct BoxBound {
    g: Compiled,
    grad: Vec<Option<Compiled>>,
}

impl BoxBound {
    /// Compiles `p` (in `nvars` variables) around `center`.
    pub fn new(p: &QPoly, center: &[f64]) -> Self {
        let nv = center.len();
        let ps = shift(p, center);
        let grad = (0..nv)
            .map(|v| {
                let d = derivative(&ps, v);
                (!d.is_zero()).then(|| Compiled::new(&d, nv))
            })
            .collect();
        BoxBound { g: Compiled::new(&ps, nv), grad }
    }

    /// An enclosure of the constraint at the centred point `x`.
    pub fn value_at(&self, x: &[f64]) -> Interval {
        let point: Vec<Interval> = x.iter().map(|&m| Interval::point(m)).collect();
        self.g.eval_box(&point)
    }

    /// A proven lower bound of the constraint over the centred box `cell`, and each
    /// variable's smear `|∂ᵢg(cell)|·width(cellᵢ)` (how much of the bound's looseness
    /// that variable causes: the dimension to split).
    pub fn lower_bound(&self, cell: &[Interval], mid: &[f64], smear: &mut [f64]) -> f64 {
        let point: Vec<Interval> = mid.iter().map(|&m| Interval::point(m)).collect();
        let mut mv = self.g.eval_box(&point);
        for (v, d) in self.grad.iter().enumerate() {
            if let Some(d) = d {
                let dv = d.eval_box(cell);
                smear[v] = dv.lo.abs().max(dv.hi.abs()) * (cell[v].hi - cell[v].lo);
                mv = mv + dv * (cell[v] - Interval::point(mid[v]));
            } else {
                smear[v] = 0.0;
            }
        }
        let naive = self.g.eval_box(cell);
        if mv.lo.is_nan() {
            return naive.lo;
        }
        mv.lo.max(naive.lo)
    }
}

/// An obstacle's two constraints at one Δ, ready for box bounds.
#[derive(Clone, Debug)]
pub struct ConstraintBounds {
    /// The centre (space, then time) of the compiled variables.
    pub center: Vec<f64>,
    cantelli: BoxBound,
    mean: BoxBound,
}

impl ConstraintBounds {
    /// `g1` and `g2` of `contour` at `delta`, centred at `center`.
    pub fn new(contour: &RiskContour, delta: &BigRational, center: &[f64]) -> Self {
        let c = contour.constraints(delta);
        ConstraintBounds {
            center: center.to_vec(),
            cantelli: BoxBound::new(&c.cantelli, center),
            mean: BoxBound::new(&c.mean, center),
        }
    }

    /// Whether both constraints are proven positive on the (absolute) box `cell`:
    /// `None` when proven, else the variable whose width loosens the failing bound most
    /// (among `split`; the widest relative to `root_w` when no smear is known).
    pub fn assess(&self, cell: &[(f64, f64)], split: &[bool], root_w: &[f64]) -> Option<usize> {
        let c: Vec<Interval> =
            cell.iter().zip(&self.center).map(|(&(lo, hi), &m)| Interval::new(lo, hi) - Interval::point(m)).collect();
        let mid: Vec<f64> = c.iter().map(|i| i.mid()).collect();
        let mut smear = vec![0.0; c.len()];
        let finite = c.iter().all(|i| i.lo.is_finite() && i.hi.is_finite());
        let mut unsafe_mid = false;
        if finite {
            let mut safe = true;
            for g in [&self.mean, &self.cantelli] {
                if g.lower_bound(&c, &mid, &mut smear) <= 0.0 {
                    safe = false;
                    // a cell whose centre is unsafe cannot be proven: split it evenly
                    unsafe_mid = g.value_at(&mid).hi <= 0.0;
                    break;
                }
            }
            if safe {
                return None;
            }
        }
        let cands = || (0..c.len()).filter(|&v| split[v] && root_w[v] > 0.0);
        let by_smear =
            cands().filter(|&v| !unsafe_mid && smear[v] > 0.0).max_by(|&a, &b| smear[a].total_cmp(&smear[b]));
        Some(by_smear.or_else(|| {
            cands().max_by(|&a, &b| {
                ((cell[a].1 - cell[a].0) / root_w[a]).total_cmp(&((cell[b].1 - cell[b].0) / root_w[b]))
            })
        })?)
        .or(Some(usize::MAX))
    }
}

/// The result of [`unsafe_cover`].
#[derive(Clone, Debug, PartialEq)]
pub enum Cover {
    /// Every point of the region is proven safe.
    Empty,
    /// Every point of the region outside this box is proven safe.
    Box(Vec<(f64, f64)>),
}

/// Statistics of one cover search.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CoverStats {
    /// Cells evaluated.
    pub cells: usize,
    /// k-d levels.
    pub levels: usize,
}

fn hull(cells: &[Vec<(f64, f64)>]) -> Vec<(f64, f64)> {
    let mut h = cells[0].clone();
    for c in &cells[1..] {
        for (a, b) in h.iter_mut().zip(c) {
            a.0 = a.0.min(b.0);
            a.1 = a.1.max(b.1);
        }
    }
    h
}

/// A proven outer box of the unsafe set of `bounds` within `region` (absolute
/// coordinates, one `(lo, hi)` per variable: space, then time). Only the dimensions
/// with `split[v]` are subdivided (time is not split for a static obstacle).
///
/// The cells not (yet) proven safe always cover the unsafe part of the region; the
/// result is their hull. Only cells on the hull's spatial faces decide it, so only
/// those are refined (the far field is proven in large cells, and cells inside the
/// hull are left as they are while they stay inside). The search ends when every
/// face cell is at most `1/COVER_RESOLUTION` of the hull, or at the budget.
pub fn unsafe_cover(bounds: &ConstraintBounds, region: &[(f64, f64)], split: &[bool]) -> (Cover, CoverStats) {
    let mut stats = CoverStats::default();
    let root_w: Vec<f64> = region.iter().map(|(lo, hi)| hi - lo).collect();
    let spatial: Vec<usize> = (0..region.len().saturating_sub(1)).filter(|&v| split[v]).collect();
    stats.cells += 1;
    let Some(v0) = bounds.assess(region, split, &root_w) else { return (Cover::Empty, stats) };
    // unproven cells, each with the dimension to split it along
    let mut cells: Vec<(Vec<(f64, f64)>, usize)> = vec![(region.to_vec(), v0)];
    loop {
        let boxes: Vec<Vec<(f64, f64)>> = cells.iter().map(|(c, _)| c.clone()).collect();
        let h = hull(&boxes);
        let on_face = |c: &[(f64, f64)]| spatial.iter().any(|&v| c[v].0 <= h[v].0 || c[v].1 >= h[v].1);
        let fine = |c: &[(f64, f64)]| spatial.iter().all(|&v| (c[v].1 - c[v].0) * COVER_RESOLUTION <= h[v].1 - h[v].0);
        let (face, inner): (Vec<_>, Vec<_>) =
            cells.into_iter().partition(|(c, v)| *v != usize::MAX && on_face(c) && !fine(c));
        if face.is_empty() || stats.cells >= MAX_COVER_CELLS || stats.levels >= MAX_COVER_LEVELS * 8 {
            return (Cover::Box(h), stats);
        }
        stats.levels += 1;
        cells = inner;
        let mut pending = face.into_iter();
        for (c, v) in pending.by_ref() {
            let m = if v < c.len() { 0.5 * (c[v].0 + c[v].1) } else { f64::NAN };
            if !(v < c.len() && m > c[v].0 && m < c[v].1) {
                // nothing left to split: the cell stays as it is
                cells.push((c, usize::MAX));
                continue;
            }
            let (mut a, mut b) = (c.clone(), c);
            a[v].1 = m;
            b[v].0 = m;
            for child in [a, b] {
                stats.cells += 1;
                if let Some(w) = bounds.assess(&child, split, &root_w) {
                    cells.push((child, w));
                }
            }
            if stats.cells >= MAX_COVER_CELLS {
                break;
            }
        }
        // sound at the budget: the face cells not yet split stay in the cover as they are
        cells.extend(pending);
        if cells.is_empty() {
            return (Cover::Empty, stats);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use riskplan_math::contour::Layout;
    use riskplan_math::poly::{parse, VarTable};

    fn contour(text: &str) -> RiskContour {
        let vars = VarTable::new(["x1", "x2", "t", "w"].map(String::from));
        let p = parse(text, &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).unwrap();
        // w uniform on [0.3, 0.4]
        let moments = |k: u32| -> BigRational {
            let (a, b) = (BigRational::new(3.into(), 10.into()), BigRational::new(4.into(), 10.into()));
            let pw = |x: &BigRational| num_traits::pow(x.clone(), k as usize + 1);
            (pw(&b) - pw(&a)) / (BigRational::from_integer((k + 1).into()) * (b - a))
        };
        RiskContour::new(Layout { dim: 2 }, &p, &|_, k| Some(moments(k)), &|v| vars.name(v)).unwrap()
    }

    /// Points outside the cover are safe, checked exactly at a dense grid (an oracle
    /// that shares no code with the cover: exact rational evaluation of the contour),
    /// and the cover is not the whole region (it is useful).
    #[test]
    fn points_outside_the_cover_are_safe() {
        for (text, region, split) in [
            ("w^2 - (x1 - 120)^2 - (x2 + 40)^2", vec![(100.0, 140.0), (-60.0, -20.0), (5.0, 5.0)], [true, true, false]),
            ("w^2 - (x1 - 0.5*t)^2 - x2^2", vec![(-2.0, 2.0), (-2.0, 2.0), (0.25, 0.5)], [true, true, true]),
            ("w^2*(1 + x1) - x1^4 - x2^2", vec![(-2.0, 2.0), (-2.0, 2.0), (0.0, 0.0)], [true, true, false]),
        ] {
            let c = contour(text);
            let delta = BigRational::new(1.into(), 20.into());
            let center: Vec<f64> = region.iter().map(|(a, b)| 0.5 * (a + b)).collect();
            let b = ConstraintBounds::new(&c, &delta, &center);
            let (cover, stats) = unsafe_cover(&b, &region, &split);
            let Cover::Box(bx) = cover else { panic!("{text}: the obstacle is in the region") };
            let area = |r: &[(f64, f64)]| (r[0].1 - r[0].0) * (r[1].1 - r[1].0);
            eprintln!("{text}: {bx:?} ({stats:?})");
            assert!(area(&bx) < 0.25 * area(&region), "{text}: {bx:?} ({stats:?})");
            let cons = c.constraints(&delta);
            let q = |v: f64| BigRational::from_float(v).unwrap();
            let n = 60;
            for i in 0..=n {
                for j in 0..=n {
                    for k in 0..=4 {
                        let x = region[0].0 + (region[0].1 - region[0].0) * i as f64 / n as f64;
                        let y = region[1].0 + (region[1].1 - region[1].0) * j as f64 / n as f64;
                        let t = region[2].0 + (region[2].1 - region[2].0) * k as f64 / 4.0;
                        let inside = [x, y, t].iter().zip(&bx).all(|(v, (lo, hi))| lo <= v && v <= hi);
                        if inside {
                            continue;
                        }
                        let p = [q(x), q(y), q(t), q(0.0)];
                        let (g1, g2) = (cons.cantelli.eval(&p), cons.mean.eval(&p));
                        assert!(
                            g1 > BigRational::from_integer(0.into()) && g2 > BigRational::from_integer(0.into()),
                            "{text}: ({x}, {y}, {t}) outside {bx:?} is unsafe"
                        );
                    }
                }
            }
        }
    }

    /// A region far from the obstacle is proven safe as a whole.
    #[test]
    fn a_far_region_is_empty() {
        let c = contour("w^2 - (x1 - 1)^2 - x2^2");
        let delta = BigRational::new(1.into(), 10.into());
        let region = vec![(10.0, 20.0), (-5.0, 5.0), (0.0, 0.0)];
        let b = ConstraintBounds::new(&c, &delta, &[15.0, 0.0, 0.0]);
        assert_eq!(unsafe_cover(&b, &region, &[true, true, false]).0, Cover::Empty);
    }
}
