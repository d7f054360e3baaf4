//! An obstacle's reach (`Reach`): proven shells outside which it never is, and a grid over the reaches of a scene (`ReachGrid`), so that a partition examines only the parts a reach meets.

use super::*;
use std::collections::HashMap;

/// Shells of a [`Reach`]'s slab test: a slab from the region's edge to near the obstacle
/// is tested as its pieces between the cuts ±2^k of the frame (the largest k covering the
/// region, and this many below it). In one interval evaluation over a long slab a term
/// like 2·z·d (z the coordinate, d an uncertain offset) takes its far end's size while
/// −z² takes its near end's: on 512 disks the reach boxes came out four times wider than
/// the disks, and a plan passed through a hundred of them instead of a dozen. A shell
/// spans a factor of 2 in |z|, so that loss is bounded. (Any union of clear slabs is
/// clear; the cuts only choose which.)
pub const REACH_SHELLS: u32 = 24;

/// Passes of a [`Reach`]'s sides: each pass tests its slabs over the box the last pass
/// left on the other axes (the points outside that box are clear already), not over the
/// whole region — on the other axes too, a long range loses the dependency of P's terms
/// (a disk's uncertain offset along x1 widened its box along x2 from 0.5 to 1.1 in a
/// region of ±5). The passes end early when a pass changes nothing.
pub const REACH_PASSES: usize = 3;

/// Bisection steps per side of a [`Reach`] box: its sides are found within 2^−16 of the
/// region's width (a looser side only clears less; the steps are paid once per obstacle
/// and scene).
pub const REACH_STEPS: u32 = 16;

/// Where in a region (the workspace × the horizon) an obstacle may be met for some ω of
/// its parameters' ranges, as a box: every point of the region outside the box lies in a
/// slab of the region (all of it but one side cut short) on which [`FoldedPoly::upper`]
/// is below 0 — P < 0 there for every ω of the ranges. The screen's first test
/// ([`cells_path_risk_in`]): a stretch of the trajectory inside the region and outside
/// the box misses the obstacle, at a few comparisons instead of P's interval evaluation
/// (on 512 disks, most of the whole-path bound's time went to evaluating far obstacles).
/// Built once per obstacle and scene ([`crate::checker::SceneKernel`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Reach {
    /// The region, in the scene's coordinates (time last).
    pub(super) region: Vec<(f64, f64)>,
    /// `[A_v, B_v]` per coordinate, rounded outward: a point of the region with
    /// `x_v < A_v` or `x_v > B_v` is clear. `None`: every point of the region is.
    pub(super) sides: Option<Vec<(f64, f64)>>,
    /// The laws' probability outside their ranges ([`FoldedPoly::outside`]): the bound of
    /// a trajectory the reach clears whole.
    pub(super) outside: f64,
}

impl Reach {
    /// The reach of the obstacle whose P is `folded` in `frame`, in `region` (a box of
    /// the scene's coordinates, time last; `None` for a region of another dimension or
    /// not finite). Each side by bisection (`REACH_STEPS`); interval evaluation is
    /// inclusion-monotone, so a slab inside a clear one is clear.
    pub fn new(folded: &FoldedPoly, frame: &Frame, region: &[(f64, f64)]) -> Option<Reach> {
        let n = frame.center.len();
        if region.len() != n
            || frame.exponents.len() != n
            || frame.exponents.iter().any(|e| e.abs() > Frame::MAX_EXPONENT)
            || region.iter().any(|(lo, hi)| !(lo.is_finite() && hi.is_finite() && lo <= hi))
        {
            return None;
        }
        let to_frame =
            |v: usize, x: Interval| (x - Interval::point(frame.center[v])) * Interval::point(frame.inv_scale(v));
        let z: Vec<Interval> =
            region.iter().enumerate().map(|(v, &(lo, hi))| to_frame(v, Interval::new(lo, hi))).collect();
        let cleared = Some(Reach { region: region.to_vec(), sides: None, outside: folded.outside });
        if folded.upper(&z) < 0.0 {
            return cleared;
        }
        let search = SideSearch { folded, cuts: shell_cuts(&z), z: &z };
        // the box of the frame outside which every point of the region is clear: the
        // region at first, then each pass's sides (see [`REACH_PASSES`])
        let mut zbox = z.clone();
        for _ in 0..REACH_PASSES {
            // (`None`: every point is beyond a clear side)
            let Some(next) = search.pass(&zbox) else { return cleared };
            if next == zbox {
                break;
            }
            zbox = next;
        }
        // back in the scene's coordinates, rounded outward: x = c + z·2^e (a side still at
        // the region's enclosure is none)
        let sides = (0..n)
            .map(|v| {
                let scale = Interval::point(crate::compiled::pow2(frame.exponents[v]));
                let back = |e: f64| Interval::point(e) * scale + Interval::point(frame.center[v]);
                let a = if zbox[v].lo > z[v].lo { back(zbox[v].lo).lo } else { f64::NEG_INFINITY };
                let b = if zbox[v].hi < z[v].hi { back(zbox[v].hi).hi } else { f64::INFINITY };
                (a, b)
            })
            .collect();
        Some(Reach { region: region.to_vec(), sides: Some(sides), outside: folded.outside })
    }

    /// Whether every point of the box `bx` (scene coordinates, time last) is clear: inside
    /// the region, and beyond a side of the reach (false for NaN).
    pub fn clears(&self, bx: &[Interval]) -> bool {
        if bx.len() != self.region.len() || !bx.iter().zip(&self.region).all(|(x, &(lo, hi))| x.lo >= lo && x.hi <= hi)
        {
            return false;
        }
        match &self.sides {
            None => true,
            Some(sides) => bx.iter().zip(sides).any(|(x, &(a, b))| x.hi < a || x.lo > b),
        }
    }
}

/// The cuts ±2^k of a reach's shells (exact in the frame): [`REACH_SHELLS`] of them each
/// side below the farthest point of the region `z`.
fn shell_cuts(z: &[Interval]) -> Vec<f64> {
    let far = z.iter().map(|zv| zv.lo.abs().max(zv.hi.abs())).fold(0.0f64, f64::max);
    if !(far > 0.0 && far.is_finite()) {
        return Vec::new();
    }
    let top = (far.log2().ceil() as i32).clamp(-1000, 1000);
    let ks = (top - REACH_SHELLS as i32).max(-1000)..=top;
    let mut c: Vec<f64> = ks.clone().rev().map(|k| -(k as f64).exp2()).collect();
    c.extend(ks.map(|k| (k as f64).exp2()));
    c
}

/// The bisection of a reach's sides (docs/design.md §5.14): in the frame, over the
/// region `z`, with P folded over the laws' ranges.
struct SideSearch<'a> {
    folded: &'a FoldedPoly,
    cuts: Vec<f64>,
    z: &'a [Interval],
}

impl SideSearch<'_> {
    /// Whether the slab of `zbox` with side `v` replaced by `side` is clear (P < 0 there
    /// for every ω of the ranges).
    fn clear_one(&self, zbox: &[Interval], v: usize, side: Interval) -> bool {
        let mut bx = zbox.to_vec();
        bx[v] = side;
        self.folded.upper(&bx) < 0.0
    }

    /// Whether the slab is clear shell by shell: the cuts strictly inside it split it, the
    /// pieces between two cuts are shells, and each whole shell's answer is kept in
    /// `known` within a pass (the bisection asks the same ones again).
    fn clear(&self, zbox: &[Interval], known: &mut HashMap<(usize, usize), bool>, v: usize, side: Interval) -> bool {
        let cuts = &self.cuts;
        let inner: Vec<usize> = (0..cuts.len()).filter(|&j| cuts[j] > side.lo && cuts[j] < side.hi).collect();
        let (Some(&first), Some(&last)) = (inner.first(), inner.last()) else {
            return self.clear_one(zbox, v, side);
        };
        self.clear_one(zbox, v, Interval::new(side.lo, cuts[first]))
            && self.clear_one(zbox, v, Interval::new(cuts[last], side.hi))
            && inner.windows(2).all(|w| {
                *known
                    .entry((v, w[0]))
                    .or_insert_with(|| self.clear_one(zbox, v, Interval::new(cuts[w[0]], cuts[w[1]])))
            })
    }

    /// Side `v`'s clear end by bisection ([`REACH_STEPS`]): from below, the largest `a`
    /// with `[zv.lo, a]` clear; from above, the smallest `b` with `[b, zv.hi]` clear;
    /// `None` when no slab is.
    fn bisect(
        &self,
        zbox: &[Interval],
        known: &mut HashMap<(usize, usize), bool>,
        v: usize,
        from_low: bool,
    ) -> Option<f64> {
        let zv = self.z[v];
        let slab = |e: f64| if from_low { Interval::new(zv.lo, e) } else { Interval::new(e, zv.hi) };
        let (mut good, mut bad) = if from_low { (zv.lo, zv.hi) } else { (zv.hi, zv.lo) };
        if !self.clear(zbox, known, v, slab(good)) {
            return None;
        }
        for _ in 0..REACH_STEPS {
            let mid = 0.5 * good + 0.5 * bad;
            if !mid.is_finite() || mid == good || mid == bad {
                break;
            }
            if self.clear(zbox, known, v, slab(mid)) {
                good = mid;
            } else {
                bad = mid;
            }
        }
        Some(good)
    }

    /// One pass over the sides of `zbox`: each narrowed to its clear ends (a side never
    /// widens: the points beyond the last pass's stay clear); `None` when every point is
    /// beyond a clear side.
    fn pass(&self, zbox: &[Interval]) -> Option<Vec<Interval>> {
        let mut known = HashMap::new();
        let mut next = zbox.to_vec();
        for v in 0..self.z.len() {
            let lo = self.bisect(zbox, &mut known, v, true).map_or(zbox[v].lo, |e| e.max(zbox[v].lo));
            let hi = self.bisect(zbox, &mut known, v, false).map_or(zbox[v].hi, |e| e.min(zbox[v].hi));
            if lo > hi {
                return None;
            }
            next[v] = Interval::new(lo, hi);
        }
        Some(next)
    }
}

impl Reach {
    /// Whether this reach clears every part of every piece of `boxes`: the obstacle's
    /// partition bound over those pieces is then its laws' outside mass alone.
    pub fn clears_all(&self, boxes: &PieceBoxes) -> bool {
        reach_clears_all(boxes, self)
    }

    /// The obstacle's partition bound over pieces this reach clears whole
    /// ([`Reach::clears_all`]): its laws' outside mass (at most 1).
    pub fn cleared_bound(&self) -> f64 {
        self.outside.min(1.0)
    }
}

/// Most cells per axis of a [`ReachGrid`].
pub const REACH_GRID_MAX_CELLS_PER_AXIS: usize = 64;

/// The obstacles' [`Reach`] boxes in a uniform grid over the region's spatial axes
/// (docs/design.md §5.14): the obstacles whose reach may not clear a trajectory are found
/// from the cells its parts' boxes meet, instead of walking every obstacle's reach (on
/// 512 disks that walk was most of the whole-path bound of a plan that passes near none).
///
/// Soundness rests on one fact: the cell of a coordinate, `f(x) = clamp(⌊(x − lo)/w⌋)`,
/// is non-decreasing in x (floating-point subtraction, division by w > 0, floor and
/// clamp all are), so a box `[a, b]` listed in cells `f(a)..=f(b)` shares the cell `f(p)`
/// with every box that holds a point p of it. A reach box and a part box with no cell in
/// common therefore have no common point: on some spatial axis they are disjoint, which
/// is the test of [`Reach::clears`]. The time axis is not gridded (never needed for that).
#[derive(Clone, Debug)]
pub struct ReachGrid {
    /// The region every gridded reach was found in.
    region: Vec<(f64, f64)>,
    /// Per spatial axis: the region's lower end, a cell's width, the number of cells.
    axes: Vec<(f64, f64, usize)>,
    /// Per cell (first axis slowest), the obstacles whose reach box meets it.
    cells: Vec<Vec<u32>>,
    /// Obstacles examined whatever the trajectory: no reach, or one of another region.
    always: Vec<u32>,
    /// Obstacles in all.
    obstacles: usize,
}

impl ReachGrid {
    /// The grid over `region` of `reaches` (one per obstacle; `None` for an obstacle
    /// without one; a reach found in another region is examined always). `None` when the
    /// region has no spatial axis or a side that is not finite and positive.
    pub fn new(region: &[(f64, f64)], reaches: &[Option<std::sync::Arc<Reach>>]) -> Option<ReachGrid> {
        let region = region.to_vec();
        let n = region.len().checked_sub(1).filter(|&n| n > 0)?;
        if region.iter().any(|(lo, hi)| !(lo.is_finite() && hi.is_finite() && hi > lo && (hi - lo).is_finite())) {
            return None;
        }
        let per_axis = ((reaches.len().max(1) as f64).powf(1.0 / n as f64).ceil() as usize)
            .clamp(1, REACH_GRID_MAX_CELLS_PER_AXIS);
        let axes: Vec<(f64, f64, usize)> =
            region[..n].iter().map(|&(lo, hi)| (lo, (hi - lo) / per_axis as f64, per_axis)).collect();
        if axes.iter().any(|&(_, w, _)| !(w > 0.0 && w.is_finite())) {
            return None;
        }
        let total = axes.iter().map(|a| a.2).product();
        let mut grid =
            ReachGrid { region, axes, cells: vec![Vec::new(); total], always: Vec::new(), obstacles: reaches.len() };
        for (i, r) in reaches.iter().enumerate() {
            let Some(r) = r.as_deref().filter(|r| r.region == grid.region) else {
                grid.always.push(i as u32);
                continue;
            };
            // a reach without sides clears every box of its region: in no cell
            let Some(sides) = &r.sides else { continue };
            let Some(range) = grid.cell_range(&sides[..n]) else {
                grid.always.push(i as u32);
                continue;
            };
            let cells = &mut grid.cells;
            for_each_cell(&grid.axes, &range, |c| cells[c].push(i as u32));
        }
        Some(grid)
    }

    /// The cell of coordinate `x` on axis `v`: non-decreasing in x (NaN is refused first).
    fn cell_of(&self, v: usize, x: f64) -> usize {
        let (lo, w, count) = self.axes[v];
        ((x - lo) / w).floor().clamp(0.0, (count - 1) as f64) as usize
    }

    /// The cells `f(a)..=f(b)` per spatial axis of the box; `None` for a NaN end.
    fn cell_range(&self, sides: &[(f64, f64)]) -> Option<Vec<(usize, usize)>> {
        sides
            .iter()
            .enumerate()
            .map(|(v, &(a, b))| {
                (!a.is_nan() && !b.is_nan() && a <= b).then(|| (self.cell_of(v, a), self.cell_of(v, b)))
            })
            .collect()
    }

    /// Per obstacle, whether its reach may fail to clear the pieces of `boxes`: every
    /// obstacle marked `false` has [`Reach::clears_all`] true (its bound is
    /// [`Reach::cleared_bound`]). `None` when a part's box is not inside the region (or
    /// not a number): the caller then asks every obstacle.
    pub fn candidates(&self, boxes: &PieceBoxes) -> Option<Vec<bool>> {
        let n = self.axes.len();
        let mut marked = vec![false; self.obstacles];
        for &i in &self.always {
            marked[i as usize] = true;
        }
        for part in boxes.parts.iter().flatten() {
            if part.len() != self.region.len()
                || !part.iter().zip(&self.region).all(|(x, &(lo, hi))| x.lo >= lo && x.hi <= hi)
            {
                return None;
            }
            let sides: Vec<(f64, f64)> = part[..n].iter().map(|x| (x.lo, x.hi)).collect();
            let range = self.cell_range(&sides)?;
            for_each_cell(&self.axes, &range, |c| {
                for &o in &self.cells[c] {
                    marked[o as usize] = true;
                }
            });
        }
        Some(marked)
    }
}

/// Calls `f` with the index of every cell of the block `range` of a grid of `axes`
/// (first axis slowest; an odometer, last axis fastest).
fn for_each_cell(axes: &[(f64, f64, usize)], range: &[(usize, usize)], mut f: impl FnMut(usize)) {
    let mut k: Vec<usize> = range.iter().map(|r| r.0).collect();
    loop {
        f(k.iter().zip(axes).fold(0usize, |acc, (&i, a)| acc * a.2 + i));
        let Some(a) = (0..k.len()).rev().find(|&a| k[a] < range[a].1) else { return };
        k[a] += 1;
        for (v, later) in k.iter_mut().enumerate().skip(a + 1) {
            *later = range[v].0;
        }
    }
}

/// Whether `reach` clears every part of every piece (the tree's hulls first).
pub(super) fn reach_clears_all(boxes: &PieceBoxes, reach: &Reach) -> bool {
    let mut stack: Vec<usize> = if boxes.nodes.is_empty() { Vec::new() } else { vec![0] };
    while let Some(i) = stack.pop() {
        let node = &boxes.nodes[i];
        if reach.clears(&node.hull) {
            continue;
        }
        match node.children {
            Some((a, b)) => {
                stack.push(b);
                stack.push(a);
            }
            None if boxes.parts[node.first].iter().all(|bx| reach.clears(bx)) => {}
            None => return false,
        }
    }
    true
}

/// The parts of the trajectory's pieces (at depth [`SCREEN_DEPTH`], as the partition's
/// parts) on which P(x(t), ω, t) may be ≥ 0 for some t of the part and some ω of the
/// parameters' ranges: a cheap screen before the partition. P, folded over the ranges in
/// `frame` ([`FoldedPoly`]), is bounded above on the tree's hulls, then on the parts' boxes
/// of the pieces whose hulls it does not dismiss, each box moved into the frame
/// (z_v = (x_v − c_v)·2^(−e_v), in interval arithmetic); an upper bound below 0 proves the
/// stretch, piece or part misses the obstacle for every ω of the ranges — which the
/// partition's root box would also find, at the cost of the pieces' restrictions (on 512
/// disks the final check restricted every piece for every obstacle). Only a bound below 0
/// drops anything (`<` is false for NaN, should one ever arise).
pub(super) fn parts_near(folded: &FoldedPoly, boxes: &PieceBoxes, frame: &Frame, reach: Option<&Reach>) -> Vec<Part> {
    let n = frame.center.len();
    let shift: Vec<(Interval, Interval)> =
        (0..n).map(|v| (Interval::point(frame.center[v]), Interval::point(frame.inv_scale(v)))).collect();
    let mut z = vec![Interval::point(0.0); n];
    let mut clear = |bx: &[Interval]| {
        if bx.len() != n {
            return false;
        }
        if reach.is_some_and(|r| r.clears(bx)) {
            return true;
        }
        for (zv, (x, (c, inv))) in z.iter_mut().zip(bx.iter().zip(&shift)) {
            *zv = (*x - *c) * *inv;
        }
        folded.upper(&z) < 0.0
    };
    let mut near = Vec::new();
    let mut stack: Vec<usize> = if boxes.nodes.is_empty() { Vec::new() } else { vec![0] };
    while let Some(i) = stack.pop() {
        let node = &boxes.nodes[i];
        if clear(&node.hull) {
            continue;
        }
        match node.children {
            Some((a, b)) => {
                stack.push(b);
                stack.push(a);
            }
            None => {
                let p = node.first;
                for (k, bx) in boxes.parts[p].iter().enumerate() {
                    if !clear(bx) {
                        near.push((p, SCREEN_DEPTH, k as u64));
                    }
                }
            }
        }
    }
    near
}
