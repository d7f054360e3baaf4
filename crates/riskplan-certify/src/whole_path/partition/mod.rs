//! The partition bound of the whole-path event (docs/design.md §5.14): when every
//! parameter of an obstacle has a distribution function that can be bounded rigorously
//! ([`CdfLaw`]: uniform, normal, discrete, exponential, Laplace, beta and gamma with shapes
//! in [10⁻³, 64]), the parameter space itself is
//! partitioned, instead of bounding the event by moments.
//!
//! The event of a trajectory is E = {ω : ∃ t, P(x(t), ω, t) ≥ 0}. Cover the parameters'
//! range R (the support, or μ ± 9σ) by boxes B. For each box and each part of the control
//! net (a dyadic sub-interval of one piece's time; the coefficients bⱼ(ω) of its
//! restriction in the Bernstein basis, in outward-rounded interval arithmetic):
//!
//! - if every bⱼ is below 0 over B (interval ranges of its terms), q < 0 on that part for
//!   every ω ∈ B (the basis is non-negative and sums to 1);
//! - if the first or the last coefficient — q's values at the part's ends — is at least 0
//!   over B, every ω ∈ B collides (a *hit*);
//! - otherwise the part is halved in time, down to [`CELLS_MAX_DEPTH`], and beyond it,
//!   down to [`CELLS_DEEPEST_DEPTH`], while the part's own curvature is what keeps it
//!   undecided ([`TIME_SPLIT_RATIO`]; a long piece beside a small obstacle).
//!
//! A box whose parts are all proven negative is outside E. Boxes neither outside nor hit
//! are halved along their widest side (relative to R), largest probability first, within a
//! budget of boxes. Then, the parameters being independent,
//!
//! ```text
//! P(E) ≤ P(ω ∉ R) + Σ_{B not proven outside} Πₖ P(ωₖ ∈ Bₖ)
//! ```
//!
//! each factor an upper bound ([`CdfLaw::mass_upper`]), every sum rounded up. The parts of
//! every piece of a trajectory enter one partition, so the event along the whole
//! trajectory is bounded at once (no sum over pieces).

use super::add_up;
use crate::compiled::Frame;
use crate::restrict::{substitutions, PieceRef};
use riskplan_math::contour::bounds::power_range;
use riskplan_math::contour::{FoldedPoly, RiskContour};
use riskplan_math::moments::cdf::{mass_between, CdfLaw};
use riskplan_math::poly::{Interval, Poly, UPoly, Var};
use std::collections::BinaryHeap;

/// Depth down to which an undecided part's time is always halved: 2⁻⁶ of a piece. A
/// coefficient of a restriction of degree D differs from q's values by O(h²) on a part of
/// relative length h; at this depth the net is within 1/4096 of q's second derivative's
/// range (over the piece) of q itself. Deeper, down to [`CELLS_DEEPEST_DEPTH`], only as
/// [`TIME_SPLIT_RATIO`] says.
pub const CELLS_MAX_DEPTH: u32 = 6;

/// Deepest halving of a part's time beyond [`CELLS_MAX_DEPTH`]: 2⁻²⁰ of a piece. Relative
/// depth alone would leave a long piece's parts long next to a small obstacle: a straight
/// shortcut 158 long (on 512 disks) has parts 2.5 long at depth 6, and beside a disk of
/// radius 0.91 at 1.22 from its centre the middle coefficient of q's net overshoots q's
/// maximum by about (2.5/2)² ≈ 1.6, so no box of the parameters would decide it and the
/// bound would be the mass of every box, near 1 where the event is impossible. Beyond depth 6
/// a part is halved only as [`TIME_SPLIT_RATIO`] says, and at most
/// `CELLS_DEEP_SPLITS_PER_BOX` times per box; 20 bounds the depth when the parameters'
/// boxes have no width to spread (point masses).
pub const CELLS_DEEPEST_DEPTH: u32 = 20;

/// Most halvings beyond [`CELLS_MAX_DEPTH`] in one box's examination, and most deeper parts
/// kept per obstacle and trajectory ([`CELLS_DEEP_PARTS_MAX`]): a bound on the work and
/// memory of a box whose q is about 0 along a long stretch (without it, every depth-6 part
/// of a piece could be halved down to depth 20 within one box, two million restrictions,
/// between two polls of `stop`). The plans on 512 disks make a few deeper parts per
/// obstacle; beyond either limit a part is not halved further and stays open for the
/// parameters' boxes (only the work is limited: any depth is sound).
pub const CELLS_DEEP_SPLITS_PER_BOX: usize = 64;

/// Deeper parts (beyond [`CELLS_MAX_DEPTH`]) kept per obstacle and trajectory after which no
/// part is halved beyond depth 6 any more (the halves already pushed are still examined:
/// at most 2·[`CELLS_DEEP_SPLITS_PER_BOX`] more); about a kilobyte each at degree 8.
pub const CELLS_DEEP_PARTS_MAX: usize = 4096;

/// Beyond [`CELLS_MAX_DEPTH`], an undecided part is halved in time (instead of left to the
/// parameters' boxes) when, at the box's centre ω, its ends are below 0 but some
/// coefficient is not, and the net's overshoot there — its largest coefficient less its
/// larger end, which a halving divides by about 4 (O(h²)) — is more than 1/3 of the
/// widest coefficient's spread over the box, which halving the box divides by about 2:
/// the larger of the two gains (¾ of the overshoot against ¼ of the spread) is taken.
/// Any depth is sound (the parts cover the piece); this only chooses which halving is
/// likelier to decide.
pub const TIME_SPLIT_RATIO: f64 = 3.0;

/// How hard the partition works.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellEffort {
    /// Most boxes examined.
    pub max_boxes: usize,
    /// The search ends when the probability of the boxes still undecided is at most this
    /// fraction of the bound of the boxes hit (the bound is then within this factor of
    /// what finer boxes could give).
    pub rel_tol: f64,
    /// ... or at most this, absolutely.
    pub abs_tol: f64,
}

impl CellEffort {
    /// For reports (`verify --whole-path`): 4000 boxes, within 2 % or 10⁻¹².
    pub const REPORT: CellEffort = CellEffort { max_boxes: 4000, rel_tol: 0.02, abs_tol: 1e-12 };
    /// For the bound every plan reports (a tenth of the boxes, within 5 %): about 10 ms per
    /// obstacle near a plan of example-d1.
    pub const PLAN: CellEffort = CellEffort { max_boxes: 400, rel_tol: 0.05, abs_tol: 1e-12 };

    /// The same effort, ending also once the undecided probability is at most `slack`
    /// (when that is more than its own `abs_tol`; a `slack` that is not a number changes
    /// nothing). The bound stays an upper bound: the undecided boxes are counted whole.
    pub fn with_slack(self, slack: f64) -> CellEffort {
        CellEffort { abs_tol: self.abs_tol.max(if slack.is_nan() { 0.0 } else { slack }), ..self }
    }
}

/// The partition bound of one obstacle over a trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellsBound {
    /// P(∃ t : collision with this obstacle) ≤ `bound` (≤ 1).
    pub bound: f64,
    /// Boxes examined.
    pub boxes: usize,
}

/// The partition bound (module docs) of the obstacle of `contour` over the trajectory
/// `pieces`, the polynomial evaluated in `frame`'s coordinates (the scene's,
/// `certify::checker::scene_frame`: centred and scaled so that no coefficient cancels far
/// from the origin; any frame is sound): `None` when a parameter of the obstacle has no [`CdfLaw`] (the moment bounds
/// apply instead), when a piece cannot be restricted (not finite, another dimension), or
/// when `stop` said yes.
pub fn cells_path_risk(
    contour: &RiskContour,
    pieces: &[PieceRef<'_>],
    frame: &Frame,
    effort: CellEffort,
    stop: &dyn Fn() -> bool,
) -> Option<CellsBound> {
    let boxes = PieceBoxes::new(pieces, contour.layout().dim);
    cells_path_risk_in(contour, pieces, &boxes, frame, None, effort, stop)
}

/// [`cells_path_risk`] with the pieces' boxes built once by the caller ([`PieceBoxes::new`]
/// of the same pieces), for many obstacles (each in its own frame, if the caller likes:
/// [`crate::checker::SceneKernel::path_frames`]).
pub fn cells_path_risk_in(
    contour: &RiskContour,
    pieces: &[PieceRef<'_>],
    boxes: &PieceBoxes,
    frame: &Frame,
    reach: Option<&Reach>,
    effort: CellEffort,
    stop: &dyn Fn() -> bool,
) -> Option<CellsBound> {
    let layout = contour.layout();
    // every piece restrictable before any box is judged (a box hit early must not hide a
    // piece that cannot be judged at all: the caller then falls back, as for one alone)
    if pieces.iter().any(|p| !p.is_finite() || p.coeffs.len() != layout.dim) {
        return None;
    }
    // an obstacle whose reach the trajectory stays out of (most, on crowded scenes): its
    // laws' outside mass, without P (the reach was found from P folded over the ranges)
    if let Some(r) = reach.filter(|r| reach_clears_all(boxes, r)) {
        return Some(CellsBound { bound: r.cleared_bound(), boxes: 0 });
    }
    // P folded over the laws' ranges: the root box (None when a parameter has no law)
    let folded = contour.folded_poly(&frame.center, &frame.exponents)?;
    let outside = folded.outside;
    // the parts that may meet the obstacle for some ω of the root box (the others are
    // outside it on every box of the partition)
    let near = parts_near(&folded, boxes, frame, reach);
    if near.is_empty() {
        return Some(CellsBound { bound: outside.min(1.0), boxes: 0 });
    }
    let laws: Vec<&CdfLaw> = folded.params.iter().map(|&v| contour.law(v)).collect::<Option<_>>()?;
    let nets = Nets::new(contour, &folded.params, pieces, frame)?;
    let root = Cell::root(&folded, &laws, contour, near);
    partition(contour, &folded.params, &laws, nets, root, outside, effort, stop)
}

/// The partition of the parameters' root box (`root`, with its parts that may meet the
/// obstacle), largest probability first, within `effort`: the laws' `outside` mass plus
/// the probability of the boxes hit or left undecided, summed and rounded up; `None` when
/// `stop` said yes or a box cannot be judged.
#[allow(clippy::too_many_arguments)]
fn partition(
    contour: &RiskContour,
    params: &[Var],
    laws: &[&CdfLaw],
    mut nets: Nets<'_>,
    root: Cell,
    outside: f64,
    effort: CellEffort,
    stop: &dyn Fn() -> bool,
) -> Option<CellsBound> {
    // F at the ends of the boxes' sides, from the contour's memo (the same middles are
    // split plan after plan)
    let cdf = |k: usize, x: f64| contour.law_cdf(params[k], x).unwrap_or_else(|| laws[k].cdf(x));
    let widths: Vec<f64> = laws.iter().map(|l| l.hi - l.lo).collect();
    let mut heap = BinaryHeap::new();
    let mut pending = root.mass;
    heap.push(root);
    let mut hit = 0.0f64;
    let mut boxes = 0usize;
    // (buffers of every box's evaluation)
    let (mut score, mut mono) = (Vec::new(), Vec::new());
    let mut centre = Centre::default();
    while let Some(cell) = heap.pop() {
        if boxes >= effort.max_boxes || pending <= effort.abs_tol || pending <= effort.rel_tol * hit {
            heap.push(cell);
            break;
        }
        if stop() {
            return None;
        }
        boxes += 1;
        pending -= cell.mass;
        score.clear();
        score.resize(cell.bx.len(), 0.0);
        monomials_into(&cell.bx, &nets.betas, &mut mono);
        let (state, open) = nets.state(&cell.bx, &mono, &mut centre, &cell.parts, &mut score)?;
        match state {
            State::Outside => {}
            State::Hit => hit = add_up(hit, cell.mass),
            State::Unknown => {
                let Some((k, mid)) = cell.side_to_split(laws, &widths, &score) else {
                    hit = add_up(hit, cell.mass);
                    continue;
                };
                for half in cell.halves(k, mid, cdf(k, mid), open) {
                    if half.mass > 0.0 {
                        pending += half.mass;
                        heap.push(half);
                    }
                }
            }
        }
    }
    let undecided = heap.iter().fold(0.0, |acc, c| add_up(acc, c.mass));
    let bound = add_up(add_up(outside, hit), undecided).min(1.0);
    Some(CellsBound { bound, boxes })
}

/// Πₖ P(ωₖ in the box's side k) from the enclosures of each side's distribution function
/// at its ends, each factor an upper bound, the product rounded up (0 only when a factor is
/// exactly 0: a product that underflows counts as the least positive float, never as an
/// empty box).
fn box_mass(ends: &[(Interval, Interval)]) -> f64 {
    let mut product = 1.0f64;
    for (fa, fb) in ends {
        let f = mass_between(*fa, *fb);
        if f == 0.0 {
            return 0.0;
        }
        product *= f;
    }
    product.next_up().min(1.0)
}

impl Cell {
    /// The root box of the partition: the laws' ranges, with the parts `near` that may
    /// meet the obstacle for some of its ω.
    fn root(folded: &FoldedPoly, laws: &[&CdfLaw], contour: &RiskContour, near: Vec<Part>) -> Cell {
        let cdf = |k: usize, x: f64| contour.law_cdf(folded.params[k], x).unwrap_or_else(|| laws[k].cdf(x));
        let ends: Vec<(Interval, Interval)> =
            laws.iter().enumerate().map(|(k, l)| (cdf(k, l.lo), cdf(k, l.hi))).collect();
        Cell { mass: box_mass(&ends), bx: folded.root.clone(), ends, parts: near }
    }

    /// The side to halve and where: the side that spreads the open parts' coefficients
    /// most (`score`; the widest relative to its range on a tie; a side of zero width, a
    /// point mass, is never halved), at [`CdfLaw::split`] (the middle, or a law known by
    /// moments its grid point). `None`: no side left (the box counts whole).
    fn side_to_split(&self, laws: &[&CdfLaw], widths: &[f64], score: &[f64]) -> Option<(usize, f64)> {
        let rel = |k: usize| (self.bx[k].hi - self.bx[k].lo) / widths[k];
        (0..self.bx.len())
            .filter(|&k| widths[k] > 0.0)
            .filter_map(|k| Some((k, laws[k].split(self.bx[k].lo, self.bx[k].hi)?)))
            .max_by(|&(a, _), &(b, _)| score[a].total_cmp(&score[b]).then(rel(a).total_cmp(&rel(b))))
    }

    /// The box halved along side `k` at `mid` (`f_mid`: the side's distribution function
    /// there, enclosed), each half with the parts still `open` and its mass.
    fn halves(self, k: usize, mid: f64, f_mid: Interval, open: Vec<Part>) -> [Cell; 2] {
        let (f_lo, f_hi) = self.ends[k];
        // (the lower half a copy, the upper one the box itself)
        let (hi_k, Cell { bx: mut upper_bx, ends: mut upper_ends, .. }) = (self.bx[k].hi, self);
        let mut lower_bx = upper_bx.clone();
        let mut lower_ends = upper_ends.clone();
        lower_bx[k] = Interval::new(lower_bx[k].lo, mid);
        lower_ends[k] = (f_lo, f_mid);
        upper_bx[k] = Interval::new(mid, hi_k);
        upper_ends[k] = (f_mid, f_hi);
        let lower = Cell { mass: box_mass(&lower_ends), bx: lower_bx, ends: lower_ends, parts: open.clone() };
        let upper = Cell { mass: box_mass(&upper_ends), bx: upper_bx, ends: upper_ends, parts: open };
        [lower, upper]
    }
}

mod boxes;
mod nets;
mod reach;
#[cfg(test)]
mod tests;

pub use boxes::*;
use nets::*;
pub use reach::*;
