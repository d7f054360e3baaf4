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

use super::super::compose::{substitutions, PieceRef};
use super::super::fast::Frame;
use super::add_up;
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

/// A coefficient bⱼ(ω) as terms c_β·ω^β, each monomial β an index into the partition's
/// list of monomials ([`Nets::betas`]).
struct Coef {
    terms: Vec<(usize, Interval)>,
}

impl Coef {
    /// An enclosure of the coefficient's range over a box, from the box's monomial ranges
    /// (`mono[β]` encloses the range of ω^β over the box: [`monomials`]).
    fn range(&self, mono: &[Interval]) -> Interval {
        let mut acc = Interval::point(0.0);
        for &(b, c) in &self.terms {
            acc = acc + c * mono[b];
        }
        acc
    }

    /// Adds to `score[k]` the width of each term's range that involves parameter k: how
    /// much of the coefficient's spread over the box halving side k may remove.
    fn spread(&self, mono: &[Interval], betas: &[Beta], score: &mut [f64]) {
        for &(b, c) in &self.terms {
            let r = c * mono[b];
            let w = r.hi - r.lo;
            for &(k, _) in &betas[b] {
                score[k] += w;
            }
        }
    }
}

/// The monomial ranges of a box: entry β encloses the range of ω^β over the box, the
/// product of the ranges of the powers of its sides (independent sides: the product of
/// the ranges is the exact range, enclosed; `contour::bounds::power_range` per power).
fn monomials_into(bx: &[Interval], betas: &[Beta], out: &mut Vec<Interval>) {
    out.clear();
    out.extend(
        betas.iter().map(|beta| beta.iter().fold(Interval::point(1.0), |acc, &(k, e)| acc * power_range(bx[k], e))),
    );
}

/// What a box is for a part (or for the whole trajectory).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Outside,
    Hit,
    Unknown,
}

/// A parameter monomial: (index into the partition's parameters, exponent) pairs.
type Beta = Vec<(usize, u32)>;

/// A part of a trajectory's control net: (piece, depth, index).
type Part = (usize, u32, u64);

/// One level of a piece's control net: per part, `None` not computed yet, `Some(None)` not
/// restrictable, else its coefficients.
type Level = Vec<Option<Option<Vec<Coef>>>>;

/// The control nets of a trajectory's pieces in interval arithmetic, computed on demand.
struct Nets<'a> {
    /// P = Σ_β c_β(x, t)·ω^β: each parameter monomial β (as indices into the partition's
    /// parameters and exponents) ...
    betas: std::rc::Rc<[Beta]>,
    /// ... and its coefficient polynomial c_β in (x, t), in the same order, split once
    /// (a [`Coef`]'s terms index both).
    coefs: Vec<Poly<Interval>>,
    /// The frame `coefs` are written in (space and time centred and scaled).
    frame: Frame,
    dim: usize,
    pieces: &'a [PieceRef<'a>],
    /// `cells[piece][depth]`, depth ≤ [`CELLS_MAX_DEPTH`].
    cells: Vec<Vec<Level>>,
    /// The deeper parts computed, by (piece, depth, index): few, near the obstacle.
    deep: std::collections::HashMap<Part, Option<Vec<Coef>>>,
    /// The Bernstein conversion's ratios C(j, k)/C(D, k), enclosed, per degree D.
    ratios: std::collections::BTreeMap<usize, Vec<Vec<Interval>>>,
}

impl<'a> Nets<'a> {
    fn new(contour: &RiskContour, params: &[Var], pieces: &'a [PieceRef<'a>], frame: &Frame) -> Option<Nets<'a>> {
        let layout = contour.layout();
        let centred = contour.centred_poly(&frame.center, &frame.exponents)?;
        let mut by_beta: std::collections::BTreeMap<Beta, Poly<Interval>> = Default::default();
        for (m, c) in centred.terms() {
            let (omega, xt) = m.split(|v| layout.is_param(v));
            let beta: Beta = omega
                .pairs()
                .iter()
                .map(|&(v, e)| Some((params.iter().position(|&p| p == v)?, e)))
                .collect::<Option<_>>()?;
            by_beta.entry(beta).or_insert_with(Poly::zero).add_term(xt, *c);
        }
        let (betas, coefs): (Vec<Beta>, Vec<Poly<Interval>>) = by_beta.into_iter().unzip();
        Some(Nets {
            betas: betas.into(),
            coefs,
            frame: frame.clone(),
            dim: layout.dim,
            pieces,
            cells: (0..pieces.len()).map(|_| Vec::new()).collect(),
            deep: Default::default(),
            ratios: Default::default(),
        })
    }

    fn coeffs(&mut self, piece: usize, d: u32, i: u64) -> Option<&[Coef]> {
        if d > CELLS_MAX_DEPTH {
            let (coefs, frame, dim, pieces, ratios) =
                (&self.coefs, &self.frame, self.dim, self.pieces, &mut self.ratios);
            return self
                .deep
                .entry((piece, d, i))
                .or_insert_with(|| restrict(coefs, frame, dim, pieces[piece], d, i, ratios))
                .as_deref();
        }
        let levels = &mut self.cells[piece];
        while levels.len() <= d as usize {
            let n = 1usize << levels.len();
            levels.push((0..n).map(|_| None).collect());
        }
        if levels[d as usize][i as usize].is_none() {
            let c = restrict(&self.coefs, &self.frame, self.dim, self.pieces[piece], d, i, &mut self.ratios);
            self.cells[piece][d as usize][i as usize] = Some(c);
        }
        self.cells[piece][d as usize][i as usize].as_ref().and_then(|c| c.as_deref())
    }

    /// The state of a box from its monomial ranges, from the parts still open for it
    /// (`parts`: piece, depth, index); the parts left undecided (at depth 6 to 20: halved
    /// no further for this box) are returned for its halves, and their coefficients'
    /// spread per side added to `score`.
    fn state(
        &mut self,
        bx: &[Interval],
        mono: &[Interval],
        centre: &mut Centre,
        parts: &[Part],
        score: &mut [f64],
    ) -> Option<(State, Vec<Part>)> {
        let mut open = Vec::new();
        let betas = self.betas.clone();
        let mut stack: Vec<Part> = parts.to_vec();
        // the monomials at the box's centre, formed when first needed
        let mut centre_ready = false;
        let mut deep_splits = 0usize;
        while let Some((p, d, i)) = stack.pop() {
            let deep_room = self.deep.len() < CELLS_DEEP_PARTS_MAX;
            let coeffs = self.coeffs(p, d, i)?;
            let (Some(first), Some(last)) = (coeffs.first(), coeffs.last()) else { return None };
            // q's values at the part's ends: one ≥ 0 over the box is a hit (then not every
            // coefficient is < 0); else every coefficient < 0 proves the part outside
            let (first, last) = (first.range(mono), last.range(mono));
            if first.lo >= 0.0 || last.lo >= 0.0 {
                return Some((State::Hit, Vec::new()));
            }
            if first.hi < 0.0 && last.hi < 0.0 && coeffs.iter().all(|c| c.range(mono).hi < 0.0) {
                continue;
            }
            let deeper = d < CELLS_MAX_DEPTH
                || (d < CELLS_DEEPEST_DEPTH && deep_splits < CELLS_DEEP_SPLITS_PER_BOX && deep_room && {
                    if !centre_ready {
                        centre.fill(bx, &betas);
                        centre_ready = true;
                    }
                    curvature_dominates(coeffs, mono, centre)
                });
            if deeper && d >= CELLS_MAX_DEPTH {
                deep_splits += 1;
            }
            if deeper {
                stack.push((p, d + 1, 2 * i + 1));
                stack.push((p, d + 1, 2 * i));
            } else {
                for c in coeffs {
                    c.spread(mono, &betas, score);
                }
                open.push((p, d, i));
            }
        }
        Some(if open.is_empty() { (State::Outside, open) } else { (State::Unknown, open) })
    }
}

/// The monomials at a box's centre point, in plain floating point (a buffer kept between
/// boxes): they only choose which halving to make ([`curvature_dominates`]).
#[derive(Default)]
struct Centre {
    mono: Vec<f64>,
}

impl Centre {
    fn fill(&mut self, bx: &[Interval], betas: &[Beta]) {
        let mid = |k: usize| 0.5 * bx[k].lo + 0.5 * bx[k].hi;
        self.mono.clear();
        self.mono.extend(betas.iter().map(|beta| beta.iter().fold(1.0, |acc, &(k, e)| acc * mid(k).powi(e as i32))));
    }
}

/// Whether a part undecided over a box is better halved in time than the box in ω
/// ([`TIME_SPLIT_RATIO`]): at the box's centre the part's ends are below 0 and some
/// coefficient is not, by more than the ratio's share of the widest coefficient's spread
/// over the box (`mono`: the box's monomial ranges). Estimated in plain floating point
/// from the coefficients' midpoints (a coefficient's spread as Σ |mid cᵦ|·width(ω^β),
/// its terms' own widths left out): only a choice of work, never a decision (any depth
/// is sound). A value that is not finite (an unbounded coefficient) means no.
fn curvature_dominates(coeffs: &[Coef], mono: &[Interval], centre: &Centre) -> bool {
    let at = |c: &Coef| c.terms.iter().map(|&(b, a)| (0.5 * a.lo + 0.5 * a.hi) * centre.mono[b]).sum::<f64>();
    let (Some(first), Some(last)) = (coeffs.first(), coeffs.last()) else { return false };
    let (a, b) = (at(first), at(last));
    if !a.is_finite() || !b.is_finite() || a.max(b) >= 0.0 {
        return false;
    }
    let ends = a.max(b);
    let mut top = f64::NEG_INFINITY;
    for c in coeffs {
        let v = at(c);
        if !v.is_finite() {
            return false;
        }
        top = top.max(v);
    }
    if top < 0.0 {
        return false;
    }
    let mut widest = 0.0f64;
    for c in coeffs {
        let w: f64 = c.terms.iter().map(|&(b, a)| (0.5 * a.lo + 0.5 * a.hi).abs() * (mono[b].hi - mono[b].lo)).sum();
        if w.is_nan() {
            return false;
        }
        widest = widest.max(w);
    }
    TIME_SPLIT_RATIO * (top - ends) > widest
}

/// The Bernstein coefficients in s ∈ [0, 1] of q(s, ω) = P(x(t(s)), ω, t(s)) on part `i` of
/// level `d` of the piece's time, in interval arithmetic: each c_β(x, t) composed with the
/// piece (the part's ends t0 + h·i/2^d enclosed, so the coefficients enclose those of the
/// exact part, and the exact parts cover the piece), then converted to the Bernstein basis
/// of the common degree D, bⱼ = Σ_{k≤j} C(j, k)/C(D, k)·a_k. `None` for a piece that is not
/// finite or of another dimension.
fn restrict(
    coefs: &[Poly<Interval>],
    frame: &Frame,
    dim: usize,
    piece: PieceRef<'_>,
    d: u32,
    i: u64,
    ratios: &mut std::collections::BTreeMap<usize, Vec<Vec<Interval>>>,
) -> Option<Vec<Coef>> {
    if !piece.is_finite() || piece.coeffs.len() != dim {
        return None;
    }
    let scale = (-(d as i32) as f64).exp2();
    let h = Interval::point(piece.t1) - Interval::point(piece.t0);
    let ta = if i == 0 {
        Interval::point(piece.t0)
    } else {
        Interval::point(piece.t0) + h * Interval::point(i as f64 * scale)
    };
    let hs = h * Interval::point(scale);
    // the piece in the frame: z_v(s) = (x_v(t(s)) − c_v)·2^(−e_v), and τ likewise
    let subs: Vec<UPoly<Interval>> = substitutions(piece, dim, ta, hs, Interval::point)
        .into_iter()
        .enumerate()
        .map(|(v, u)| {
            let inv = Interval::point(frame.inv_scale(v));
            let c = u.coeffs().iter().enumerate().map(|(k, &a)| {
                if k == 0 {
                    (a - Interval::point(frame.center[v])) * inv
                } else {
                    a * inv
                }
            });
            UPoly::new(c.collect())
        })
        .collect();
    let restricted: Vec<UPoly<Interval>> = riskplan_math::poly::compose_univariate_all(coefs, &subs);
    let degree = restricted.iter().map(|u| if u.is_zero() { 0 } else { u.degree() }).max().unwrap_or(0);
    let kept;
    let ratio: &[Vec<Interval>] = match BERNSTEIN_RATIOS.get(degree) {
        Some(cell) => cell.get_or_init(|| bernstein_ratios(degree)),
        None => {
            kept = ratios.entry(degree).or_insert_with(|| bernstein_ratios(degree));
            kept
        }
    };
    let mut out: Vec<Coef> = (0..=degree).map(|_| Coef { terms: Vec::new() }).collect();
    for (beta, u) in restricted.iter().enumerate() {
        if u.is_zero() {
            continue;
        }
        let a = u.coeffs();
        for (j, coef) in out.iter_mut().enumerate() {
            let mut b = Interval::point(0.0);
            for (k, ak) in a.iter().enumerate().take(j + 1) {
                b = b + ratio[j][k] * *ak;
            }
            if !(b.lo == 0.0 && b.hi == 0.0) {
                coef.terms.push((beta, b));
            }
        }
    }
    Some(out)
}

/// The Bernstein conversion's ratios C(j, k)/C(D, k) for j ≤ D, k ≤ j, enclosed from the
/// exact rationals.
fn bernstein_ratios(degree: usize) -> Vec<Vec<Interval>> {
    let binom = |n: usize, k: usize| riskplan_math::moments::binomial(n as u32, k as u32);
    (0..=degree)
        .map(|j| (0..=j).map(|k| Interval::enclose_rational(&(binom(j, k) / binom(degree, k)))).collect())
        .collect()
}

/// [`bernstein_ratios`] of the degrees below [`BERNSTEIN_RATIOS_KEPT`], formed once per
/// process (exact binomials: they were formed anew for every obstacle of every plan, 6 %
/// of the whole-path bound's time on 512 disks).
static BERNSTEIN_RATIOS: [std::sync::OnceLock<Vec<Vec<Interval>>>; BERNSTEIN_RATIOS_KEPT] =
    [const { std::sync::OnceLock::new() }; BERNSTEIN_RATIOS_KEPT];

/// Degrees whose Bernstein ratios are kept for the process (a restricted P of degree 4 in
/// space on quadratic pieces has degree 8; higher ones are kept per partition).
const BERNSTEIN_RATIOS_KEPT: usize = 33;

/// A box waiting in the partition, largest probability first.
struct Cell {
    mass: f64,
    bx: Vec<Interval>,
    /// Enclosures of each parameter's distribution function at the box's ends.
    ends: Vec<(Interval, Interval)>,
    parts: Vec<Part>,
}

impl PartialEq for Cell {
    fn eq(&self, o: &Self) -> bool {
        self.mass.total_cmp(&o.mass).is_eq()
    }
}
impl Eq for Cell {}
impl PartialOrd for Cell {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Cell {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.mass.total_cmp(&o.mass)
    }
}

/// Parts of a piece the screen encloses separately: 2^5 = 32 equal parts of its time. A
/// piece whose box meets an obstacle's reach may still pass it at every part (its box is
/// the hull of a long, diagonal or curved piece); measured on 512 disks, six in ten of the
/// obstacles that passed the screen of whole pieces were then proven outside by the
/// partition's root box, at the cost of restricting their pieces — the parts' boxes prove
/// most of them outside at a few interval evaluations each. The parts are the partition's
/// own parts at this depth (piece, depth, index), so the partition starts from those kept.
pub const SCREEN_DEPTH: u32 = 5;

/// Enclosures of a trajectory's pieces, for the partition's screen ([`cells_path_risk_in`]),
/// built once for all obstacles of a scene: per piece and per part of its time
/// (2^`SCREEN_DEPTH` of them), each coordinate (time last) over the part, x_v(t(s)) for
/// s in the part, by Horner in interval arithmetic; and a binary tree of hulls over
/// consecutive pieces, so that an obstacle far from a stretch of the trajectory is
/// dismissed for the whole stretch at one evaluation. In the scene's coordinates: each
/// obstacle's screen moves them into its own frame.
pub struct PieceBoxes {
    /// `parts[piece][k]`: the box of part k, s ∈ [k, k + 1]·2^(−SCREEN_DEPTH).
    parts: Vec<Vec<Vec<Interval>>>,
    /// The tree; `nodes[0]` is its root (when there are pieces).
    nodes: Vec<HullNode>,
}

/// A node of [`PieceBoxes`]' tree: the hull of the boxes of a run of consecutive pieces.
struct HullNode {
    hull: Vec<Interval>,
    /// The run's first piece (the only one when the node has no children).
    first: usize,
    /// The two halves, or `None` for a single piece.
    children: Option<(usize, usize)>,
}

impl PieceBoxes {
    /// The boxes of `pieces` (of dimension `dim`). A piece that is not finite or of another
    /// dimension gets the whole line (the partition refuses it anyway).
    pub fn new(pieces: &[PieceRef<'_>], dim: usize) -> PieceBoxes {
        let n_parts = 1usize << SCREEN_DEPTH;
        let scale = (-(SCREEN_DEPTH as i32) as f64).exp2();
        let parts: Vec<Vec<Vec<Interval>>> = pieces
            .iter()
            .map(|piece| {
                if !piece.is_finite() || piece.coeffs.len() != dim {
                    return vec![vec![Interval::ENTIRE; dim + 1]; n_parts];
                }
                let t0 = Interval::point(piece.t0);
                let h = Interval::point(piece.t1) - t0;
                let subs = substitutions(*piece, dim, t0, h, Interval::point);
                (0..n_parts)
                    .map(|k| {
                        // (k·2⁻³ and (k + 1)·2⁻³ are exact)
                        let s = Interval::new(k as f64 * scale, (k + 1) as f64 * scale);
                        subs.iter().map(|u| u.eval(&s)).collect()
                    })
                    .collect()
            })
            .collect();
        let mut boxes = PieceBoxes { parts, nodes: Vec::new() };
        if !pieces.is_empty() {
            boxes.build(0, pieces.len());
        }
        boxes
    }

    /// Adds the node of pieces `first..end` and its subtree; returns its index.
    fn build(&mut self, first: usize, end: usize) -> usize {
        let at = self.nodes.len();
        self.nodes.push(HullNode { hull: Vec::new(), first, children: None });
        let hull_of =
            |a: &[Interval], b: &[Interval]| -> Vec<Interval> { a.iter().zip(b).map(|(x, y)| x.hull(*y)).collect() };
        if end - first == 1 {
            let parts = &self.parts[first];
            self.nodes[at].hull = parts[1..].iter().fold(parts[0].clone(), |acc, b| hull_of(&acc, b));
        } else {
            let mid = first + (end - first) / 2;
            let (a, b) = (self.build(first, mid), self.build(mid, end));
            self.nodes[at].hull = hull_of(&self.nodes[a].hull, &self.nodes[b].hull);
            self.nodes[at].children = Some((a, b));
        }
        at
    }
}

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
/// Built once per obstacle and scene ([`crate::scene::SceneKernel`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Reach {
    /// The region, in the scene's coordinates (time last).
    region: Vec<(f64, f64)>,
    /// `[A_v, B_v]` per coordinate, rounded outward: a point of the region with
    /// `x_v < A_v` or `x_v > B_v` is clear. `None`: every point of the region is.
    sides: Option<Vec<(f64, f64)>>,
    /// The laws' probability outside their ranges ([`FoldedPoly::outside`]): the bound of
    /// a trajectory the reach clears whole.
    outside: f64,
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
        // the box of the frame outside which every point of the region is clear: the
        // region at first, then each pass's sides (see [`REACH_PASSES`])
        let mut zbox = z.clone();
        let clear_one = |zbox: &[Interval], v: usize, side: Interval| {
            let mut bx = zbox.to_vec();
            bx[v] = side;
            folded.upper(&bx) < 0.0
        };
        if folded.upper(&z) < 0.0 {
            return Some(Reach { region: region.to_vec(), sides: None, outside: folded.outside });
        }
        // a slab is clear when each of its shells is ([`REACH_SHELLS`]): the cuts ±2^k of
        // the frame (exact), and each whole shell's answer kept within a pass (the
        // bisection asks the same ones again)
        let far = z.iter().map(|zv| zv.lo.abs().max(zv.hi.abs())).fold(0.0f64, f64::max);
        let cuts: Vec<f64> = if far > 0.0 && far.is_finite() {
            let top = (far.log2().ceil() as i32).clamp(-1000, 1000);
            let ks = (top - REACH_SHELLS as i32).max(-1000)..=top;
            let mut c: Vec<f64> = ks.clone().rev().map(|k| -(k as f64).exp2()).collect();
            c.extend(ks.map(|k| (k as f64).exp2()));
            c
        } else {
            Vec::new()
        };
        for _ in 0..REACH_PASSES {
            let known: std::cell::RefCell<std::collections::HashMap<(usize, usize), bool>> = Default::default();
            let clear = |v: usize, side: Interval| {
                // the cuts strictly inside the slab split it; pieces between two cuts are shells
                let inner: Vec<usize> = (0..cuts.len()).filter(|&j| cuts[j] > side.lo && cuts[j] < side.hi).collect();
                let (Some(&first), Some(&last)) = (inner.first(), inner.last()) else {
                    return clear_one(&zbox, v, side);
                };
                clear_one(&zbox, v, Interval::new(side.lo, cuts[first]))
                    && clear_one(&zbox, v, Interval::new(cuts[last], side.hi))
                    && inner.windows(2).all(|w| {
                        let key = (v, w[0]);
                        if let Some(&k) = known.borrow().get(&key) {
                            return k;
                        }
                        let k = clear_one(&zbox, v, Interval::new(cuts[w[0]], cuts[w[1]]));
                        known.borrow_mut().insert(key, k);
                        k
                    })
            };
            let mut next = zbox.clone();
            for (v, zv) in z.iter().enumerate() {
                // in the frame: a = the largest end found with [zv.lo, a] clear (zv.lo: none),
                // b = the smallest with [b, zv.hi] clear
                let bisect = |from_low: bool| -> Option<f64> {
                    let slab = |e: f64| if from_low { Interval::new(zv.lo, e) } else { Interval::new(e, zv.hi) };
                    let (mut good, mut bad) = if from_low { (zv.lo, zv.hi) } else { (zv.hi, zv.lo) };
                    if !clear(v, slab(good)) {
                        return None;
                    }
                    for _ in 0..REACH_STEPS {
                        let mid = 0.5 * good + 0.5 * bad;
                        if !mid.is_finite() || mid == good || mid == bad {
                            break;
                        }
                        if clear(v, slab(mid)) {
                            good = mid;
                        } else {
                            bad = mid;
                        }
                    }
                    Some(good)
                };
                // a side never widens: the points beyond the last pass's stay clear
                let lo = bisect(true).map_or(zbox[v].lo, |e| e.max(zbox[v].lo));
                let hi = bisect(false).map_or(zbox[v].hi, |e| e.min(zbox[v].hi));
                if lo > hi {
                    // every point is beyond a clear side
                    return Some(Reach { region: region.to_vec(), sides: None, outside: folded.outside });
                }
                next[v] = Interval::new(lo, hi);
            }
            if next == zbox {
                break;
            }
            zbox = next;
        }
        // back in the scene's coordinates, rounded outward: x = c + z·2^e (a side still at
        // the region's enclosure is none)
        let sides = (0..n)
            .map(|v| {
                let scale = Interval::point(super::super::fast::pow2(frame.exponents[v]));
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
fn reach_clears_all(boxes: &PieceBoxes, reach: &Reach) -> bool {
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
fn parts_near(folded: &FoldedPoly, boxes: &PieceBoxes, frame: &Frame, reach: Option<&Reach>) -> Vec<Part> {
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

/// The partition bound (module docs) of the obstacle of `contour` over the trajectory
/// `pieces`, the polynomial evaluated in `frame`'s coordinates (the scene's,
/// `certify::scene::scene_frame`: centred and scaled so that no coefficient cancels far
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
/// [`crate::scene::SceneKernel::path_frames`]).
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
    let (params, root) = (&folded.params, folded.root.clone());
    let laws: Vec<&CdfLaw> = params.iter().map(|&v| contour.law(v)).collect::<Option<_>>()?;
    let mut nets = Nets::new(contour, params, pieces, frame)?;
    // Πₖ P(ωₖ in the box's side k), each factor an upper bound, the product rounded up
    // (0 only when a factor is exactly 0: a product that underflows counts as the least
    // positive float, never as an empty box)
    let mass = |ends: &[(Interval, Interval)]| -> f64 {
        let mut product = 1.0f64;
        for (fa, fb) in ends {
            let f = mass_between(*fa, *fb);
            if f == 0.0 {
                return 0.0;
            }
            product *= f;
        }
        product.next_up().min(1.0)
    };
    // F at the ends of the boxes' sides, from the contour's memo (the same middles are
    // split plan after plan)
    let cdf = |k: usize, x: f64| contour.law_cdf(params[k], x).unwrap_or_else(|| laws[k].cdf(x));
    let root_ends: Vec<(Interval, Interval)> =
        laws.iter().enumerate().map(|(k, l)| (cdf(k, l.lo), cdf(k, l.hi))).collect();
    let widths: Vec<f64> = laws.iter().map(|l| l.hi - l.lo).collect();
    let mut heap = BinaryHeap::new();
    heap.push(Cell { mass: mass(&root_ends), bx: root, ends: root_ends, parts: near });
    let mut pending = heap.peek().map_or(0.0, |c| c.mass);
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
                // halve the side that spreads the open parts' coefficients most (the widest
                // relative to its range on a tie; a side of zero width, a point mass, is
                // never halved; with none left the box counts whole)
                // (CdfLaw::split: the middle, or a law known by moments its grid point)
                let rel = |k: usize| (cell.bx[k].hi - cell.bx[k].lo) / widths[k];
                let chosen = (0..cell.bx.len())
                    .filter(|&k| widths[k] > 0.0)
                    .filter_map(|k| Some((k, laws[k].split(cell.bx[k].lo, cell.bx[k].hi)?)))
                    .max_by(|&(a, _), &(b, _)| score[a].total_cmp(&score[b]).then(rel(a).total_cmp(&rel(b))));
                let Some((k, mid)) = chosen else {
                    hit = add_up(hit, cell.mass);
                    continue;
                };
                let f_mid = cdf(k, mid);
                let (f_lo, f_hi) = cell.ends[k];
                // (the lower half a copy, the upper one the box itself)
                let (hi_k, Cell { bx: mut upper_bx, ends: mut upper_ends, .. }) = (cell.bx[k].hi, cell);
                let mut lower_bx = upper_bx.clone();
                let mut lower_ends = upper_ends.clone();
                lower_bx[k] = Interval::new(lower_bx[k].lo, mid);
                lower_ends[k] = (f_lo, f_mid);
                upper_bx[k] = Interval::new(mid, hi_k);
                upper_ends[k] = (f_mid, f_hi);
                let lower_parts = open.clone();
                for (bx, ends, parts) in [(lower_bx, lower_ends, lower_parts), (upper_bx, upper_ends, open)] {
                    let m = mass(&ends);
                    if m > 0.0 {
                        pending += m;
                        heap.push(Cell { mass: m, bx, ends, parts });
                    }
                }
            }
        }
    }
    let undecided = heap.iter().fold(0.0, |acc, c| add_up(acc, c.mass));
    let bound = add_up(add_up(outside, hit), undecided).min(1.0);
    Some(CellsBound { bound, boxes })
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_rational::BigRational;
    use proptest::prelude::*;
    use rand::SeedableRng;
    use rand_distr::Distribution as _;
    use riskplan_math::contour::Layout;
    use riskplan_math::moments::Distribution;
    use riskplan_math::poly::{parse, VarTable};

    fn q(s: &str) -> BigRational {
        riskplan_math::poly::parse_decimal(s).unwrap()
    }

    /// An obstacle `text` in 2-D over (x1, x2, t) and the named parameters, with their laws.
    fn contour(text: &str, params: &[(&str, Distribution)]) -> RiskContour {
        let mut names: Vec<String> = ["x1", "x2", "t"].map(String::from).to_vec();
        names.extend(params.iter().map(|(n, _)| n.to_string()));
        let vars = VarTable::new(names);
        let p = parse(text, &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).unwrap();
        let order = |d: &Distribution| if let Distribution::Moments { raw } = d { raw.len() as u32 } else { 32 };
        let moments: Vec<Vec<BigRational>> = params.iter().map(|(_, d)| d.raw_moments(order(d)).unwrap()).collect();
        let lookup = |v: Var, k: u32| moments.get(v as usize - 3).and_then(|m| m.get(k as usize)).cloned();
        let laws: Vec<(Var, &Distribution)> = params.iter().enumerate().map(|(i, (_, d))| (3 + i as Var, d)).collect();
        RiskContour::new(Layout { dim: 2 }, &p, &lookup, &|v| vars.name(v)).unwrap().with_laws(&laws)
    }

    fn bound(c: &RiskContour, pieces: &[riskplan_scene::Piece]) -> f64 {
        let refs: Vec<PieceRef<'_>> =
            pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect();
        cells_path_risk(c, &refs, &Frame::centred(&[0.0; 3]), CellEffort::REPORT, &|| false).unwrap().bound
    }

    /// A clone of a contour given other laws folds P over the new laws' ranges, not over
    /// the ranges its original had cached (the cached folded form would keep [−0.1, 0.1]
    /// for a law on [−1, 1], understating the reach and the bound).
    #[test]
    fn a_clone_with_other_laws_folds_over_their_ranges() {
        let a = Distribution::Uniform { low: q("-0.1"), high: q("0.1") };
        let b = Distribution::Uniform { low: q("-1"), high: q("1") };
        let c1 = contour("1/4 - (x1 - d)^2 - x2^2", &[("d", a)]);
        let _ = c1.folded_poly(&[0.0, 0.0, 0.5], &[0, 0, 0]).unwrap();
        let c2 = c1.clone().with_laws(&[(3, &b)]);
        let f = c2.folded_poly(&[0.0, 0.0, 0.5], &[0, 0, 0]).unwrap();
        assert!(f.root[0].lo <= -1.0 && f.root[0].hi >= 1.0, "{:?}", f.root);
    }

    /// The distance from the origin to the segment a → b, in closed form.
    fn d_min(a: [f64; 2], b: [f64; 2]) -> f64 {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let vv = dx * dx + dy * dy;
        let s = if vv > 0.0 { (-(a[0] * dx + a[1] * dy) / vv).clamp(0.0, 1.0) } else { 0.0 };
        ((a[0] + s * dx).powi(2) + (a[1] + s * dy).powi(2)).sqrt()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Sound and tight against the closed form on illustrative-3's disk (w ~ U[0.3, 0.4],
        /// collision iff w ≥ the path's distance from the origin): a random polyline of two
        /// segments, timed over [0, 1], bounded as one trajectory: at least the truth
        /// P(w ≥ d_min), and within 0.02 of it.
        #[test]
        fn the_partition_covers_the_closed_form(
            ax in -1.0f64..1.0, ay in -1.0f64..1.0, bx in -1.0f64..1.0, by in -1.0f64..1.0,
            cx in -1.0f64..1.0, cy in -1.0f64..1.0,
        ) {
            let c = contour("w^2 - x1^2 - x2^2", &[("w", Distribution::Uniform { low: q("0.3"), high: q("0.4") })]);
            let (a, b, e) = ([ax, ay], [bx, by], [cx, cy]);
            let truth = ((0.4 - d_min(a, b).min(d_min(b, e))) / 0.1).clamp(0.0, 1.0);
            let pieces = [
                riskplan_scene::Piece::segment(&a, &b, 0.0, 0.5),
                riskplan_scene::Piece::segment(&b, &e, 0.5, 1.0),
            ];
            let v = bound(&c, &pieces);
            prop_assert!(v >= truth - 1e-12, "bound {v} < truth {truth} for {a:?} {b:?} {e:?}");
            prop_assert!(v <= truth + 0.02, "bound {v} loose against truth {truth} for {a:?} {b:?} {e:?}");
        }
    }

    /// A disk of radius s ~ U[0.9, 1.1] at the origin whose centre is offset along x₁ by
    /// d ~ N(0, 0.05) (the long-piece tests).
    fn sliding_disk() -> RiskContour {
        contour(
            "s^2 - (x1 - d)^2 - x2^2",
            &[
                ("s", Distribution::Uniform { low: q("0.9"), high: q("1.1") }),
                ("d", Distribution::Normal { mean: q("0"), std: q("0.05") }),
            ],
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// A long straight piece beside a small disk: a disk of radius s ~ U[0.9, 1.1]
        /// whose centre is offset along x₁ by d ~ N(0, 0.05), and a piece along x₁ at
        /// height h, 4 to 2000 radii long, covering the centre's range: the offset slides
        /// the disk along the piece, so the event is s ≥ h, P = (1.1 − h)/0.2 clamped — a
        /// closed form sharing no code with the bound. At least the truth, and within 0.02
        /// of it. The long pieces are why [`CELLS_DEEPEST_DEPTH`] exists: with parts no
        /// finer than 2⁻⁶ of the piece, one 98 long beside the disk at h = 1.18 would get a
        /// bound far above 0 where the event is impossible.
        #[test]
        fn a_long_piece_beside_a_small_disk_gets_the_closed_form(
            h in 0.85f64..1.25, before in 2.0f64..1000.0, after in 2.0f64..1000.0, t1 in 0.01f64..100.0,
        ) {
            let c = sliding_disk();
            let truth = ((1.1 - h) / 0.2).clamp(0.0, 1.0);
            let piece = riskplan_scene::Piece::segment(&[-before, h], &[after, h], 0.0, t1);
            let v = bound(&c, &[piece]);
            prop_assert!(v >= truth - 1e-12, "bound {v} < truth {truth} (h {h}, from {before} before to {after} after)");
            prop_assert!(v <= truth + 0.02, "bound {v} loose against truth {truth} (h {h}, from {before} before to {after} after)");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]
        /// The same disk beside a long *curved* piece (a parabola x₂ = h + k·x₁², degree 2 in
        /// time, up to 2000 radii long), where the deeper halving of the time also runs: at
        /// least a Monte Carlo estimate sharing no code with the bound (one (s, d) per
        /// scenario, the curve sampled every 10⁻³ where |x₁| ≤ 2 — elsewhere it is farther than
        /// 1.5 from every centre the laws allow), minus 3.3 σ; and within 0.05 of it.
        #[test]
        fn a_long_curved_piece_beside_a_small_disk_covers_a_monte_carlo_audit(
            h in 0.85f64..1.25, k in -0.002f64..0.002, before in 2.0f64..1000.0, after in 2.0f64..1000.0, seed in 0u64..1000,
        ) {
            let c = sliding_disk();
            let (a0, a1) = (-before, before + after);
            let piece = riskplan_scene::Piece {
                t0: 0.0,
                t1: 1.0,
                coeffs: vec![vec![a0, a1], vec![h + k * a0 * a0, 2.0 * k * a0 * a1, k * a1 * a1]],
            };
            let v = bound(&c, std::slice::from_ref(&piece));
            // the curve where |x₁| ≤ 2, every 10⁻³ in x₁
            let curve: Vec<(f64, f64)> = (0..=4000).map(|j| {
                let x1 = -2.0 + j as f64 * 1e-3;
                (x1, h + k * x1 * x1)
            }).collect();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let normal = rand_distr::Normal::new(0.0, 0.05).unwrap();
            let n = 4000;
            let mut hits = 0;
            for _ in 0..n {
                let s: f64 = rand::Rng::random_range(&mut rng, 0.9..1.1);
                let d: f64 = normal.sample(&mut rng);
                hits += curve.iter().any(|&(x1, x2)| (x1 - d).powi(2) + x2 * x2 <= s * s) as usize;
            }
            let p = hits as f64 / n as f64;
            let margin = 3.3 * (p * (1.0 - p) / n as f64).sqrt() + 2.0 / n as f64;
            prop_assert!(v >= p - margin, "bound {v} below the audit {p} (h {h}, k {k}, {before} before, {after} after)");
            prop_assert!(v <= p + margin + 0.05, "bound {v} loose against the audit {p} (h {h}, k {k}, {before} before, {after} after)");
        }
    }

    /// Gaussian centres (σ = 1/32, about example-d1's) and a Monte Carlo oracle sharing no
    /// code with the bound: one centre per scenario, the closed-form distance from the
    /// segment. The bound is at least the estimate's lower 99.9 % end and, where the event is
    /// not rare, within 1.25× of it.
    #[test]
    fn the_partition_covers_a_monte_carlo_audit_on_a_gaussian_disk() {
        let n01 = || Distribution::Normal { mean: q("0"), std: BigRational::new(1.into(), 32.into()) };
        let c = contour("9/100 - (x1 - w1)^2 - (x2 - w2)^2", &[("w1", n01()), ("w2", n01())]);
        let n = 200_000;
        let normal = rand_distr::Normal::new(0.0, 1.0 / 32.0).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let centres: Vec<[f64; 2]> = (0..n).map(|_| [normal.sample(&mut rng), normal.sample(&mut rng)]).collect();
        let seg_distance =
            |a: [f64; 2], b: [f64; 2], p: [f64; 2]| d_min([a[0] - p[0], a[1] - p[1]], [b[0] - p[0], b[1] - p[1]]);
        for (a, b) in [
            ([-1.0, 0.33], [1.0, 0.33]),
            ([-1.0, 0.36], [1.0, 0.35]),
            ([-1.0, -1.0], [-0.2, 0.29]),
            ([0.31, -0.5], [0.31, 0.5]),
            ([0.4, 0.0], [1.0, 0.0]),
            ([-2.0, 0.45], [2.0, 0.45]),
        ] {
            let hits = centres.iter().filter(|&&p| seg_distance(a, b, p) <= 0.3).count();
            let p = hits as f64 / n as f64;
            let margin = 3.3 * (p * (1.0 - p) / n as f64).sqrt() + 3.0 / n as f64;
            let v = bound(&c, &[riskplan_scene::Piece::segment(&a, &b, 0.0, 1.0)]);
            println!("{a:?} -> {b:?}: whole-path MC {p:.4e}, partition bound {v:.4e}");
            assert!(v >= p - margin, "bound {v} below the audit {p} for {a:?} -> {b:?}");
            if p > 0.01 {
                assert!(v <= 1.25 * (p + margin), "bound {v} loose against the audit {p} for {a:?} -> {b:?}");
            }
        }
    }

    /// A pedestrian (radius 0.3, along x from −5 at a speed v ~ N(1, 0.2)); a robot
    /// crossing its path (x₁ = 0, x₂ from −3 to 3 over [0, 10]) is met in about 44 % of
    /// the scenarios. The moment envelope could only say 1; the partition is within 5 % of
    /// a Monte Carlo audit (one speed per scenario, closest approach in closed form).
    #[test]
    fn the_partition_bounds_the_crossing_of_a_pedestrian_of_uncertain_speed() {
        let c =
            contour("9/100 - (x1 + 5 - v*t)^2 - x2^2", &[("v", Distribution::Normal { mean: q("1"), std: q("0.2") })]);
        let v = bound(&c, &[riskplan_scene::Piece::segment(&[0.0, -3.0], &[0.0, 3.0], 0.0, 10.0)]);
        let normal = rand_distr::Normal::new(1.0, 0.2).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(44);
        let n = 200_000;
        let hits = (0..n)
            .filter(|_| {
                let s: f64 = normal.sample(&mut rng);
                let (p0, d) = ([5.0, -3.0], [-s, 0.6]);
                let t = (-(p0[0] * d[0] + p0[1] * d[1]) / (d[0] * d[0] + d[1] * d[1])).clamp(0.0, 10.0);
                ((p0[0] + d[0] * t).powi(2) + (p0[1] + d[1] * t).powi(2)).sqrt() <= 0.3
            })
            .count();
        let p = hits as f64 / n as f64;
        let margin = 3.3 * (p * (1.0 - p) / n as f64).sqrt();
        println!("crossing a pedestrian: whole-path MC {p:.4}, partition bound {v:.4}");
        assert!(v >= p - margin, "bound {v} below the audit {p}");
        assert!(v <= 1.05 * (p + margin), "bound {v} loose against the audit {p}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// The screen before the partition keeps every part of a piece that can meet the
        /// obstacle (closed form: a segment meets the disk of radius w ~ U[0.3, 0.4] at the
        /// origin for some w iff its distance from the origin is ≤ 0.4), through the tree of
        /// hulls and the parts' boxes, in the identity frame and in a shifted, scaled one; and
        /// it drops the parts far from it (distance ≥ 0.4 + the part's length: its box is then
        /// clear of the disk).
        #[test]
        fn the_screen_keeps_every_part_that_may_meet(
            pts in proptest::collection::vec((-2.0f64..2.0, -2.0f64..2.0), 2..12),
            shift in -3.0f64..3.0, e in -3i32..3i32,
        ) {
            let c = contour("w^2 - x1^2 - x2^2", &[("w", Distribution::Uniform { low: q("0.3"), high: q("0.4") })]);
            let pieces: Vec<riskplan_scene::Piece> = pts
                .windows(2)
                .enumerate()
                .map(|(i, w)| riskplan_scene::Piece::segment(&[w[0].0, w[0].1], &[w[1].0, w[1].1], i as f64, i as f64 + 1.0))
                .collect();
            let refs: Vec<PieceRef<'_>> = pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect();
            let n_parts = 1u64 << SCREEN_DEPTH;
            for (k, frame) in [Frame::centred(&[0.0; 3]), Frame { center: vec![shift, -shift, 1.0], exponents: vec![e, -e, 1] }].into_iter().enumerate() {
                let folded = c.folded_poly(&frame.center, &frame.exponents).unwrap();
                let near = parts_near(&folded, &PieceBoxes::new(&refs, 2), &frame, None);
                for (i, w) in pts.windows(2).enumerate() {
                    for j in 0..n_parts {
                        let at = |s: f64| [w[0].0 + (w[1].0 - w[0].0) * s, w[0].1 + (w[1].1 - w[0].1) * s];
                        let (a, b) = (at(j as f64 / n_parts as f64), at((j + 1) as f64 / n_parts as f64));
                        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
                        let d = d_min(a, b);
                        let kept = near.contains(&(i, SCREEN_DEPTH, j));
                        if d <= 0.4 + 1e-9 {
                            prop_assert!(kept, "part {j} of piece {i} at distance {d} dropped in {frame:?}");
                        }
                        // (in the identity frame P's squares are ranged exactly; a shifted frame
                        // expands them and the screen may keep more)
                        if k == 0 && d >= 0.4 + 1.5 * len + 1e-6 {
                            prop_assert!(!kept, "part {j} of piece {i} at distance {d}, length {len} kept");
                        }
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The reach of a disk ‖x − m‖ ≤ w, w ~ U[0.3, 0.4], in a region around it, against
        /// the closed form (a point may be met iff it is within 0.4 of m): a box it clears is
        /// inside the region and farther than 0.4 from m, whatever the frame; a box outside
        /// the region is never cleared; and in the disk's own frame the reach is tight (a box
        /// beyond 0.45 + 1 % of the region on a side is cleared).
        #[test]
        fn the_reach_clears_only_boxes_the_disk_cannot_meet(
            m in (-5.0f64..5.0, -5.0f64..5.0),
            half in 1.0f64..20.0,
            shift in -3.0f64..3.0, e in -3i32..3i32,
            boxes in proptest::collection::vec((0.0f64..1.0, 0.0f64..1.0, 0.0f64..0.3, 0.0f64..0.3), 40),
        ) {
            let text = format!("w^2 - (x1 - ({}))^2 - (x2 - ({}))^2", m.0, m.1);
            let c = contour(&text, &[("w", Distribution::Uniform { low: q("0.3"), high: q("0.4") })]);
            let region = [(m.0 - half, m.0 + half), (m.1 - 0.5 * half, m.1 + 2.0 * half), (0.0, 1.0)];
            for (k, frame) in [Frame { center: vec![m.0, m.1, 0.5], exponents: vec![0, 0, 0] }, Frame { center: vec![shift, -shift, 1.0], exponents: vec![e, -e, 1] }].into_iter().enumerate() {
                let folded = c.folded_poly(&frame.center, &frame.exponents).unwrap();
                let reach = Reach::new(&folded, &frame, &region).unwrap();
                for &(u, v, wx, wy) in &boxes {
                    // a box of the region (sides up to 30 % of it), at any time
                    let lo = [region[0].0 + u * (region[0].1 - region[0].0), region[1].0 + v * (region[1].1 - region[1].0)];
                    let hi = [lo[0] + wx * (region[0].1 - region[0].0), lo[1] + wy * (region[1].1 - region[1].0)];
                    let bx = [Interval::new(lo[0], hi[0]), Interval::new(lo[1], hi[1]), Interval::new(0.25, 0.75)];
                    let inside = hi[0] <= region[0].1 && hi[1] <= region[1].1;
                    // the closed form: the box's distance from m
                    let gap = |l: f64, h: f64, c: f64| (l - c).max(c - h).max(0.0);
                    let d = gap(lo[0], hi[0], m.0).hypot(gap(lo[1], hi[1], m.1));
                    if reach.clears(&bx) {
                        prop_assert!(inside, "box {bx:?} outside the region {region:?} cleared");
                        prop_assert!(d > 0.4, "box {bx:?} at {d} from the disk cleared in {frame:?}");
                    }
                    let beyond = 0.45 + 0.01 * 3.0 * half;
                    if k == 0 && inside && (lo[0] - m.0 > beyond || m.0 - hi[0] > beyond || lo[1] - m.1 > beyond || m.1 - hi[1] > beyond) {
                        prop_assert!(reach.clears(&bx), "box {bx:?} at {d} from the disk kept: {reach:?}");
                    }
                }
                let out = [Interval::new(region[0].1 - 0.1, region[0].1 + 0.1), Interval::new(m.1 + 0.4 * half, m.1 + 0.5 * half), Interval::new(0.0, 1.0)];
                prop_assert!(!reach.clears(&out), "a box across the region's side cleared");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// A disk whose centre is uncertain along x1 (‖x − (m + d, m₂)‖ ≤ 0.5, d ~ U[−0.1,
        /// 0.1]) in a region up to 80 times its size: the reach box, in the disk's frame,
        /// is within 0.05 + 1 % of the region of the closed form (0.6 along x1, 0.5 along
        /// x2) — the shells of [`REACH_SHELLS`]; one slab from the region's edge gave about
        /// 2 + 0.1·half along x1 — and sound (nothing within 0.6 / 0.5 of m is cleared).
        #[test]
        fn the_reach_of_an_uncertain_centre_is_tight_in_a_large_region(
            m in (-5.0f64..5.0, -5.0f64..5.0),
            half in 5.0f64..40.0,
        ) {
            let text = format!("1/4 - (x1 - ({}) - d)^2 - (x2 - ({}))^2", m.0, m.1);
            let c = contour(&text, &[("d", Distribution::Uniform { low: q("-0.1"), high: q("0.1") })]);
            let region = [(m.0 - half, m.0 + half), (m.1 - half, m.1 + half), (0.0, 1.0)];
            let frame = Frame { center: vec![m.0, m.1, 0.5], exponents: vec![0, 0, 0] };
            let folded = c.folded_poly(&frame.center, &frame.exponents).unwrap();
            let reach = Reach::new(&folded, &frame, &region).unwrap();
            let sides = reach.sides.clone().unwrap();
            let slack = 0.05 + 0.01 * 2.0 * half;
            for (v, want) in [(0, 0.6), (1, 0.5)] {
                let centre = [m.0, m.1][v];
                let (a, b) = sides[v];
                prop_assert!(a <= centre - want && b >= centre + want, "axis {v}: {sides:?} cuts into the disk");
                prop_assert!(a >= centre - want - slack && b <= centre + want + slack, "axis {v}: {sides:?} loose (half {half})");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The grid of the reaches never leaves out an obstacle whose reach does not clear
        /// the pieces: against the walk of every reach ([`Reach::clears_all`], which knows
        /// nothing of the grid), on reach boxes of all sizes (some unbounded, some of another
        /// region, some clearing all, some absent) and pieces anywhere in the region.
        #[test]
        fn the_reach_grid_keeps_every_obstacle_a_trajectory_may_meet(
            cells in proptest::collection::vec((0u8..8, -1.2f64..1.2, -1.2f64..1.2, 0.0f64..0.8, 0.0f64..0.8), 1..300),
            small in 0.01f64..1.0,
            ends in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 2..7),
            scale_exp in -60i32..60,
        ) {
            let k = (scale_exp as f64).exp2();
            // widened as the kernel widens it (REACH_REGION_MARGIN): the parts' boxes
            // overshoot the pieces' ends and times by roundings
            let region: Vec<(f64, f64)> = vec![(-1.01 * k, 1.01 * k), (-1.01 * k, 1.01 * k), (-0.01, 1.01)];
            let reaches: Vec<Option<std::sync::Arc<Reach>>> = cells
                .iter()
                .map(|&(kind, x, y, w, h)| {
                    // boxes from a hundredth of the region to most of it
                    let (w, h) = (w * small, h * small);
                    let sides = match kind {
                        0 => return None,
                        1 => None,
                        2 => Some(vec![(f64::NEG_INFINITY, x * k), (y * k, (y + h) * k), (0.0, 1.0)]),
                        3 => {
                            let other: Vec<(f64, f64)> = vec![(-2.0 * k, 2.0 * k), (-k, k), (0.0, 1.0)];
                            return Some(std::sync::Arc::new(Reach { region: other, sides: Some(vec![(x * k, (x + w) * k), (y * k, (y + h) * k), (0.0, 1.0)]), outside: 0.0 }));
                        }
                        _ => Some(vec![(x * k, (x + w) * k), (y * k, (y + h) * k), (0.0, 0.5)]),
                    };
                    Some(std::sync::Arc::new(Reach { region: region.clone(), sides, outside: 1e-9 }))
                })
                .collect();
            let pieces: Vec<riskplan_scene::Piece> = ends
                .windows(2)
                .map(|w| riskplan_scene::Piece::segment(&[w[0].0 * k, w[0].1 * k], &[w[1].0 * k, w[1].1 * k], 0.0, 1.0))
                .collect();
            let refs: Vec<PieceRef<'_>> = pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect();
            let boxes = PieceBoxes::new(&refs, 2);
            let grid = ReachGrid::new(&region, &reaches).expect("a grid of a finite region");
            match grid.candidates(&boxes) {
                Some(marked) => {
                    for (i, r) in reaches.iter().enumerate() {
                        let clears = r.as_ref().is_some_and(|r| r.clears_all(&boxes));
                        prop_assert!(marked[i] || clears, "obstacle {i} left out: {r:?}");
                    }
                }
                // only when a part's box leaves the region (never here: the pieces lie well
                // inside it)
                None => prop_assert!(false, "a part's box left the region: {:?}", boxes.parts.iter().flatten().find(|b| b.iter().zip(&region).any(|(x, &(lo, hi))| x.lo < lo || x.hi > hi))),
            }
        }
    }

    // ---- adversarial screen tests ----

    /// The obstacles the screen is attacked with: (text, laws).
    fn review_obstacle(kind: usize, a: i64, b: i64) -> RiskContour {
        let u = |lo: &str, hi: &str| Distribution::Uniform { low: q(lo), high: q(hi) };
        let n = |m: &str, s: &str| Distribution::Normal { mean: q(m), std: q(s) };
        match kind {
            // a disk at (a, b)/64, radius w
            0 => contour(&format!("w^2 - (x1 - {a}/64)^2 - (x2 - {b}/64)^2"), &[("w", u("0.3", "0.4"))]),
            // moving pedestrian of uncertain speed
            1 => contour("9/100 - (x1 + 5 - v*t)^2 - x2^2", &[("v", n("1", "0.2"))]),
            // parameters mixed with x and t, odd powers of ranges around 0
            2 => contour("w*x1*t + v*x2^3 - x1^2*t^2 - 1/4", &[("w", u("-1", "1")), ("v", n("0", "0.5"))]),
            // high degree in x and ω
            3 => contour("w^3 - x1^4 - (x2 - v)^2", &[("w", u("-0.5", "1")), ("v", n("0", "0.3"))]),
            // time in the obstacle, ω odd and even, cross term
            4 => contour(&format!("w^5*t - (x1 - {a}/64)^2 - (x2 - {b}/64)^2 + v*x1*x2"), &[("w", u("-1", "1.2")), ("v", n("0", "0.1"))]),
            // a tiny disk (radius ~ 2^-530) near the origin: subnormal squares
            6 => contour(&format!("(w*w0)^2 - (x1 - {a}/64*w0)^2 - (x2 - {b}/64*w0)^2").replace("w0", "(1/3514776401986872174070733209129673327241950873673372369609965291102998109899599898686750536018664732148375711432438199315006457855854921632037902485050909261824)"), &[("w", u("0.3", "0.4"))]),
            // a disk at 2^40
            7 => contour(&format!("w^2 - (x1 - 1099511627776 - {a}/64)^2 - (x2 - {b}/64)^2"), &[("w", u("0.3", "0.4"))]),
            // a disk far from the origin (10^6 + a, b)
            _ => contour(&format!("w^2 - (x1 - 1000000 - {a}/64)^2 - (x2 - {b}/64)^2"), &[("w", u("0.3", "0.4"))]),
        }
    }

    /// P exactly at (x, t, ω).
    fn exact_p(c: &RiskContour, xt: &[BigRational], omega: &[BigRational]) -> BigRational {
        let mut vals: Vec<BigRational> = xt.to_vec();
        vals.extend(omega.iter().cloned());
        c.poly().eval(&vals)
    }

    fn r(f: f64) -> BigRational {
        BigRational::from_float(f).unwrap()
    }

    /// A piece of degree `deg` in local time around `(cx, cy)`, written in absolute time.
    fn review_piece(t0: f64, h: f64, local: &[(f64, f64)], cx: f64, cy: f64) -> riskplan_scene::Piece {
        // x(t) = Σ a_k ((t − t0)/max(h, 1))^k, expanded in t
        let sc = 1.0 / h.max(1.0);
        let mut rows = vec![vec![0.0; local.len()], vec![0.0; local.len()]];
        for (k, &(ax, ay)) in local.iter().enumerate() {
            // (sc·(t − t0))^k = Σ_j C(k, j) sc^k t^j (−t0)^(k−j)
            let (row_x, row_y) = rows.split_at_mut(1);
            for (j, (rx, ry)) in row_x[0].iter_mut().zip(row_y[0].iter_mut()).enumerate().take(k + 1) {
                let c = riskplan_math::contour::bounds::binomial_f64(k as u32, j as u32)
                    * sc.powi(k as i32)
                    * (-t0).powi((k - j) as i32);
                *rx += ax * c;
                *ry += ay * c;
            }
        }
        rows[0][0] += cx;
        rows[1][0] += cy;
        riskplan_scene::Piece { t0, t1: t0 + h, coeffs: rows }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(40))]
        /// Every part the screen drops has P < 0 at every sampled (t, ω) of the part and the
        /// laws' ranges, evaluated exactly (no interval code), for pieces of degree 0–5,
        /// zero-length pieces, moving and mixed obstacles, in frames near, far, and with
        /// extreme exponents; with and without a reach (region: the pieces' hull, widened).
        #[test]
        fn review_dropped_parts_are_negative_at_every_sample(
            kind in 0usize..8, a in -128i64..128, b in -128i64..128,
            pieces in proptest::collection::vec(
                (-1.0f64..3.0, prop_oneof![Just(0.0), 1e-9f64..1e-6, 0.01f64..3.0],
                 proptest::collection::vec((-1.5f64..1.5, -1.5f64..1.5), 1..7),
                 -2.5f64..2.5, -2.5f64..2.5),
                1..6),
            fc in (-3.0f64..3.0, -3.0f64..3.0, -3.0f64..5.0),
            fe in prop_oneof![(-4i32..4, -4i32..4, -4i32..4), (-60i32..60, -60i32..60, -60i32..60), Just((1000, -1000, 1000)), Just((-1000, 1000, -1000))],
        ) {
            let c = review_obstacle(kind, a, b);
            let (off, sc, es) = match kind { 5 => (1_000_000.0, 1.0, 0), 6 => (0.0, 0.5f64.powi(530), -530), 7 => (1099511627776.0, 1.0, 0), _ => (0.0, 1.0, 0) };
            let pieces: Vec<riskplan_scene::Piece> = pieces
                .iter()
                .map(|(t0, h, local, cx, cy)| {
                    let local: Vec<(f64, f64)> = local.iter().map(|&(x, y)| (x * sc, y * sc)).collect();
                    review_piece(*t0, *h, &local, cx * sc + off, cy * sc)
                })
                .collect();
            let refs: Vec<PieceRef<'_>> = pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect();
            let boxes = PieceBoxes::new(&refs, 2);
            let frames = [
                Frame::centred(&[off, 0.0, 0.0]),
                Frame { center: vec![fc.0 * sc + off, fc.1 * sc, fc.2], exponents: vec![fe.0 + es, fe.1 + es, fe.2] },
            ];
            // the region of the reach: the pieces' hull, widened (any region is sound)
            let mut region: Vec<(f64, f64)> = vec![(f64::INFINITY, f64::NEG_INFINITY); 3];
            for p in &refs {
                for (k, side) in crate::scene::interval_hull(*p).unwrap_or_default().iter().enumerate().take(2) {
                    region[k] = (region[k].0.min(side.lo), region[k].1.max(side.hi));
                }
                region[2] = (region[2].0.min(p.t0), region[2].1.max(p.t1));
            }
            for side in &mut region {
                let m = 0.01 * (side.1 - side.0) + 1e-300;
                *side = (side.0 - m, side.1 + m);
            }
            for (frame, with_reach) in frames.iter().flat_map(|f| [(f.clone(), false), (f.clone(), true)]) {
                let Some(folded) = c.folded_poly(&frame.center, &frame.exponents) else { continue };
                let reach = if with_reach { Reach::new(&folded, &frame, &region) } else { None };
                let near = parts_near(&folded, &boxes, &frame, reach.as_ref());
                let omegas: Vec<Vec<BigRational>> = {
                    let grids: Vec<Vec<BigRational>> = folded
                        .root
                        .iter()
                        .map(|w| (0..=4).map(|j| r(w.lo) + (r(w.hi) - r(w.lo)) * BigRational::new(j.into(), 4.into())).collect())
                        .collect();
                    let mut all = vec![Vec::new()];
                    for g in grids {
                        all = all.iter().flat_map(|o| g.iter().map(move |v| { let mut o = o.clone(); o.push(v.clone()); o })).collect();
                    }
                    all
                };
                let n_parts = 1u64 << SCREEN_DEPTH;
                for (i, p) in refs.iter().enumerate() {
                    for k in 0..n_parts {
                        if near.contains(&(i, SCREEN_DEPTH, k)) {
                            continue;
                        }
                        for j in 0..=2i64 {
                            let s = BigRational::new((2 * k as i64 + j).into(), (2 * n_parts as i64).into());
                            let t = r(p.t0) + (r(p.t1) - r(p.t0)) * &s;
                            let mut xt: Vec<BigRational> = p
                                .coeffs
                                .iter()
                                .map(|row| row.iter().rev().fold(BigRational::from_integer(0.into()), |acc, &cf| acc * &t + r(cf)))
                                .collect();
                            xt.push(t.clone());
                            for o in &omegas {
                                let v = exact_p(&c, &xt, o);
                                prop_assert!(v < BigRational::from_integer(0.into()),
                                    "part {k} of piece {i} dropped, yet P = {} ≥ 0 at s = {s}, ω = {o:?}, kind {kind}, frame {frame:?}, piece {p:?}",
                                    num_traits::ToPrimitive::to_f64(&v).unwrap_or(f64::NAN));
                            }
                        }
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// The whole bound (screen and partition) in a random frame is at least a Monte Carlo
        /// estimate of the event's probability (ω drawn from the laws, t sampled densely:
        /// a lower estimate of P(E)), minus 3.3 σ.
        #[test]
        fn review_bound_in_any_frame_covers_a_sampled_audit(
            kind in 0usize..8, a in -64i64..64, b in -64i64..64,
            pieces in proptest::collection::vec(
                (0.0f64..2.0, 0.01f64..2.0,
                 proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 1..6),
                 -1.5f64..1.5, -1.5f64..1.5),
                1..4),
            fc in (-3.0f64..3.0, -3.0f64..3.0, -3.0f64..5.0),
            fe in prop_oneof![(-4i32..4, -4i32..4, -4i32..4), (-40i32..40, -40i32..40, -40i32..40)],
            seed in 0u64..1000,
        ) {
            use rand::Rng;
            let c = review_obstacle(kind, a, b);
            let (off, sc, es) = match kind { 5 => (1_000_000.0, 1.0, 0), 6 => (0.0, 0.5f64.powi(530), -530), 7 => (1099511627776.0, 1.0, 0), _ => (0.0, 1.0, 0) };
            let pieces: Vec<riskplan_scene::Piece> = pieces
                .iter()
                .map(|(t0, h, local, cx, cy)| {
                    let local: Vec<(f64, f64)> = local.iter().map(|&(x, y)| (x * sc, y * sc)).collect();
                    review_piece(*t0, *h, &local, cx * sc + off, cy * sc)
                })
                .collect();
            let refs: Vec<PieceRef<'_>> = pieces.iter().map(|p| PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }).collect();
            let frame = Frame { center: vec![fc.0 * sc + off, fc.1 * sc, fc.2], exponents: vec![fe.0 + es, fe.1 + es, fe.2] };
            // (the audit evaluates P expanded, in floats: far or tiny disks are left to the exact test)
            if kind >= 5 { return Ok(()); }
            let Some(bnd) = cells_path_risk(&c, &refs, &frame, CellEffort::PLAN.with_slack(1e-3), &|| false) else { return Ok(()) };
            // the laws, sampled
            let folded = c.folded_poly(&frame.center, &frame.exponents).unwrap();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let n = 3000;
            let pf = c.poly().map_coeffs(|x| num_traits::ToPrimitive::to_f64(x).unwrap());
            let mut hits = 0;
            for _ in 0..n {
                let omega: Vec<f64> = folded.params.iter().enumerate().map(|(k, _)| {
                    let (lo, hi) = (folded.root[k].lo, folded.root[k].hi);
                    // uniform laws: their range; normal: μ ± 9σ, drawn from the normal
                    match (kind, k) {
                        (1, 0) => rand_distr::Normal::new(1.0, 0.2).unwrap().sample(&mut rng),
                        (2, 1) => rand_distr::Normal::new(0.0, 0.5).unwrap().sample(&mut rng),
                        (3, 1) => rand_distr::Normal::new(0.0, 0.3).unwrap().sample(&mut rng),
                        (4, 1) => rand_distr::Normal::new(0.0, 0.1).unwrap().sample(&mut rng),
                        _ => rng.random_range(lo..=hi),
                    }
                }).collect();
                let met = refs.iter().any(|p| (0..=400).any(|j| {
                    let t = p.t0 + (p.t1 - p.t0) * j as f64 / 400.0;
                    let mut v: Vec<f64> = p.coeffs.iter().map(|row| row.iter().rev().fold(0.0, |acc, &cf| acc * t + cf)).collect();
                    v.push(t);
                    v.extend(&omega);
                    pf.eval(&v) >= 1e-9
                }));
                hits += met as usize;
            }
            let pm = hits as f64 / n as f64;
            let margin = 3.3 * (pm * (1.0 - pm) / n as f64).sqrt() + 2.0 / n as f64;
            prop_assert!(bnd.bound >= pm - margin, "bound {} below the audit {pm} (kind {kind}, frame {frame:?}, pieces {pieces:?})", bnd.bound);
        }
    }

    /// A trajectory bounded at once is not the sum of its pieces: four pieces along the
    /// uniform disk at distance 0.35 share one event {w ≥ 0.35} of probability 1/2.
    #[test]
    fn pieces_along_one_obstacle_share_their_event() {
        let c = contour("w^2 - x1^2 - x2^2", &[("w", Distribution::Uniform { low: q("0.3"), high: q("0.4") })]);
        let pts = [[-1.0, 0.35], [-0.3, 0.35], [0.0, 0.35], [0.3, 0.35], [1.0, 0.35]];
        let pieces: Vec<riskplan_scene::Piece> = pts
            .windows(2)
            .enumerate()
            .map(|(i, w)| riskplan_scene::Piece::segment(&w[0], &w[1], i as f64, i as f64 + 1.0))
            .collect();
        let v = bound(&c, &pieces);
        assert!((0.5..0.52).contains(&v), "{v}");
    }

    /// With a slack the partition stops early, yet its bound still covers the closed form
    /// and exceeds it by at most the slack (plus the 2 % relative tolerance): the
    /// undecided boxes are counted whole. Segment at distance d from the disk ‖x‖ ≤ w,
    /// w ~ U[0.3, 0.4]: P = (0.4 − d)/0.1.
    #[test]
    fn a_slack_ends_the_partition_early_and_stays_an_upper_bound() {
        let c = contour("w^2 - x1^2 - x2^2", &[("w", Distribution::Uniform { low: q("0.3"), high: q("0.4") })]);
        let p = riskplan_scene::Piece::segment(&[-1.0, 0.3512], &[1.0, 0.3512], 0.0, 1.0);
        let r = [PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs }];
        let truth = (0.4 - 0.3512) / 0.1;
        let frame = Frame::centred(&[0.0; 3]);
        let full = cells_path_risk(&c, &r, &frame, CellEffort::REPORT, &|| false).unwrap();
        for slack in [1e-3, 1e-2, 0.1] {
            let b = cells_path_risk(&c, &r, &frame, CellEffort::REPORT.with_slack(slack), &|| false).unwrap();
            assert!(b.bound >= truth, "slack {slack}: {} below the closed form {truth}", b.bound);
            assert!(b.bound <= truth * 1.02 + slack + 1e-9, "slack {slack}: {} vs {truth}", b.bound);
            assert!(b.boxes <= full.boxes, "slack {slack}: {} boxes, {} without", b.boxes, full.boxes);
        }
        assert_eq!(CellEffort::PLAN.with_slack(f64::NAN), CellEffort::PLAN);
    }

    /// An obstacle with a parameter of no distribution function (a normal of a deviation
    /// whose inverse overflows) is left to the moment envelopes.
    #[test]
    fn no_partition_without_laws() {
        let tiny = Distribution::Normal {
            mean: q("0.1"),
            std: BigRational::new(1.into(), num_bigint::BigInt::from(10).pow(400)),
        };
        let c = contour("w - x1^2 - x2^2", &[("w", tiny)]);
        let p = riskplan_scene::Piece::segment(&[-1.0, 0.5], &[1.0, 0.5], 0.0, 1.0);
        let r = PieceRef { t0: p.t0, t1: p.t1, coeffs: &p.coeffs };
        assert!(cells_path_risk(&c, &[r], &Frame::centred(&[0.0; 3]), CellEffort::REPORT, &|| false).is_none());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// Gamma and beta parameters of non-integer shapes (moments/incomplete.rs) against the
        /// closed form of a disk of uncertain size about the origin, the truth from statrs'
        /// distribution functions (independent code, accurate to about 10⁻¹⁰): a disk of
        /// squared radius w ~ Γ(2.5, 0.1) (hit iff w ≥ d²) and one of radius
        /// r ~ 0.3 + 0.1·Beta(3.39, 4.93) (hit iff r ≥ d); at least the truth, within 0.02.
        #[test]
        fn the_partition_covers_the_closed_form_with_gamma_and_beta_sizes(
            dg in 0.0f64..0.9, db in 0.28f64..0.45, theta in 0.0f64..6.3, half in 0.05f64..1.0,
        ) {
            use statrs::distribution::{Beta, ContinuousCDF, Gamma};
            // a segment at distance d from the origin (its closest point at the middle)
            let segment = |d: f64| {
                let (c, n) = ([d * theta.cos(), d * theta.sin()], [-theta.sin(), theta.cos()]);
                let (a, b) = ([c[0] - half * n[0], c[1] - half * n[1]], [c[0] + half * n[0], c[1] + half * n[1]]);
                ([riskplan_scene::Piece::segment(&a, &b, 0.0, 1.0)], d_min(a, b))
            };
            let (pieces, d) = segment(dg);
            let g = contour("w - x1^2 - x2^2", &[("w", Distribution::Gamma { shape: q("2.5"), scale: q("0.1") })]);
            let truth = Gamma::new(2.5, 10.0).unwrap().sf(d * d);
            let v = bound(&g, &pieces);
            prop_assert!(v >= truth - 1e-9, "gamma: bound {v} < truth {truth} at distance {d}");
            prop_assert!(v <= truth + 0.02, "gamma: bound {v} loose against truth {truth} at distance {d}");
            let (pieces, d) = segment(db);
            let beta = Distribution::Beta { alpha: q("3.39"), beta: q("4.93"), low: q("0.3"), high: q("0.4") };
            let bt = contour("w^2 - x1^2 - x2^2", &[("w", beta)]);
            let truth = if d <= 0.3 { 1.0 } else if d >= 0.4 { 0.0 } else { Beta::new(3.39, 4.93).unwrap().sf((d - 0.3) / 0.1) };
            let v = bound(&bt, &pieces);
            prop_assert!(v >= truth - 1e-9, "beta: bound {v} < truth {truth} at distance {d}");
            prop_assert!(v <= truth + 0.02, "beta: bound {v} loose against truth {truth} at distance {d}");
            // the same radius known by its moments only (orders ≤ 8, no support): sound,
            // and small once the path is a few deviations (about 0.016) beyond the mean
            let raw = Distribution::Beta { alpha: q("3.39"), beta: q("4.93"), low: q("0.3"), high: q("0.4") }
                .raw_moments(8)
                .unwrap();
            let mt = contour("w^2 - x1^2 - x2^2", &[("w", Distribution::Moments { raw: raw[1..].to_vec() })]);
            let v = bound(&mt, &pieces);
            prop_assert!(v >= truth - 1e-9, "moments: bound {v} < truth {truth} at distance {d}");
            if d >= 0.41 {
                prop_assert!(v <= 0.01, "moments: bound {v} at distance {d}");
            }
        }
    }

    /// Far from the origin and small: illustrative-3's disk scaled by 10⁻³ and moved to
    /// (10⁶, 10⁶) — P's terms are 10¹², its values 10⁻⁷, so in the scene's coordinates every
    /// interval would hold 0 (the bound 1). In the scene's frame (centred, scaled by 2⁻¹⁰)
    /// the partition matches the closed form as at the origin. Evaluating in the identity
    /// frame instead gives 1 (checked below: the frame is what makes it work).
    #[test]
    fn the_partition_is_tight_far_from_the_origin() {
        let c = contour(
            "w^2 - (x1 - 1000000)^2 - (x2 - 1000000)^2",
            &[("w", Distribution::Uniform { low: q("0.0003"), high: q("0.0004") })],
        );
        let frame = Frame { center: vec![1e6, 1e6, 0.5], exponents: vec![-10, -10, -1] };
        for (a, b) in [
            ([-1.0, 0.35], [1.0, 0.35]),
            ([-1.0, -1.0], [1.0, 1.0]),
            ([0.2, -1.0], [0.37, 1.0]),
            ([0.5, 0.5], [1.0, 0.2]),
        ] {
            let truth = ((0.4 - d_min(a, b)) / 0.1).clamp(0.0, 1.0);
            let far = |p: [f64; 2]| [1e6 + 1e-3 * p[0], 1e6 + 1e-3 * p[1]];
            let piece = riskplan_scene::Piece::segment(&far(a), &far(b), 0.0, 1.0);
            let r = PieceRef { t0: piece.t0, t1: piece.t1, coeffs: &piece.coeffs };
            let v = cells_path_risk(&c, &[r], &frame, CellEffort::REPORT, &|| false).unwrap().bound;
            assert!(v >= truth - 1e-9 && v <= truth + 0.02, "{a:?} -> {b:?}: bound {v}, truth {truth}");
            if truth == 0.0 {
                let id =
                    cells_path_risk(&c, &[r], &Frame::centred(&[0.0; 3]), CellEffort::PLAN, &|| false).unwrap().bound;
                assert!(id >= 0.5, "uncentred: {id}");
            }
        }
    }
}
