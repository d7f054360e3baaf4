//! The partition's machinery: a box's coefficient ranges, the control nets of a piece's parts, their restriction to a box, and the cells of the partition by probability (docs/design.md §5.14).

use super::*;

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
pub(super) fn monomials_into(bx: &[Interval], betas: &[Beta], out: &mut Vec<Interval>) {
    out.clear();
    out.extend(
        betas.iter().map(|beta| beta.iter().fold(Interval::point(1.0), |acc, &(k, e)| acc * power_range(bx[k], e))),
    );
}

/// What a box is for a part (or for the whole trajectory).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum State {
    Outside,
    Hit,
    Unknown,
}

/// A parameter monomial: (index into the partition's parameters, exponent) pairs.
type Beta = Vec<(usize, u32)>;

/// A part of a trajectory's control net: (piece, depth, index).
pub(super) type Part = (usize, u32, u64);

/// One level of a piece's control net: per part, `None` not computed yet, `Some(None)` not
/// restrictable, else its coefficients.
type Level = Vec<Option<Option<Vec<Coef>>>>;

/// The control nets of a trajectory's pieces in interval arithmetic, computed on demand.
pub(super) struct Nets<'a> {
    /// P = Σ_β c_β(x, t)·ω^β: each parameter monomial β (as indices into the partition's
    /// parameters and exponents) ...
    pub(super) betas: std::rc::Rc<[Beta]>,
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
    pub(super) fn new(
        contour: &RiskContour,
        params: &[Var],
        pieces: &'a [PieceRef<'a>],
        frame: &Frame,
    ) -> Option<Nets<'a>> {
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
    pub(super) fn state(
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
pub(super) struct Centre {
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
pub(super) struct Cell {
    pub(super) mass: f64,
    pub(super) bx: Vec<Interval>,
    /// Enclosures of each parameter's distribution function at the box's ends.
    pub(super) ends: Vec<(Interval, Interval)>,
    pub(super) parts: Vec<Part>,
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
