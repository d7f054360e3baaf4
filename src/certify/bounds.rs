//! Certifying a piece against one obstacle with several bounds (docs/design.md §5.13) —
//! beyond the paper.
//!
//! A piece is safe for an obstacle when its local time interval [0, 1] is covered by
//! dyadic sub-intervals, each proven by **one** bound on the whole sub-interval: Cantelli's
//! constraints (g₁ > 0, g₂ > 0), zero risk from bounded support (P < 0 for every parameter
//! value, §3.7), or a shifted moment bound of order 4, 6 or 8 with a shift b fixed for the
//! sub-interval (H > 0 and E\[P\] < 0, §3.8). Never a point-wise minimum of bounds: each
//! proof covers its whole sub-interval. Every proof is an outward-rounded interval
//! computation: the restricted polynomials' coefficients enclose the exact ones, the
//! sub-interval is mapped to [0, 1] in interval arithmetic, and the Bernstein hull's lower
//! end must be positive (or the support form's upper end negative).
//!
//! The search splits a sub-interval in two when no bound proves it, up to
//! [`COVER_MAX_DEPTH`] and [`COVER_MAX_NODES`]; it gives up early at a point where E\[P\] ≥ 0
//! or where every bound is above Δ in floating point (no bound could prove a sub-interval
//! containing it — giving up is always sound: the piece is then not certified).

use super::bernstein::bernstein_hull;
use super::compose::{interval_substitutions, PieceRef};
use super::fast::{CompiledContour, FPoly, CAPACITY};
use crate::contour::bounds::{best_shift, binomial_f64, interval_pow as pow, moment_bound_f64, monomial_range, MOMENT_ORDERS};
use crate::contour::{cantelli_bound_f64, BoundKind, RiskContour};
use crate::poly::{rational_to_f64, Interval, UPoly, Var};
use num_rational::BigRational;
use std::cell::OnceCell;

/// Deepest split of a piece's local time (sub-intervals at least 2⁻¹² of the piece):
/// a sub-interval that needs more lies on the Δ-contour of every bound, where the piece
/// would be within ~2⁻²⁴ relative of the bound's limit anyway.
pub const COVER_MAX_DEPTH: u32 = 12;

/// Most sub-intervals examined per piece and obstacle (bounds the work of a grazing piece).
pub const COVER_MAX_NODES: usize = 128;

/// Evenly spaced local times (besides a hint) at which a piece is checked for hopelessness
/// before any sub-interval proof: 1/16 of the piece apart.
pub const HOPELESS_PROBES: usize = 16;

/// Most parameter boxes examined by one zero-risk proof on one sub-interval.
pub const SUPPORT_MAX_BOXES: usize = 48;

/// A point is hopeless (no bound can prove a sub-interval that contains it) when every
/// bound computed there in floating point exceeds Δ by this factor: the float values are
/// accurate to far better than 10⁻⁶ relative away from the contour, and a miss only means
/// the piece is not certified.
pub const HOPELESS_FACTOR: f64 = 1.0 + 1e-6;

/// One sub-interval of a piece's local time, proven by one bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundPart {
    /// Start (local time τ ∈ [0, 1]).
    pub tau0: f64,
    /// End.
    pub tau1: f64,
    /// The bound that proves it.
    pub bound: BoundKind,
}

/// Why a piece could not be covered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoverFailure {
    /// E\[P\] ≥ 0 at `tau`: no bound applies there.
    MeanNotNegative {
        /// Local time.
        tau: f64,
    },
    /// Every bound exceeds Δ at `tau` (float values; `best` is the smallest).
    AboveDelta {
        /// Local time.
        tau: f64,
        /// The smallest bound found there.
        best: f64,
    },
    /// The depth or node budget ran out near `tau` (undecided).
    Budget {
        /// Local time.
        tau: f64,
    },
}

impl CoverFailure {
    /// The local time of the failure.
    pub fn tau(&self) -> f64 {
        match *self {
            CoverFailure::MeanNotNegative { tau } | CoverFailure::AboveDelta { tau, .. } | CoverFailure::Budget { tau } => {
                tau
            }
        }
    }
}

/// A risk level Δ as the cover search uses it: an enclosure for the proofs and the nearest
/// float for the choices. Built once per certifier and obstacle (converting the exact
/// rational costs big-integer work that an edge check should not repeat).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    interval: Interval,
    nearest: f64,
}

impl Level {
    /// The level Δ = `delta`.
    pub fn new(delta: &BigRational) -> Self {
        Level { interval: Interval::enclose_rational(delta), nearest: rational_to_f64(delta) }
    }

    /// The level used where the answer does not depend on Δ (the support proof of a point:
    /// zero risk is below every level).
    const ANY: Level = Level { interval: Interval { lo: 0.5, hi: 0.5 }, nearest: 0.5 };
}

/// The restrictions of one obstacle's bound polynomials to one piece (or one point), built
/// as needed, and the cover search over them.
pub struct PieceBounds<'a> {
    contour: &'a RiskContour,
    subs: Vec<UPoly<Interval>>,
    /// `Some` for a piece: its coordinates, to evaluate points cheaply.
    piece: Option<PieceRef<'a>>,
    delta: Interval,
    delta_f: f64,
    /// The compiled restriction (frame coordinates of the piece), when the caller has one:
    /// cheaper than the general composition (§5.13).
    fast: Option<Fast<'a>>,
    mu: OnceCell<UPoly<Interval>>,
    g1: OnceCell<UPoly<Interval>>,
    central: OnceCell<Option<Scaled>>,
    support: OnceCell<Option<SupportTerms>>,
}

/// A piece's coordinates in a compiled contour's frame.
struct Fast<'a> {
    compiled: &'a CompiledContour,
    subs: [FPoly<CAPACITY>; 9],
    nv: usize,
}

impl Fast<'_> {
    fn subs(&self) -> &[FPoly<CAPACITY>] {
        &self.subs[..self.nv]
    }
}

/// The support form's coefficients a_β restricted to the piece, with their ω^β.
type SupportTerms = Vec<(Vec<(Var, u32)>, UPoly<Interval>)>;

/// μ and the central moments scaled by a power of two s (μ/s, cⱼ/sʲ), so that the moment
/// constraint's numbers stay near 1 at any scene scale, with the products it needs.
struct Scaled {
    /// (μ/s)^i for i = 0 … max order.
    mu_pow: Vec<UPoly<Interval>>,
    /// cⱼ/sʲ.
    central: Vec<UPoly<Interval>>,
    /// Per order 2k (index k): (μ/s)^(2k−j)·cⱼ/sʲ for j = 0 … 2k (built on first use).
    products: Vec<OnceCell<Vec<UPoly<Interval>>>>,
}

fn reparam(p: &UPoly<Interval>, a: f64, w: f64) -> UPoly<Interval> {
    if a == 0.0 && w == 1.0 {
        return p.clone();
    }
    p.compose_affine(&Interval::point(a), &Interval::point(w))
}

fn hull_on(p: &UPoly<Interval>, a: f64, w: f64) -> Option<Interval> {
    bernstein_hull(reparam(p, a, w).coeffs())
}

impl<'a> PieceBounds<'a> {
    /// For a piece at risk level `level`.
    pub fn for_piece(contour: &'a RiskContour, piece: PieceRef<'a>, level: Level) -> Self {
        let subs = interval_substitutions(piece, contour.layout().dim);
        Self::from_subs(contour, subs, Some(piece), level)
    }

    /// For a piece, with the obstacle's compiled contour (the certifier's fast path): the
    /// restrictions are composed in the compiled frame where the degrees allow, generally
    /// elsewhere.
    pub fn for_piece_compiled(
        contour: &'a RiskContour,
        compiled: &'a CompiledContour,
        piece: PieceRef<'a>,
        level: Level,
    ) -> Self {
        let mut pb = Self::for_piece(contour, piece, level);
        pb.fast = compiled.substitutions::<CAPACITY>(piece).map(|subs| Fast { compiled, subs, nv: compiled.frame().len() });
        pb
    }

    /// For one point, with the obstacle's compiled contour: `x` its floats (the frame
    /// coordinates are enclosed from them) and `xt` the same point exactly.
    pub fn for_point_compiled(
        contour: &'a RiskContour,
        compiled: &'a CompiledContour,
        x: &[f64],
        xt: &[BigRational],
        level: Level,
    ) -> Self {
        let mut pb = Self::for_point(contour, xt, level);
        let z = compiled.frame().point_coords(x);
        let mut subs = [FPoly::zero(); 9];
        for (s, v) in subs.iter_mut().zip(&z) {
            *s = FPoly::constant(*v);
        }
        pb.fast = (z.len() == compiled.frame().len() && z.len() <= 9).then_some(Fast { compiled, subs, nv: z.len() });
        pb
    }

    /// For one point `xt` = (x1..xn, t), exactly.
    pub fn for_point(contour: &'a RiskContour, xt: &[BigRational], level: Level) -> Self {
        let mut subs: Vec<UPoly<Interval>> =
            xt.iter().map(|v| UPoly::constant(Interval::enclose_rational(v))).collect();
        subs.resize(contour.layout().xt_len(), UPoly::zero());
        Self::from_subs(contour, subs, None, level)
    }

    fn from_subs(
        contour: &'a RiskContour,
        subs: Vec<UPoly<Interval>>,
        piece: Option<PieceRef<'a>>,
        level: Level,
    ) -> Self {
        PieceBounds {
            contour,
            subs,
            piece,
            delta: level.interval,
            delta_f: level.nearest,
            fast: None,
            mu: OnceCell::new(),
            g1: OnceCell::new(),
            central: OnceCell::new(),
            support: OnceCell::new(),
        }
    }

    fn mu(&self) -> &UPoly<Interval> {
        self.mu.get_or_init(|| {
            self.fast
                .as_ref()
                .and_then(|f| f.compiled.mean_on(f.subs()))
                .unwrap_or_else(|| self.contour.interval_polys().0.compose_univariate(&self.subs))
        })
    }

    fn g1(&self) -> &UPoly<Interval> {
        self.g1.get_or_init(|| {
            let e1 = self.mu();
            let e2 = self
                .fast
                .as_ref()
                .and_then(|f| f.compiled.second_on(f.subs()))
                .unwrap_or_else(|| self.contour.interval_polys().1.compose_univariate(&self.subs));
            let omd = Interval::point(1.0) - self.delta;
            e1.mul(e1).sub(&e2.scale(&omd))
        })
    }

    fn scaled(&self) -> Option<&Scaled> {
        self.central
            .get_or_init(|| {
                // the central moments restricted: compiled in the frame, else generally
                let restricted: Vec<UPoly<Interval>> = match self
                    .fast
                    .as_ref()
                    .and_then(|f| f.compiled.bounds(self.contour).central_on(f.subs()))
                {
                    Some(c) => c,
                    None => {
                        let hm = self.contour.higher();
                        let top = hm.max_order() as usize;
                        hm.interval().iter().take(top + 1).map(|c| c.compose_univariate(&self.subs)).collect()
                    }
                };
                if restricted.len() <= MOMENT_ORDERS[0] as usize {
                    return None;
                }
                let mu = self.mu();
                let h = bernstein_hull(mu.coeffs())?;
                let big = h.lo.abs().max(h.hi.abs());
                if !(big > 0.0 && big.is_finite()) {
                    return None;
                }
                let e = big.log2().floor() as i32;
                let inv = |j: i32| {
                    let f = 2f64.powi(-e * j);
                    (f.is_finite() && f > 0.0 && f.is_normal()).then_some(Interval::point(f))
                };
                let mu_s = mu.scale(&inv(1)?);
                let top = restricted.len() - 1;
                let mut central = Vec::with_capacity(top + 1);
                for (j, c) in restricted.iter().enumerate() {
                    central.push(c.scale(&inv(j as i32)?));
                }
                let mut mu_pow = vec![UPoly::constant(Interval::point(1.0))];
                for i in 1..=top {
                    let next = mu_pow[i - 1].mul(&mu_s);
                    mu_pow.push(next);
                }
                let products = (0..=top / 2).map(|_| OnceCell::new()).collect();
                Some(Scaled { mu_pow, central, products })
            })
            .as_ref()
    }

    fn support_terms(&self) -> Option<&SupportTerms> {
        self.support
            .get_or_init(|| {
                let sf = self.contour.support()?;
                if let Some(terms) =
                    self.fast.as_ref().and_then(|f| f.compiled.bounds(self.contour).support_on(f.subs()))
                {
                    return Some(terms);
                }
                Some(sf.terms.iter().map(|(beta, _, ai)| (beta.clone(), ai.compose_univariate(&self.subs))).collect())
            })
            .as_ref()
    }

    /// Whether P < 0 for every τ in [a, a + w] and every parameter in the support box,
    /// proven by interval branch and bound over the parameter box (§3.7).
    fn support_proves(&self, a: f64, w: f64) -> bool {
        let (Some(terms), Some(sf)) = (self.support_terms(), self.contour.support()) else { return false };
        let ranges: Option<Vec<Interval>> = terms.iter().map(|(_, p)| hull_on(p, a, w)).collect();
        let Some(ranges) = ranges else { return false };
        let root: Vec<Interval> = sf
            .support
            .iter()
            .map(|(_, lo, hi)| Interval::new(Interval::enclose_rational(lo).lo, Interval::enclose_rational(hi).hi))
            .collect();
        let vars: Vec<Var> = sf.support.iter().map(|s| s.0).collect();
        let mid_tau = a + 0.5 * w;
        let at_mid: Vec<Interval> = terms.iter().map(|(_, p)| p.eval(&Interval::point(mid_tau))).collect();
        // Σ_β coefficient_β · range of ω^β over the box `bx` (`at`: map a box side to the values used)
        let sum = |coeffs: &[Interval], bx: &[Interval], at: &dyn Fn(Interval) -> Interval| {
            let range_of = |v: Var| vars.iter().position(|&u| u == v).map_or(Interval::ENTIRE, |i| at(bx[i]));
            terms.iter().zip(coeffs).fold(Interval::point(0.0), |acc, ((beta, _), r)| acc + *r * monomial_range(beta, range_of))
        };
        let mut stack = vec![root];
        let mut boxes = 0;
        while let Some(bx) = stack.pop() {
            boxes += 1;
            if boxes > SUPPORT_MAX_BOXES {
                return false;
            }
            if sum(&ranges, &bx, &|side| side).hi < 0.0 {
                continue;
            }
            // P ≥ 0 at the box's centre and the sub-interval's middle: no proof possible
            if sum(&at_mid, &bx, &|side| Interval::point(side.mid())).lo >= 0.0 {
                return false;
            }
            // split the widest parameter range
            let Some((i, _)) = bx.iter().enumerate().max_by(|x, y| x.1.width().total_cmp(&y.1.width())) else {
                return false;
            };
            let m = bx[i].mid();
            if !(bx[i].lo < m && m < bx[i].hi) {
                return false;
            }
            let mut left = bx.clone();
            left[i] = Interval::new(bx[i].lo, m);
            let mut right = bx;
            right[i] = Interval::new(m, right[i].hi);
            stack.push(left);
            stack.push(right);
        }
        true
    }

    fn products(&self, s: &'a Scaled, order: u32) -> &'a [UPoly<Interval>] {
        let k = (order / 2) as usize;
        s.products[k].get_or_init(|| {
            (0..=order as usize).map(|j| s.mu_pow[order as usize - j].mul(&s.central[j])).collect()
        })
    }

    /// H/s^2k = (Δ(1−b)^2k − b^2k)·(μ/s)^2k − Σ_{j≥2} C(2k,j)·b^(2k−j)·(μ/s)^(2k−j)·cⱼ/sʲ.
    fn moment_constraint(&self, s: &'a Scaled, order: u32, b: f64) -> UPoly<Interval> {
        let prods = self.products(s, order);
        let bi = Interval::point(b);
        let omb = Interval::point(1.0) - bi;
        let lead = self.delta * pow(omb, order) - pow(bi, order);
        let mut h = prods[0].scale(&lead);
        for (j, p) in prods.iter().enumerate().skip(2) {
            let coef = Interval::point(binomial_f64(order, j as u32)) * pow(bi, order - j as u32);
            h = h.sub(&p.scale(&coef));
        }
        h
    }

    /// The best shifted moment bound at local time `tau` in floating point (order, shift,
    /// value), from the restricted polynomials.
    fn best_moment_at(&self, s: &Scaled, tau: f64) -> Option<(u32, f64, f64)> {
        let t = Interval::point(tau);
        let mu = s.mu_pow[1].eval(&t).mid();
        let c: Vec<f64> = s.central.iter().map(|p| p.eval(&t).mid()).collect();
        let top = (c.len() - 1) as u32;
        MOMENT_ORDERS
            .into_iter()
            .filter(|&o| o <= top)
            .filter_map(|o| best_shift(mu, &c, o).map(|(b, v)| (o, b, v)))
            .min_by(|x, y| x.2.total_cmp(&y.2))
    }

    /// Whether no bound can prove any sub-interval containing local time `tau`, judged at the
    /// point in floating point (cheap; only ever used to give up).
    pub fn hopeless_at(&self, tau: f64) -> Option<CoverFailure> {
        let (mu, second, xt) = self.point_values(tau)?;
        if mu >= 0.0 {
            return Some(CoverFailure::MeanNotNegative { tau });
        }
        let limit = self.delta_f * HOPELESS_FACTOR;
        let mut best = cantelli_bound_f64(mu, second);
        if best <= limit {
            return None;
        }
        let central = self.central_at(&xt);
        // the central-moment Markov bounds (shift 0) first: one evaluation each
        for o in MOMENT_ORDERS.into_iter().rev() {
            best = best.min(moment_bound_f64(mu, &central, o, 0.0));
            if best <= limit {
                return None;
            }
        }
        for o in MOMENT_ORDERS.into_iter().rev() {
            if let Some((_, v)) = best_shift(mu, &central, o) {
                best = best.min(v);
                if best <= limit {
                    return None;
                }
            }
        }
        // zero risk from the support at the point itself (a zero-width sub-interval)
        if best <= self.delta_f * HOPELESS_FACTOR || self.support_proves(tau, 0.0) {
            return None;
        }
        Some(CoverFailure::AboveDelta { tau, best })
    }

    /// μ and E\[P²\] at local time `tau` of the piece (from the piece's coordinates and
    /// the contour's `f64` copies), with the point (x, t).
    fn point_values(&self, tau: f64) -> Option<(f64, f64, Vec<f64>)> {
        let dim = self.contour.layout().dim;
        let mut xt = vec![0.0; dim + 1];
        match self.piece {
            Some(p) => {
                let t = p.t0 + (p.t1 - p.t0) * tau;
                for (d, row) in p.coeffs.iter().enumerate().take(dim) {
                    xt[d] = row.iter().rev().fold(0.0, |acc, &c| acc * t + c);
                }
                xt[dim] = t;
            }
            None => {
                for (d, s) in self.subs.iter().enumerate().take(dim + 1) {
                    xt[d] = s.coeff(0).mid();
                }
            }
        }
        if xt.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let (mu, second) = self.contour.moments_f64(&xt);
        Some((mu, second, xt))
    }

    /// The central moments at the point (x, t) in floating point (empty below the lowest
    /// order of [`MOMENT_ORDERS`]): from the compiled frame when there is one.
    fn central_at(&self, xt: &[f64]) -> Vec<f64> {
        let central = match &self.fast {
            Some(f) => f.compiled.bounds(self.contour).central_at(&f.compiled.frame().point_coords_f64(xt)),
            None => self.contour.higher().eval_f64(xt),
        };
        if central.len() > MOMENT_ORDERS[0] as usize {
            central
        } else {
            Vec::new()
        }
    }

    /// Covers [0, 1] by sub-intervals each proven by one bound (§5.13), or says where it
    /// could not. `hint`: a local time where Cantelli failed (checked first for hopelessness).
    pub fn cover(&self, hint: Option<f64>) -> Result<Vec<BoundPart>, CoverFailure> {
        // cheap rejection first: the hint, then evenly spaced points (a piece that fails
        // somewhere usually fails at one of them; the float checks cost microseconds,
        // a sub-interval proof tens); a point is probed once
        let spaced = if self.piece.is_some() { HOPELESS_PROBES } else { 0 };
        let probes = hint.into_iter().chain((0..=spaced).map(|k| k as f64 / spaced.max(1) as f64));
        for t in probes {
            if let Some(f) = self.hopeless_at(t) {
                return Err(f);
            }
        }
        let max_depth = if self.piece.is_some() { COVER_MAX_DEPTH } else { 0 };
        let mut parts: Vec<BoundPart> = Vec::new();
        let mut stack = vec![(0.0f64, 1.0f64, 0u32)];
        let mut nodes = 0usize;
        while let Some((a, w, depth)) = stack.pop() {
            nodes += 1;
            let mid = a + 0.5 * w;
            if nodes > COVER_MAX_NODES {
                return Err(CoverFailure::Budget { tau: mid });
            }
            if let Some(kind) = self.node(a, w) {
                match parts.last_mut() {
                    Some(last) if last.bound == kind && last.tau1 == a => last.tau1 = a + w,
                    _ => parts.push(BoundPart { tau0: a, tau1: a + w, bound: kind }),
                }
                continue;
            }
            if depth >= max_depth {
                return Err(self.failure_at(mid));
            }
            if depth >= 1 {
                if let Some(f) = (self.piece.is_some()).then(|| self.hopeless_at(mid)).flatten() {
                    return Err(f);
                }
            }
            let half = 0.5 * w;
            stack.push((a + half, half, depth + 1));
            stack.push((a, half, depth + 1));
        }
        Ok(parts)
    }

    fn failure_at(&self, tau: f64) -> CoverFailure {
        if self.piece.is_some() {
            if let Some(f) = self.hopeless_at(tau) {
                return f;
            }
        } else {
            let mu = self.mu().eval(&Interval::point(0.0));
            if mu.lo >= 0.0 {
                return CoverFailure::MeanNotNegative { tau };
            }
        }
        CoverFailure::Budget { tau }
    }

    /// The bound proving [a, a + w], if one does.
    fn node(&self, a: f64, w: f64) -> Option<BoundKind> {
        let mu_h = hull_on(self.mu(), a, w)?;
        if mu_h.hi < 0.0 && hull_on(self.g1(), a, w).is_some_and(|g| g.lo > 0.0) {
            return Some(BoundKind::Cantelli);
        }
        if self.support_proves(a, w) {
            return Some(BoundKind::Support);
        }
        if mu_h.hi < 0.0 {
            if let Some(s) = self.scaled() {
                let (order, b, value) = self.best_moment_at(s, a + 0.5 * w)?;
                if value < self.delta_f && b < 1.0 {
                    let h = self.moment_constraint(s, order, b);
                    if hull_on(&h, a, w).is_some_and(|g| g.lo > 0.0) {
                        return Some(BoundKind::Moment(order));
                    }
                }
            }
        }
        None
    }
}

/// Whether zero risk from the support is proven at the exact point `xt` (`None` without
/// bounded support).
fn support_zero_at(contour: &RiskContour, xt: &[BigRational]) -> Option<bool> {
    contour.support().map(|_| PieceBounds::for_point(contour, xt, Level::ANY).support_proves(0.0, 1.0))
}

/// Every bound at the exact point `xt` (docs/design.md §3.10): Cantelli's exactly, proven
/// upper bounds of the moment bounds, and zero risk when the support proof holds there.
pub fn point_bounds_proven(contour: &RiskContour, xt: &[BigRational]) -> crate::contour::PointBounds {
    crate::contour::bounds::point_bounds(contour, xt, support_zero_at(contour, xt))
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

#[cfg(test)]
mod tests;
