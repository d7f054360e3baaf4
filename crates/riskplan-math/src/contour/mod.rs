//! Risk contours (Section IV: eq. (10) `rc_s_cheby`, static; eq. (12) `rc_d_cheby`,
//! dynamic) — layer L1.
//!
//! For an obstacle `{x : P(x, ω, t) ≥ 0}` the contour polynomials are E\[P\] and E\[P²\]
//! in (x, t), computed once from the moments of ω and kept ([`RiskContour`]). For a
//! risk level Δ they give the two constraints of docs/design.md §3.2,
//!
//! ```text
//! g1 = E\[P\]² − (1−Δ)·E\[P²\] ≥ 0      (Cantelli, Theorem 1)
//! g2 = −E\[P\] ≥ 0                    (mean on the safe side)
//! ```
//!
//! and, at a point, the bound `(E[P²] − E[P]²) / E[P²]` on the probability of
//! collision where `E[P] ≤ 0` (1 elsewhere). The guarantee is per obstacle and per
//! instant (§3.1, §1.1).

pub mod bounds;
pub mod grow;
pub mod tail;

pub use bounds::{BoundChoice, BoundKind, HigherLimit, HigherMoments, PointBounds, SupportForm, UnknownBound};

use crate::poly::{rational_to_f64, Interval, Poly, QPoly, Var};
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use std::sync::{Arc, OnceLock};
use thiserror::Error;

/// Why a contour could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ContourError {
    /// A moment of a parameter was unavailable (for instance, too few raw moments).
    #[error("the moment E[{param}^{order}] is not available")]
    MissingMoment {
        /// Parameter name.
        param: String,
        /// Moment order.
        order: u32,
    },
}

/// Layout of the variables of a scene's polynomials: `x1..x{dim}` are `0..dim`,
/// `t` is `dim`, parameters come after.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Spatial dimension n.
    pub dim: usize,
}

impl Layout {
    /// The time variable.
    pub fn t(&self) -> Var {
        self.dim as Var
    }
    /// Whether `v` is an uncertain parameter.
    pub fn is_param(&self, v: Var) -> bool {
        v as usize > self.dim
    }
    /// Number of (x, t) variables: `dim + 1`.
    pub fn xt_len(&self) -> usize {
        self.dim + 1
    }
}

/// The constraints of one obstacle at one risk level (docs/design.md §3.2).
#[derive(Clone, Debug, PartialEq)]
pub struct Constraints {
    /// `g1 = E[P]² − (1−Δ)·E[P²]` (degree `2·deg P`).
    pub cantelli: QPoly,
    /// `g2 = −E[P]`.
    pub mean: QPoly,
}

/// The risk at one point and time, exact.
#[derive(Clone, Debug, PartialEq)]
pub struct PointRisk {
    /// E\[P\] at the point.
    pub mean: BigRational,
    /// E\[P²\] at the point.
    pub second_moment: BigRational,
    /// The Cantelli bound on Prob(P ≥ 0): `(E[P²] − E[P]²)/E[P²]` where `E[P] ≤ 0` and
    /// `E[P²] > 0`, and 1 otherwise.
    pub bound: BigRational,
}

/// The Cantelli bound from the two moments of `P` at a point (Theorem 1, Appendix).
pub fn cantelli_bound(mean: &BigRational, second: &BigRational) -> BigRational {
    if mean.is_positive() || !second.is_positive() {
        return BigRational::one();
    }
    (second - mean * mean) / second
}

/// [`cantelli_bound`] in floating point, clamped to [0, 1] (for plots and displays only).
pub fn cantelli_bound_f64(mean: f64, second: f64) -> f64 {
    if mean > 0.0 || second <= 0.0 || mean.is_nan() || second.is_nan() {
        return 1.0;
    }
    ((second - mean * mean) / second).clamp(0.0, 1.0)
}

/// Enclosures of a contour's raw parameter moments: per parameter, E[ω^k] for k = 0, 1, …
type EnclosedMoments = Vec<(Var, Vec<Interval>)>;

/// A floating-point polynomial's terms in flat arrays, for evaluation without the map of
/// monomials or the generic powers (the post-processing guess, [`RiskContour::mean_f64`]).
#[derive(Clone, Debug, Default)]
struct FlatPoly {
    coeffs: Vec<f64>,
    /// Where each term's (variable, exponent) pairs end in `pairs`.
    ends: Vec<usize>,
    pairs: Vec<(usize, i32)>,
}

impl FlatPoly {
    fn of(p: &Poly<f64>) -> FlatPoly {
        let mut f = FlatPoly::default();
        for (m, &c) in p.terms() {
            f.coeffs.push(c);
            f.pairs.extend(m.pairs().iter().map(|&(v, e)| (v as usize, e.min(i32::MAX as u32) as i32)));
            f.ends.push(f.pairs.len());
        }
        f
    }

    /// The value at `vals` (a variable beyond them is 0).
    fn eval(&self, vals: &[f64]) -> f64 {
        let mut acc = 0.0;
        let mut start = 0;
        for (&c, &end) in self.coeffs.iter().zip(&self.ends) {
            let mut t = c;
            for &(v, e) in &self.pairs[start..end] {
                let x = vals.get(v).copied().unwrap_or(0.0);
                // (products for the low powers of contours, not the `powi` library call)
                t *= match e {
                    1 => x,
                    2 => x * x,
                    3 => x * x * x,
                    4 => (x * x) * (x * x),
                    _ => x.powi(e),
                };
            }
            acc += t;
            start = end;
        }
        acc
    }
}

/// The moment-expanded contour polynomials of one obstacle, kept for its lifetime.
#[derive(Clone, Debug)]
pub struct RiskContour {
    layout: Layout,
    /// E\[P\](x, t), exact.
    pub mean: QPoly,
    /// E\[P²\](x, t), exact.
    pub second: QPoly,
    mean_f: Poly<f64>,
    /// `mean_f`'s terms flattened (the post-processing guess evaluates it along pieces).
    mean_flat: FlatPoly,
    second_f: Poly<f64>,
    mean_i: Poly<Interval>,
    second_i: Poly<Interval>,
    dynamic: bool,
    /// P itself (for the higher moments and the support form).
    poly: QPoly,
    /// Raw moments of P's parameters, `E[ω^k]` for k = 0 … up to
    /// [`bounds::MAX_MOMENT_ORDER`]·deg_ω P (fewer when a moment list stops early).
    raw: Vec<(Var, String, Vec<BigRational>)>,
    /// The support form, when every parameter of P has a bounded support.
    support: Option<Arc<SupportForm>>,
    /// Central moments, built on first use (docs/design.md §3.8).
    higher: OnceLock<Arc<HigherMoments>>,
    /// The raw moments of `raw` as enclosures, converted once on first use (the
    /// big-integer conversion dominated the central moments' build; the whole-path bound
    /// asks for them thousands of times per trajectory, §5.14).
    raw_i: OnceLock<Arc<EnclosedMoments>>,
    /// The parameters' laws where their distribution function can be bounded rigorously
    /// (the whole-path bound's partition of the parameter space, §5.14).
    laws: Vec<(Var, crate::moments::cdf::CdfLaw)>,
    /// P in centred, scaled coordinates, per frame asked (the last [`CENTRED_FRAMES_KEPT`];
    /// shared by clones: the whole-path partition of every scene that uses this contour).
    centred: Arc<std::sync::Mutex<Vec<CentredPoly>>>,
    /// The laws' distribution functions at the points the partition asked, enclosed (at
    /// most [`CDF_MEMO_MAX`]; shared by clones, made anew with the laws).
    cdf_memo: Arc<std::sync::Mutex<std::collections::HashMap<(Var, u64), Interval>>>,
}

/// Most values kept by a contour's memo of its laws' distribution functions
/// ([`RiskContour::law_cdf`]): 16 bytes and a key each. The whole-path partition (§5.14)
/// splits each parameter's range at the same middles plan after plan (the halves of the
/// halves of the range), and one enclosure of a normal distribution function sums its
/// series in interval arithmetic (about a microsecond): on 512 disks a fifth of the
/// whole-path bound's time was spent there, again and again for the same points.
pub const CDF_MEMO_MAX: usize = 4096;

/// P(c + 2^e·z, ω, t_c + 2^(e_t)·τ) for one frame (center, exponents), exact then enclosed,
/// and its form with the parameters' ranges folded in (built on first use).
#[derive(Debug)]
struct CentredPoly {
    center: Vec<f64>,
    exponents: Vec<i32>,
    poly: Arc<Poly<Interval>>,
    folded: OnceLock<Option<Arc<FoldedPoly>>>,
}

/// P in a frame (z, τ) with every parameter ω ranging over its law's range [lo, hi]
/// (`CdfLaw`: the support, or μ ± 9σ), grouped by (z, τ) monomial: Σₘ Cₘ·(z, τ)^m, each
/// Cₘ enclosing Σ_β c_{m,β}·range(ω^β) (docs/design.md §5.14, the screen). For any box X of
/// (z, τ), [`FoldedPoly::upper`] bounds P over X × the ranges from above: by
/// subdistributivity (Σ c_β·W_β)·X ⊆ Σ (c_β·W_β·X), never looser than the term-by-term sum.
/// Built once per contour and frame (a scene's obstacles are screened against every plan).
#[derive(Debug)]
pub struct FoldedPoly {
    /// P's parameters (its variables past the layout's (x, t)), in increasing order.
    pub params: Vec<Var>,
    /// Their ranges, `[lo, hi]` of each law, in the same order.
    pub root: Vec<Interval>,
    /// The laws' probabilities outside their ranges, summed (rounded up).
    pub outside: f64,
    /// (monomial as ((x, t) index, exponent) pairs, enclosed coefficient).
    terms: Vec<(Vec<(usize, u32)>, Interval)>,
}

impl FoldedPoly {
    /// An upper bound of P over the box `bx` of (z, τ) (dim + 1 sides) and every ω in the
    /// ranges, in interval arithmetic (even powers by their exact range). An operation that
    /// would give NaN gives the whole line (`Interval`), so the bound is then +∞ and proves
    /// nothing.
    pub fn upper(&self, bx: &[Interval]) -> f64 {
        let mut value = Interval::point(0.0);
        for (m, c) in &self.terms {
            value = value + m.iter().fold(*c, |acc, &(v, e)| acc * bounds::power_range(bx[v], e));
        }
        value.hi
    }
}

/// Largest scale exponent of a frame (the scene frames' limit, `Frame::MAX_EXPONENT`):
/// 2^(±1000) and its inverse are normal floats, so the pieces' mapping stays exact.
pub const CENTRED_MAX_EXPONENT: i32 = 1000;

/// Frames whose centred P a contour keeps (a contour is shared by the scenes of a cache; a
/// scene has one frame).
pub const CENTRED_FRAMES_KEPT: usize = 4;

impl RiskContour {
    /// Builds E\[P\] and E\[P²\] from the obstacle polynomial and the raw moments of its
    /// parameters (`moment(ω, k)` = E[ω^k]). Squares first, then takes expectations
    /// (E\[P²\] ≠ E\[P\]², docs/design.md §2.3).
    pub fn new(
        layout: Layout,
        p: &QPoly,
        moment: &dyn Fn(Var, u32) -> Option<BigRational>,
        name: &dyn Fn(Var) -> String,
    ) -> Result<Self, ContourError> {
        let is_param = |v| layout.is_param(v);
        let missing = |(v, k): (Var, u32)| ContourError::MissingMoment { param: name(v), order: k };
        // E[P] and E[P²] exactly, over common denominators (docs/design.md §2.3)
        let (mean, second) = crate::poly::mean_and_second_moment(p, is_param, moment).map_err(missing)?;
        let dynamic = p.contains_var(layout.t());
        // the raw moments the higher central moments may need, as far as they are known
        let raw = p
            .vars()
            .into_iter()
            .filter(|&v| layout.is_param(v))
            .map(|v| {
                let top = bounds::MAX_MOMENT_ORDER * p.degree_in(v);
                let ms: Vec<BigRational> = (0..=top).map_while(|k| moment(v, k)).collect();
                (v, name(v), ms)
            })
            .collect();
        let mean_f = mean.map_coeffs(rational_to_f64);
        Ok(RiskContour {
            layout,
            mean_flat: FlatPoly::of(&mean_f),
            mean_f,
            second_f: second.map_coeffs(rational_to_f64),
            mean_i: mean.map_coeffs(Interval::enclose_rational),
            second_i: second.map_coeffs(Interval::enclose_rational),
            mean,
            second,
            dynamic,
            poly: p.clone(),
            raw,
            support: None,
            higher: OnceLock::new(),
            raw_i: OnceLock::new(),
            laws: Vec::new(),
            centred: Default::default(),
            cdf_memo: Default::default(),
        })
    }

    /// The same contour with the parameters' bounded supports `(parameter, lo, hi)`: when
    /// every parameter of P has one, zero-risk certificates become possible (§3.7).
    pub fn with_support(mut self, support: &[(Var, BigRational, BigRational)]) -> Self {
        let layout = self.layout;
        self.support = SupportForm::new(&self.poly, |v| layout.is_param(v), support).map(Arc::new);
        self
    }

    /// The same contour with the parameters' distributions: those with a rigorous
    /// distribution function ([`crate::moments::cdf::CdfLaw`]) are kept for the whole-path
    /// bound (docs/design.md §5.14); the others are ignored, as are the laws of parameters
    /// P does not depend on (a scene passes every parameter's: on 512 disks with two
    /// parameters each, forming all 1 024 laws for every obstacle was half the scene's load).
    pub fn with_laws(mut self, laws: &[(Var, &crate::moments::Distribution)]) -> Self {
        let own = self.poly.vars();
        self.laws = laws
            .iter()
            .filter(|(v, _)| own.contains(v))
            .filter_map(|(v, d)| Some((*v, crate::moments::cdf::CdfLaw::of(d)?)))
            .collect();
        // what depends on the laws is made anew: the memo of their distribution functions,
        // and the folded forms (ranges and outside mass) kept with the centred polynomials
        // (a clone given other laws must not keep its original's ranges)
        self.cdf_memo = Default::default();
        self.centred = Default::default();
        self
    }

    /// F(x) of parameter `v`'s law ([`crate::moments::cdf::CdfLaw::cdf`], enclosed), from
    /// the memo when it was asked before ([`CDF_MEMO_MAX`]); `None` for a parameter
    /// without a law.
    pub fn law_cdf(&self, v: Var, x: f64) -> Option<Interval> {
        let key = (v, x.to_bits());
        if let Some(&f) = self.cdf_memo.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
            return Some(f);
        }
        let f = self.law(v)?.cdf(x);
        let mut memo = self.cdf_memo.lock().unwrap_or_else(|e| e.into_inner());
        if memo.len() < CDF_MEMO_MAX {
            memo.insert(key, f);
        }
        Some(f)
    }

    /// P in the frame z_v = (x_v − c_v)·2^(−e_v) (space, then time; docs/design.md §5.10):
    /// P(c + 2^e·z, ω, t_c + 2^(e_t)·τ) formed exactly and enclosed coefficient by
    /// coefficient — far from the origin, P's own coefficients cancel (a quartic at x ≈ 10³
    /// has terms of 10¹² for values of 10⁻⁶) and interval evaluations in x lose every
    /// digit; in the frame they do not (the whole-path partition, §5.14). `center` and
    /// `exponents` have dim + 1 entries (`None` otherwise, or for a centre that is not
    /// finite or an exponent beyond ±[`CENTRED_MAX_EXPONENT`]); cached per frame.
    pub fn centred_poly(&self, center: &[f64], exponents: &[i32]) -> Option<Arc<Poly<Interval>>> {
        let n = self.layout.dim + 1;
        if center.len() != n || exponents.len() != n || exponents.iter().any(|e| e.abs() > CENTRED_MAX_EXPONENT) {
            return None;
        }
        {
            let kept = self.centred.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(c) = kept.iter().find(|c| c.center == center && c.exponents == exponents) {
                return Some(c.poly.clone());
            }
        }
        // v ↦ c_v + 2^(e_v)·v, exactly (one common denominator: `affine_subst`)
        let maps: Vec<Option<(BigRational, BigRational)>> = (0..n)
            .map(|v| {
                let c = BigRational::from_float(*center.get(v)?)?;
                let e = *exponents.get(v)?;
                let two = BigRational::from_integer(2.into());
                let scale = if e >= 0 {
                    num_traits::pow(two, e as usize)
                } else {
                    BigRational::one() / num_traits::pow(two, (-e) as usize)
                };
                Some(Some((c, scale)))
            })
            .collect::<Option<_>>()?;
        let exact = crate::poly::affine_subst(&self.poly, &maps);
        let p = Arc::new(exact.map_coeffs(Interval::enclose_rational));
        let mut kept = self.centred.lock().unwrap_or_else(|e| e.into_inner());
        if kept.len() >= CENTRED_FRAMES_KEPT {
            kept.remove(0);
        }
        kept.push(CentredPoly {
            center: center.to_vec(),
            exponents: exponents.to_vec(),
            poly: p.clone(),
            folded: OnceLock::new(),
        });
        Some(p)
    }

    /// P in the frame of [`Self::centred_poly`] with the parameters' ranges folded in
    /// ([`FoldedPoly`]); `None` when that frame is refused or a parameter has no law with a
    /// rigorous distribution function. Cached with the centred P.
    pub fn folded_poly(&self, center: &[f64], exponents: &[i32]) -> Option<Arc<FoldedPoly>> {
        let centred = self.centred_poly(center, exponents)?;
        let fold = || -> Option<Arc<FoldedPoly>> {
            let params: Vec<Var> = self.poly.vars().into_iter().filter(|&v| self.layout.is_param(v)).collect();
            let laws: Vec<&crate::moments::cdf::CdfLaw> = params.iter().map(|&v| self.law(v)).collect::<Option<_>>()?;
            let root: Vec<Interval> = laws.iter().map(|l| Interval::new(l.lo, l.hi)).collect();
            let outside = laws.iter().fold(0.0, |acc, l| crate::moments::cdf::add_up(acc, l.outside));
            let mut grouped: std::collections::BTreeMap<Vec<(usize, u32)>, Interval> = Default::default();
            for (m, c) in centred.terms() {
                let mut w = *c;
                let mut xt = Vec::new();
                for &(v, e) in m.pairs() {
                    if self.layout.is_param(v) {
                        let k = params.iter().position(|&p| p == v)?;
                        w = w * bounds::power_range(root[k], e);
                    } else {
                        xt.push((v as usize, e));
                    }
                }
                let slot = grouped.entry(xt).or_insert(Interval::point(0.0));
                *slot = *slot + w;
            }
            Some(Arc::new(FoldedPoly { params, root, outside, terms: grouped.into_iter().collect() }))
        };
        let kept = self.centred.lock().unwrap_or_else(|e| e.into_inner());
        match kept.iter().find(|c| c.center == center && c.exponents == exponents) {
            Some(c) => c.folded.get_or_init(fold).clone(),
            // (evicted meanwhile by another frame: formed without keeping it)
            None => fold(),
        }
    }

    /// The law of parameter `v`, when [`Self::with_laws`] gave one with a rigorous
    /// distribution function.
    pub fn law(&self, v: Var) -> Option<&crate::moments::cdf::CdfLaw> {
        self.laws.iter().find(|l| l.0 == v).map(|l| &l.1)
    }

    /// The obstacle polynomial P(x, ω, t).
    pub fn poly(&self) -> &QPoly {
        &self.poly
    }

    /// The support form, when every parameter has a bounded support.
    pub fn support(&self) -> Option<&SupportForm> {
        self.support.as_deref()
    }

    /// The central moments (built on first use, within [`bounds::MAX_HIGHER_MOMENT_WORK`]).
    pub fn higher(&self) -> &HigherMoments {
        self.higher.get_or_init(|| Arc::new(bounds::build_higher(self)))
    }

    /// Whether the central moments have been built (for status and benches).
    pub fn higher_built(&self) -> bool {
        self.higher.get().is_some()
    }

    /// The raw moment E\[ω^k\] of a parameter of P, when known (up to
    /// [`bounds::MAX_MOMENT_ORDER`]·deg_ω P).
    pub fn param_moment(&self, v: Var, k: u32) -> Option<BigRational> {
        self.raw_moment(v, k)
    }

    /// An enclosure of E\[ω^k\] ([`Self::param_moment`]), converted once per contour.
    pub fn param_moment_interval(&self, v: Var, k: u32) -> Option<Interval> {
        let all = self.raw_i.get_or_init(|| {
            Arc::new(
                self.raw.iter().map(|(v, _, ms)| (*v, ms.iter().map(Interval::enclose_rational).collect())).collect(),
            )
        });
        all.iter().find(|r| r.0 == v).and_then(|r| r.1.get(k as usize)).copied()
    }

    fn raw_moment(&self, v: Var, k: u32) -> Option<BigRational> {
        self.raw.iter().find(|r| r.0 == v).and_then(|r| r.2.get(k as usize)).cloned()
    }

    fn param_name(&self, v: Var) -> String {
        self.raw.iter().find(|r| r.0 == v).map_or_else(|| format!("#{v}"), |r| r.1.clone())
    }

    /// Whether the obstacle moves (its polynomial contains `t`).
    pub fn is_dynamic(&self) -> bool {
        self.dynamic
    }

    /// The variable layout.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// `D`: the largest total degree in (x, t) of E\[P\] (docs/design.md §3.3);
    /// `deg g2 = D`, while `deg g1 ≤ 2·deg P`, which can exceed `2D` when the top-degree
    /// part of P averages out (E\[P²\] keeps it).
    pub fn degree(&self) -> u32 {
        self.mean.degree()
    }

    /// The constraints `g1`, `g2` at risk level Δ (§3.2).
    pub fn constraints(&self, delta: &BigRational) -> Constraints {
        let one_minus = BigRational::one() - delta;
        Constraints {
            cantelli: crate::poly::square_minus_scaled(&self.mean, &self.second, &one_minus),
            mean: self.mean.neg(),
        }
    }

    /// E\[P\] and E\[P²\] with outward-rounded interval coefficients (each encloses the
    /// exact rational coefficient), for fast sound certification.
    pub fn interval_polys(&self) -> (&Poly<Interval>, &Poly<Interval>) {
        (&self.mean_i, &self.second_i)
    }

    /// Exact risk at `xt = (x1..xn, t)`.
    pub fn risk_at(&self, xt: &[BigRational]) -> PointRisk {
        let vals = self.pad(xt, BigRational::zero());
        let mean = self.mean.eval_exact(&vals);
        let second = self.second.eval_exact(&vals);
        let bound = cantelli_bound(&mean, &second);
        PointRisk { mean, second_moment: second, bound }
    }

    /// Floating-point E\[P\], E\[P²\] at `xt` (fast; for plots and sampling displays).
    pub fn moments_f64(&self, xt: &[f64]) -> (f64, f64) {
        let vals = self.pad(xt, 0.0);
        (self.mean_f.eval(&vals), self.second_f.eval(&vals))
    }

    /// Floating-point E\[P\] at `xt` (a guess's arithmetic, not a decision's).
    pub fn mean_f64(&self, xt: &[f64]) -> f64 {
        self.mean_flat.eval(xt)
    }

    /// Floating-point Cantelli bound at `xt` (for plots and displays, not for decisions).
    pub fn bound_f64(&self, xt: &[f64]) -> f64 {
        let (m, s) = self.moments_f64(xt);
        cantelli_bound_f64(m, s)
    }

    fn pad<C: Clone>(&self, xt: &[C], zero: C) -> Vec<C> {
        let mut v = xt.to_vec();
        v.resize(self.layout.xt_len(), zero);
        v
    }
}

/// A risk level Δ, validated once: an exact rational strictly between 0 and 1.
///
/// Every front end (scene files, CLI flags, service requests) makes one with
/// [`RiskLevel::new`], [`RiskLevel::from_f64`] or [`RiskLevel::parse`], so the rule
/// "Δ ∈ (0, 1)" is checked in one place and in exact arithmetic (a float such as
/// `1 − 1e-17` that rounds to 1 is judged by its exact value).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct RiskLevel(BigRational);

/// A number that is not a valid risk level.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("the risk level Δ must be in (0, 1), got {0}")]
pub struct RiskLevelError(pub String);

impl RiskLevel {
    /// Δ = `q` if `0 < q < 1`.
    pub fn new(q: BigRational) -> Result<RiskLevel, RiskLevelError> {
        if q.is_positive() && q < BigRational::one() {
            Ok(RiskLevel(q))
        } else {
            Err(RiskLevelError(q.to_string()))
        }
    }
    /// Δ from a float, read as its shortest decimal (`0.1` is 1/10, as in scene files).
    pub fn from_f64(d: f64) -> Result<RiskLevel, RiskLevelError> {
        let q = crate::poly::f64_shortest_decimal(d).ok_or_else(|| RiskLevelError(d.to_string()))?;
        RiskLevel::new(q).map_err(|_| RiskLevelError(d.to_string()))
    }
    /// Δ from text: a decimal (`0.1`, `1e-3`) or a fraction (`1/10`), exactly.
    pub fn parse(s: &str) -> Result<RiskLevel, RiskLevelError> {
        let q = crate::poly::parse_num_text(s).ok_or_else(|| RiskLevelError(format!("'{s}' (not a number)")))?;
        RiskLevel::new(q).map_err(|_| RiskLevelError(s.to_string()))
    }
    /// The exact value.
    pub fn rational(&self) -> &BigRational {
        &self.0
    }
    /// The nearest float (for displays and sampling checks, never for decisions).
    pub fn to_f64(&self) -> f64 {
        rational_to_f64(&self.0)
    }
    /// The largest float at or below Δ: what sums of upper bounds are compared with
    /// (a whole-path budget, `risk_mode: trajectory`), so that a sum within it is within Δ.
    pub fn floor_f64(&self) -> f64 {
        let d = self.to_f64();
        if BigRational::from_float(d).is_some_and(|e| e > self.0) {
            d.next_down()
        } else {
            d
        }
    }
}

impl std::fmt::Display for RiskLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.to_f64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::moments::Distribution;
    use crate::poly::{parse, parse_decimal, VarTable};

    fn q(n: i64, d: i64) -> BigRational {
        BigRational::new(n.into(), d.into())
    }

    fn example1() -> (RiskContour, VarTable) {
        let vars = VarTable::new(["x1", "x2", "t", "w"].map(String::from));
        let p = parse("w^2 - x1^2 - x2^2", &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).unwrap();
        let m = Distribution::Uniform { low: parse_decimal("0.3").unwrap(), high: parse_decimal("0.4").unwrap() }
            .raw_moments(4)
            .unwrap();
        let c = RiskContour::new(Layout { dim: 2 }, &p, &|_, k| m.get(k as usize).cloned(), &|v| vars.name(v)).unwrap();
        (c, vars)
    }

    /// Illustrative Example 1 (Section IV-A): the paper prints
    /// E\[P\] = 0.1233 − x1² − x2², E\[P²\] = 0.0156 − 0.2466x1² − 0.2466x2² + x1⁴ + 2x1²x2² + x2⁴.
    #[test]
    fn illustrative_example_1_polynomials() {
        let (c, vars) = example1();
        let names = |v| vars.name(v);
        assert_eq!(c.mean.to_text(&names), "37/300 - x1^2 - x2^2");
        let printed = c.second.to_text(&names);
        assert_eq!(printed, "781/50000 - 37/150*x1^2 - 37/150*x2^2 + x1^4 + 2*x1^2*x2^2 + x2^4");
        // to the printed digits (the paper truncates to 4 decimals: 37/150 = 0.24666.. prints 0.2466)
        let digits4 = |p: &QPoly, m: crate::poly::Monomial| (rational_to_f64(&p.coeff(&m)) * 1e4).trunc() / 1e4;
        use crate::poly::Monomial as M;
        assert_eq!(digits4(&c.mean, M::one()), 0.1233);
        assert_eq!(digits4(&c.mean, M::var_pow(0, 2)), -1.0);
        assert_eq!(digits4(&c.second, M::one()), 0.0156);
        assert_eq!(digits4(&c.second, M::var_pow(0, 2)), -0.2466);
        assert_eq!(digits4(&c.second, M::var_pow(1, 2)), -0.2466);
        assert_eq!(digits4(&c.second, M::from_pairs([(0, 2), (1, 2)])), 2.0);
        assert_eq!(digits4(&c.second, M::var_pow(0, 4)), 1.0);
        assert_eq!(c.second.len(), 6);
        assert!(!c.is_dynamic());
        assert_eq!(c.degree(), 2);
    }

    /// The 0.1-contour is the circle of radius 0.428948 (docs/design.md §3.4).
    #[test]
    fn contour_radius_matches_closed_form() {
        let (c, _) = example1();
        let cons = c.constraints(&q(1, 10));
        let r_in = 0.428947;
        let r_out = 0.428949;
        let at = |r: f64| cons.cantelli.map_coeffs(rational_to_f64).eval(&[r, 0.0, 0.0]);
        assert!(at(r_in) < 0.0 && at(r_out) > 0.0);
        // centre: g1 > 0 but g2 < 0: both constraints are needed
        let centre = [q(0, 1), q(0, 1), q(0, 1)];
        assert!(cons.cantelli.eval(&centre).is_positive());
        assert!(cons.mean.eval(&centre).is_negative());
        assert_eq!(c.risk_at(&centre[..2]).bound, q(1, 1));
    }

    #[test]
    fn exact_bound_at_half_half() {
        let (c, _) = example1();
        let r = c.risk_at(&[q(1, 2), q(1, 2)]);
        let mean = q(37, 300) - q(1, 2);
        let second = q(781, 50000) - q(37, 150) * q(1, 2) + q(1, 4);
        assert_eq!(r.mean, mean);
        assert_eq!(r.second_moment, second);
        assert_eq!(r.bound, (&second - &mean * &mean) / &second);
        assert!((c.bound_f64(&[0.5, 0.5]) - rational_to_f64(&r.bound)).abs() < 1e-15);
    }
}
