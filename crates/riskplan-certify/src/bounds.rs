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
use super::fast::{CompiledContour, FPoly, Substitution, CAPACITY};
use num_rational::BigRational;
use riskplan_math::contour::bounds::{
    best_shift, binomial_f64, interval_pow as pow, moment_bound_f64, power_range, shift_search, MOMENT_ORDERS,
    SHIFT_SEARCH_COARSE,
};
use riskplan_math::contour::{cantelli_bound_f64, BoundKind, RiskContour};
use riskplan_math::poly::{rational_to_f64, Interval, UPoly, Var};
use std::cell::OnceCell;

/// Deepest split of a piece's local time (sub-intervals at least 2⁻⁶ of the piece).
/// Measured on the reference scenes at Δ = 0.1 (docs/design.md §5.13): one cover in a
/// hundred that succeeds needs more than four levels; the searches that went deeper (to
/// 2⁻¹²) failed in nine cases of ten, at the enclosure's precision floor (where the
/// central moments are tiny next to their coefficients in the scene's frame, halving the
/// sub-interval no longer narrows the moment constraint's hull) or where the piece grazes
/// a contour, and cost six times a successful cover. Giving up only refuses the piece.
pub const COVER_MAX_DEPTH: u32 = 6;

/// Most sub-intervals examined per piece and obstacle (bounds the work of a grazing piece).
pub const COVER_MAX_NODES: usize = 128;

/// A moment bound of a low order is preferred to a smaller one of a higher order when
/// its value at a sub-interval's middle is at most this share of Δ: the low orders'
/// restrictions have lower degree (cⱼ has degree j·deg P) and so cost less. The share is
/// high because a split with a cheap order costs less than restricting the higher ones;
/// the 5 % leaves the proof some margin.
pub const LOW_ORDER_SHARE: f64 = 0.95;

/// Evenly spaced local times (besides a hint) at which a piece is checked for hopelessness
/// when the whole piece is not proven, before it is split: 1/8 of the piece apart (the
/// failed sub-intervals are probed at their middles as the split goes on).
pub const HOPELESS_PROBES: usize = 16;

/// Up to this many parameters, a support proof first evaluates P at every corner of the
/// parameter box (2ⁿ points) at the sub-interval's middle, to refute quickly.
pub const SUPPORT_CORNER_PARAMS: usize = 4;

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
            CoverFailure::MeanNotNegative { tau }
            | CoverFailure::AboveDelta { tau, .. }
            | CoverFailure::Budget { tau } => tau,
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
    last_point: std::cell::RefCell<Option<std::rc::Rc<PointValues>>>,
    /// The support terms' ω^β as (box side, exponent) pairs.
    support_index: OnceCell<Vec<Vec<(usize, u32)>>>,
}

/// A piece's coordinates in a compiled contour's frame.
struct Fast<'a> {
    compiled: &'a CompiledContour,
    subs: [FPoly<CAPACITY>; 9],
    nv: usize,
    /// The same coordinates for the `f64` restriction ([`Substitution`]), when the caller
    /// has them.
    esub: Option<&'a Substitution>,
}

impl Fast<'_> {
    fn subs(&self) -> &[FPoly<CAPACITY>] {
        &self.subs[..self.nv]
    }
}

/// The support form's coefficients a_β restricted to the piece, with their ω^β.
type SupportTerms = Vec<(Vec<(Var, u32)>, UPoly<Interval>)>;

/// μ and the central moments scaled by a power of two s (μ/s, cⱼ/sʲ), so that the moment
/// constraint's numbers stay near 1 at any scene scale. Each cⱼ is restricted on first use:
/// a proof of order 2k needs c₂ … c₂ₖ only, and the low orders cost far less (cⱼ has
/// degree j·deg P).
struct Scaled {
    /// The exponent e of s = 2^e.
    e: i32,
    /// μ/s.
    mu_s: UPoly<Interval>,
    /// cⱼ/sʲ for j = 0 … top, restricted on first use (`None`: beyond the capacity of the
    /// scaling, see [`PieceBounds::central_scaled`]).
    central: Vec<OnceCell<Option<UPoly<Interval>>>>,
}

/// A point's values in floating point (choices and giving up only).
struct PointValues {
    tau: f64,
    mu: f64,
    second: f64,
    /// The central moments (empty below the lowest order of [`MOMENT_ORDERS`]).
    central: OnceCell<Vec<f64>>,
    xt: Vec<f64>,
    /// The point in the compiled frame, when there is one.
    z: Option<Vec<f64>>,
    /// The moment bound chosen here ([`PieceBounds::moment_choice_at`]), once computed.
    choice: OnceCell<Option<(u32, f64, f64)>>,
}

impl PointValues {
    fn central(&self, pb: &PieceBounds<'_>) -> &[f64] {
        self.central.get_or_init(|| {
            usable(match (&pb.fast, &self.z) {
                (Some(f), Some(z)) => f.compiled.bounds(pb.contour).central_at(z),
                _ => pb.contour.higher().eval_f64(&self.xt),
            })
        })
    }
}

/// The central moments if they reach the lowest moment order, else none.
fn usable(central: Vec<f64>) -> Vec<f64> {
    if central.len() > MOMENT_ORDERS[0] as usize {
        central
    } else {
        Vec::new()
    }
}

/// The coefficients of p(a + w·τ) in place of those of p (outward rounded, so each
/// encloses the exact one for any polynomial within the input's enclosures): a Taylor
/// shift by `a` (repeated synthetic division, no allocation), then τᵏ scaled by wᵏ.
fn reparam_in_place(c: &mut [Interval], a: f64, w: f64) {
    let n = c.len();
    if a != 0.0 {
        let ai = Interval::point(a);
        for k in 0..n.saturating_sub(1) {
            for j in (k..n - 1).rev() {
                c[j] = c[j] + ai * c[j + 1];
            }
        }
    }
    if w != 1.0 {
        let wi = Interval::point(w);
        let mut wk = wi;
        for x in c.iter_mut().skip(1) {
            *x = *x * wk;
            wk = wk * wi;
        }
    }
}

/// 2^(−e·j) as a point interval, when it is a normal float (scaling by it is exact).
fn scale_factor(e: i32, j: i32) -> Option<Interval> {
    let f = 2f64.powi(-e * j);
    (f.is_finite() && f.is_normal()).then_some(Interval::point(f))
}

fn hull_on(p: &UPoly<Interval>, a: f64, w: f64) -> Option<Interval> {
    let src = p.coeffs();
    if src.len() <= CAPACITY {
        let mut buf = [Interval::point(0.0); CAPACITY];
        let c = &mut buf[..src.len()];
        c.copy_from_slice(src);
        reparam_in_place(c, a, w);
        bernstein_hull(c)
    } else {
        let mut c = src.to_vec();
        reparam_in_place(&mut c, a, w);
        bernstein_hull(&c)
    }
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
        pb.fast = compiled.substitutions::<CAPACITY>(piece).map(|subs| Fast {
            compiled,
            subs,
            nv: compiled.frame().len(),
            esub: None,
        });
        pb
    }

    /// With the enclosures of −E\[P\] and of Cantelli's g₁ on the piece that the caller's
    /// fast path computed (`(−E[P], g₁)` coefficients; the same polynomials
    /// `PieceBounds::mu` and `PieceBounds::g1` would restrict again).
    pub fn with_cantelli_restrictions(self, restricted: Option<(Vec<Interval>, Vec<Interval>)>) -> Self {
        if let Some((neg_mean, g1)) = restricted {
            let _ = self.mu.set(UPoly::new(neg_mean.into_iter().map(|v| -v).collect()));
            let _ = self.g1.set(UPoly::new(g1));
        }
        self
    }

    /// With the piece's coordinates in the compiled frame for the `f64` restriction of the
    /// central moments (the certifier computes them for Cantelli's constraints anyway).
    pub fn with_substitution(mut self, sub: Option<&'a Substitution>) -> Self {
        if let Some(f) = self.fast.as_mut() {
            f.esub = sub;
        }
        self
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
        pb.fast = (z.len() == compiled.frame().len() && z.len() <= 9).then_some(Fast {
            compiled,
            subs,
            nv: z.len(),
            esub: None,
        });
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
            last_point: std::cell::RefCell::new(None),
            support_index: OnceCell::new(),
        }
    }

    fn mu(&self) -> &UPoly<Interval> {
        self.mu.get_or_init(|| {
            self.fast
                .as_ref()
                .and_then(|f| {
                    f.esub.and_then(|sub| f.compiled.mean_on_f64(sub)).or_else(|| f.compiled.mean_on(f.subs()))
                })
                .unwrap_or_else(|| self.contour.interval_polys().0.compose_univariate(&self.subs))
        })
    }

    fn g1(&self) -> &UPoly<Interval> {
        self.g1.get_or_init(|| {
            let e1 = self.mu();
            let e2 = self
                .fast
                .as_ref()
                .and_then(|f| {
                    f.esub.and_then(|sub| f.compiled.second_on_f64(sub)).or_else(|| f.compiled.second_on(f.subs()))
                })
                .unwrap_or_else(|| self.contour.interval_polys().1.compose_univariate(&self.subs));
            let omd = Interval::point(1.0) - self.delta;
            e1.mul(e1).sub(&e2.scale(&omd))
        })
    }

    /// The highest central-moment order available (compiled in the frame, else general).
    fn top_order(&self) -> u32 {
        match &self.fast {
            Some(f) => f.compiled.bounds(self.contour).max_order(),
            None => self.contour.higher().max_order(),
        }
    }

    fn scaled(&self) -> Option<&Scaled> {
        self.central
            .get_or_init(|| {
                let top = self.top_order();
                if top < MOMENT_ORDERS[0] {
                    return None;
                }
                let mu = self.mu();
                let h = bernstein_hull(mu.coeffs())?;
                let big = h.lo.abs().max(h.hi.abs());
                if !(big > 0.0 && big.is_finite()) {
                    return None;
                }
                let e = big.log2().floor() as i32;
                let mu_s = mu.scale(&scale_factor(e, 1)?);
                let central = (0..=top).map(|_| OnceCell::new()).collect();
                Some(Scaled { e, mu_s, central })
            })
            .as_ref()
    }

    /// cⱼ/sʲ restricted to the piece: compiled in the frame, else generally composed;
    /// `None` when sʲ is not a normal power of two (the proof is not attempted then).
    fn central_scaled<'s>(&self, s: &'s Scaled, j: usize) -> Option<&'s UPoly<Interval>> {
        s.central
            .get(j)?
            .get_or_init(|| {
                let f = scale_factor(s.e, j as i32)?;
                // in f64 with midpoints and radii where the model allows, else in intervals
                // (compiled), else generally composed
                let fast = self.fast.as_ref().and_then(|fa| {
                    let cb = fa.compiled.bounds(self.contour);
                    fa.esub.and_then(|sub| cb.central_one_on_f64(j, sub)).or_else(|| cb.central_one_on(j, fa.subs()))
                });
                let c = match fast {
                    Some(c) => c,
                    None => self.contour.higher().interval().get(j)?.compose_univariate(&self.subs),
                };
                Some(c.scale(&f))
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
        // each term's ω^β as (box side, exponent) pairs, once per piece
        let index = self.support_index.get_or_init(|| {
            terms
                .iter()
                .map(|(beta, _)| {
                    beta.iter()
                        .map(|&(v, e)| (sf.support.iter().position(|s| s.0 == v).unwrap_or(usize::MAX), e))
                        .collect()
                })
                .collect()
        });
        let ranges: Option<Vec<Interval>> = terms.iter().map(|(_, p)| hull_on(p, a, w)).collect();
        let Some(ranges) = ranges else { return false };
        let root = &sf.support_box;
        let mid_tau = Interval::point(a + 0.5 * w);
        let at_mid: Vec<Interval> = terms.iter().map(|(_, p)| p.eval(&mid_tau)).collect();
        // Σ_β coefficient_β · range of ω^β, each parameter's range given by `side(i)`
        let sum = |coeffs: &[Interval], side: &dyn Fn(usize) -> Interval| {
            index.iter().zip(coeffs).fold(Interval::point(0.0), |acc, (beta, r)| {
                let m = beta.iter().fold(Interval::point(1.0), |m, &(i, e)| {
                    m * if i == usize::MAX { Interval::ENTIRE } else { power_range(side(i), e) }
                });
                acc + *r * m
            })
        };
        // quick refutation at the box's corners (the maximum over a box is often at a corner;
        // the search below finds such points only after many splits): P ≥ 0 there at the
        // sub-interval's middle, or P's range over the sub-interval at the corner not below
        // 0 — every box containing the corner has a range at least as wide, so no split
        // can prove the box that holds it
        if root.len() <= SUPPORT_CORNER_PARAMS {
            for mask in 0..1usize << root.len() {
                let corner = |i: usize| Interval::point(if mask >> i & 1 == 1 { root[i].hi } else { root[i].lo });
                if sum(&at_mid, &corner).lo >= 0.0 || sum(&ranges, &corner).hi >= 0.0 {
                    return false;
                }
            }
        }
        let mut stack = vec![root.clone()];
        let mut boxes = 0;
        while let Some(bx) = stack.pop() {
            boxes += 1;
            if boxes > SUPPORT_MAX_BOXES {
                return false;
            }
            if sum(&ranges, &|i| bx[i]).hi < 0.0 {
                continue;
            }
            // P ≥ 0 at the box's centre and the sub-interval's middle: no proof possible
            if sum(&at_mid, &|i| Interval::point(bx[i].mid())).lo >= 0.0 {
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

    /// H/s^2k = Σⱼ αⱼ·(μ/s)^(2k−j)·cⱼ/sʲ with α₀ = Δ(1−b)^2k − b^2k, α₁ = 0 (c₁ = 0) and
    /// αⱼ = −C(2k,j)·b^(2k−j), by Horner's rule in μ/s (2k products by the low-degree μ/s
    /// instead of the powers of μ times each cⱼ); `None` when a cⱼ is unavailable.
    fn moment_constraint(&self, s: &Scaled, order: u32, b: f64) -> Option<UPoly<Interval>> {
        let bi = Interval::point(b);
        let omb = Interval::point(1.0) - bi;
        let mu = s.mu_s.coeffs();
        let cap = (order as usize + 1) * mu.len().max(1) + 1;
        // two buffers, no allocation per step
        let (mut h, mut next) = (Vec::with_capacity(cap), Vec::with_capacity(cap));
        h.push(self.delta * pow(omb, order) - pow(bi, order));
        let zero = Interval::point(0.0);
        for j in 1..=order {
            // next = h·(μ/s)
            next.clear();
            next.resize(h.len() + mu.len().max(1) - 1, zero);
            for (i, x) in h.iter().enumerate() {
                for (k, y) in mu.iter().enumerate() {
                    next[i + k] = next[i + k] + *x * *y;
                }
            }
            std::mem::swap(&mut h, &mut next);
            if j >= 2 {
                let coef = -(Interval::point(binomial_f64(order, j)) * pow(bi, order - j));
                let c = self.central_scaled(s, j as usize)?.coeffs();
                if c.len() > h.len() {
                    h.resize(c.len(), zero);
                }
                for (x, y) in h.iter_mut().zip(c) {
                    *x = *x + coef * *y;
                }
            }
        }
        Some(UPoly::new(h))
    }

    /// The moment bound to try at local time `tau` (order, shift, float value at `tau`),
    /// from the point's central moments in floating point: the lowest order whose best
    /// shifted bound is at most [`LOW_ORDER_SHARE`]·Δ there, else the smallest bound.
    fn moment_choice_at(&self, tau: f64) -> Option<(u32, f64, f64)> {
        let pt = self.point_at(tau)?;
        *pt.choice.get_or_init(|| {
            let (mu, c) = (pt.mu, pt.central(self));
            let top = (c.len() as u32).saturating_sub(1);
            let mut best: Option<(u32, f64, f64)> = None;
            for o in MOMENT_ORDERS.into_iter().filter(|&o| o <= top) {
                let Some((b, v)) = shift_search(mu, c, o, f64::NEG_INFINITY, SHIFT_SEARCH_COARSE) else { continue };
                if v <= LOW_ORDER_SHARE * self.delta_f {
                    return Some((o, b, v));
                }
                if best.is_none_or(|x| v < x.2) {
                    best = Some((o, b, v));
                }
            }
            best
        })
    }

    /// Whether no bound can prove any sub-interval containing local time `tau`, judged at the
    /// point in floating point (cheap; only ever used to give up): every bound there is
    /// above `factor`·Δ.
    fn hopeless_at(&self, tau: f64, factor: f64) -> Option<CoverFailure> {
        let pt = self.point_at(tau)?;
        if pt.mu >= 0.0 {
            return Some(CoverFailure::MeanNotNegative { tau });
        }
        let limit = self.delta_f * factor;
        let mut best = cantelli_bound_f64(pt.mu, pt.second);
        if best <= limit {
            return None;
        }
        // the moment bound a proof here would use (memoised for that proof): the smallest
        // over the orders unless a low order is already below ½Δ
        if let Some(c) = self.moment_choice_at(tau) {
            best = best.min(c.2);
            if best <= limit {
                return None;
            }
        }
        // the central-moment Markov bounds (shift 0), which the shift grid may miss
        let central = pt.central(self);
        for o in MOMENT_ORDERS {
            best = best.min(moment_bound_f64(pt.mu, central, o, 0.0));
            if best <= limit {
                return None;
            }
        }
        // zero risk from the support at the point itself (a zero-width sub-interval)
        if self.support_proves(tau, 0.0) {
            return None;
        }
        Some(CoverFailure::AboveDelta { tau, best })
    }

    /// μ, E\[P²\] and the central moments at local time `tau` of the piece (or at the
    /// point) in floating point: from the compiled frame's point table when there is one
    /// (one pass for all of them), else from the contour's `f64` copies.
    fn point_values(&self, tau: f64) -> Option<PointValues> {
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
        if let Some(f) = &self.fast {
            let z = f.compiled.frame().point_coords_f64(&xt);
            let (mu, second) = f.compiled.bounds(self.contour).moments_at(&z);
            if mu.is_finite() && second.is_finite() {
                return Some(PointValues {
                    tau,
                    mu,
                    second,
                    central: OnceCell::new(),
                    xt,
                    z: Some(z),
                    choice: OnceCell::new(),
                });
            }
        }
        let (mu, second) = self.contour.moments_f64(&xt);
        Some(PointValues { tau, mu, second, central: OnceCell::new(), xt, z: None, choice: OnceCell::new() })
    }

    /// [`Self::point_values`] with a one-entry memo: a failed sub-interval's choice and
    /// its give-up test look at the same middle.
    fn point_at(&self, tau: f64) -> Option<std::rc::Rc<PointValues>> {
        if let Some(p) = self.last_point.borrow().as_ref().filter(|p| p.tau == tau) {
            return Some(p.clone());
        }
        let p = std::rc::Rc::new(self.point_values(tau)?);
        *self.last_point.borrow_mut() = Some(p.clone());
        Some(p)
    }

    /// Covers [0, 1] by sub-intervals each proven by one bound (§5.13), or says where it
    /// could not. `hint`: a local time where Cantelli failed (checked first for hopelessness).
    pub fn cover(&self, hint: Option<f64>) -> Result<Vec<BoundPart>, CoverFailure> {
        let is_piece = self.piece.is_some();
        // cheap rejection first (the float checks cost about a microsecond, a sub-interval
        // proof tens): the hint; then the whole piece, which one bound proves more often
        // than not; then evenly spaced points before splitting (a piece that fails
        // somewhere usually fails at one of them)
        if let Some(f) = hint.and_then(|t| self.hopeless_at(t, HOPELESS_FACTOR)) {
            return Err(f);
        }
        // a hint is where Cantelli's constraints failed: they cannot prove the whole piece
        if let Some(kind) = self.node_at(0.0, 1.0, hint.is_none(), hint.unwrap_or(0.5)) {
            return Ok(vec![BoundPart { tau0: 0.0, tau1: 1.0, bound: kind }]);
        }
        if !is_piece {
            return Err(self.failure_at(0.5));
        }
        for k in 0..=HOPELESS_PROBES {
            if let Some(f) = self.hopeless_at(k as f64 / HOPELESS_PROBES as f64, HOPELESS_FACTOR) {
                return Err(f);
            }
        }
        let mut parts: Vec<BoundPart> = Vec::new();
        let mut stack = vec![(0.5f64, 0.5f64, 1u32), (0.0, 0.5, 1)];
        let mut nodes = 1usize;
        while let Some((a, w, depth)) = stack.pop() {
            nodes += 1;
            let mid = a + 0.5 * w;
            if nodes > COVER_MAX_NODES {
                return Err(CoverFailure::Budget { tau: mid });
            }
            if let Some(kind) = self.node(a, w, true) {
                match parts.last_mut() {
                    Some(last) if last.bound == kind && last.tau1 == a => last.tau1 = a + w,
                    _ => parts.push(BoundPart { tau0: a, tau1: a + w, bound: kind }),
                }
                continue;
            }
            if depth >= COVER_MAX_DEPTH {
                return Err(self.failure_at(mid));
            }
            if let Some(f) = self.hopeless_at(mid, HOPELESS_FACTOR) {
                return Err(f);
            }
            let half = 0.5 * w;
            stack.push((a + half, half, depth + 1));
            stack.push((a, half, depth + 1));
        }
        Ok(parts)
    }

    fn failure_at(&self, tau: f64) -> CoverFailure {
        if self.piece.is_some() {
            if let Some(f) = self.hopeless_at(tau, HOPELESS_FACTOR) {
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
    /// `cantelli`: whether to try Cantelli's constraints (not on a whole piece where the
    /// caller saw them fail).
    fn node(&self, a: f64, w: f64, cantelli: bool) -> Option<BoundKind> {
        self.node_at(a, w, cantelli, a + 0.5 * w)
    }

    /// [`Self::node`] with the moment bound chosen at local time `at` in [a, a + w] (the
    /// whole piece: at the hint, where Cantelli's constraints fail and the give-up test
    /// has just computed the choice's ingredients).
    fn node_at(&self, a: f64, w: f64, cantelli: bool, at: f64) -> Option<BoundKind> {
        let mu_h = hull_on(self.mu(), a, w)?;
        if cantelli && mu_h.hi < 0.0 && hull_on(self.g1(), a, w).is_some_and(|g| g.lo > 0.0) {
            return Some(BoundKind::Cantelli);
        }
        let moment = || -> Option<BoundKind> {
            let s = self.scaled()?;
            let (order, b, value) = self.moment_choice_at(at)?;
            if !(value < self.delta_f && b < 1.0) {
                return None;
            }
            let h = self.moment_constraint(s, order, b)?;
            hull_on(&h, a, w).is_some_and(|g| g.lo > 0.0).then_some(BoundKind::Moment(order))
        };
        // a moment bound well below Δ at the choice point is tried before the support
        // proof (a branch and bound over the parameter box, the dearer of the two)
        let negative = mu_h.hi < 0.0;
        let promising = negative && self.moment_choice_at(at).is_some_and(|c| c.2 <= LOW_ORDER_SHARE * self.delta_f);
        if promising {
            if let Some(kind) = moment() {
                return Some(kind);
            }
        }
        if self.support_proves(a, w) {
            return Some(BoundKind::Support);
        }
        if negative && !promising {
            return moment();
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
pub fn point_bounds_proven(contour: &RiskContour, xt: &[BigRational]) -> riskplan_math::contour::PointBounds {
    riskplan_math::contour::bounds::point_bounds(contour, xt, support_zero_at(contour, xt))
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
