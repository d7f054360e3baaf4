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

use crate::compiled::{CompiledContour, FPoly, Substitution, CAPACITY};
use crate::positivity::bernstein::bernstein_hull;
use crate::restrict::{interval_substitutions, PieceRef};
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
}

mod cover;
mod point;
mod proofs;
mod restricted;

pub use point::*;

#[cfg(test)]
mod tests;
