//! Risk bounds tighter than Cantelli's (docs/design.md §3.7–§3.10) — beyond the paper.
//!
//! At a point (x, t) let z = P(x, ω, t), μ = E\[z\] and cⱼ = E\[(z − μ)ʲ\] (central moments,
//! polynomials in (x, t) built exactly from the parameters' moments). Three families bound
//! Prob(z ≥ 0):
//!
//! - **Cantelli** (eq. (10), (12), §3.1): σ²/(σ² + μ²) where μ < 0.
//! - **Zero risk from bounded support** (§3.7): if every parameter of the obstacle has a
//!   bounded support B and P(x, ω, t) < 0 for every ω ∈ B, the risk is exactly 0.
//! - **Shifted even-moment Markov bounds** (§3.8): for an even order 2k, a constant b < 1 and
//!   μ < 0, with c = (1 − b)·(−μ) > 0,
//!
//!   ```text
//!   Prob(z ≥ 0) ≤ E[(z + c)^2k] / c^2k = Σⱼ C(2k, j)·(bμ)^(2k−j)·cⱼ / ((1 − b)μ)^2k
//!   ```
//!
//!   (b = 0 is the Markov bound on the 2k-th central moment). Multiplied out,
//!   `H = (Δ(1−b)^2k − b^2k)·μ^2k − Σ_{j≥2} C(2k,j)·b^(2k−j)·μ^(2k−j)·cⱼ > 0` together with
//!   μ < 0 proves risk < Δ; H is a polynomial in (x, t), so it is certified continuously in
//!   time like eq. (15). Any b < 1 is sound: b is chosen per sub-interval of a piece
//!   (by [`best_shift`]) and fixed exactly before the proof.
//!
//! This module holds the exact moment polynomials, the support form of P, the choice of
//! bounds ([`BoundChoice`]) and the bounds at a point; certification over pieces is in
//! `certify::piece_bounds`.

use super::{cantelli_bound, RiskContour};
use crate::poly::{rational_to_f64, Interval, Monomial, Poly, QPoly, Var};
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The highest moment order used by the shifted Markov bounds. E\[(P − μ)⁸\] has degree
/// 8·deg P in (x, t); order 8 closes most of the gap to the true contour on the families
/// measured in docs/design.md §3.9 while keeping the restricted constraint's degree
/// (≤ 8·deg P·deg piece) within what interval Bernstein enclosures handle.
pub const MAX_MOMENT_ORDER: u32 = 8;

/// The orders of the shifted Markov bounds tried by `bound: auto`, lowest first.
pub const MOMENT_ORDERS: [u32; 3] = [4, 6, 8];

/// Budget of exact term products for the central moments of one obstacle (Σ over
/// orders of terms(Zʲ⁻¹)·terms(Z)); at about 2 µs a product this is at most about half a
/// second, once per obstacle. Orders whose expansion would exceed it are not built (the
/// obstacle then has fewer moment bounds, stated in `risk` and in [`HigherMoments::limit`]).
pub const MAX_HIGHER_MOMENT_WORK: usize = 250_000;

/// Which bounds may prove a piece or a point safe: `auto` or `cantelli`.
// Its serde names are its `as_str` names (a test holds them equal); a scene file's unknown
// name is serde's error, a request's `UnknownBound`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "lowercase")]
#[schemars(inline)]
pub enum BoundChoice {
    /// The tightest sound one (the default): Cantelli first (cheapest), then zero risk
    /// from bounded support and the shifted moment bounds of orders 4, 6 and 8, on
    /// sub-intervals (docs/design.md §5.13).
    #[default]
    Auto,
    /// Cantelli's bound only: the paper's eq. (10), (12) (the reproduction uses it).
    Cantelli,
}

/// A bound name that is not one of `auto`, `cantelli`.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("unknown bound '{0}' (expected auto or cantelli)")]
pub struct UnknownBound(pub String);

impl BoundChoice {
    /// Every choice.
    pub const ALL: [BoundChoice; 2] = [BoundChoice::Auto, BoundChoice::Cantelli];

    /// The name in requests, scene files and reports.
    pub fn as_str(&self) -> &'static str {
        match self {
            BoundChoice::Auto => "auto",
            BoundChoice::Cantelli => "cantelli",
        }
    }

    /// Whether bounds beyond Cantelli's may be used.
    pub fn beyond_cantelli(&self) -> bool {
        *self == BoundChoice::Auto
    }
}

impl std::str::FromStr for BoundChoice {
    type Err = UnknownBound;
    fn from_str(s: &str) -> Result<Self, UnknownBound> {
        BoundChoice::ALL.into_iter().find(|b| b.as_str() == s).ok_or_else(|| UnknownBound(s.to_string()))
    }
}

impl std::fmt::Display for BoundChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The bound that proved a piece (or part of one) or a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BoundKind {
    /// Cantelli (eq. (10), (12)).
    Cantelli,
    /// Zero risk: P < 0 for every parameter value in the bounded support (§3.7).
    Support,
    /// The shifted Markov bound on the moment of this even order (§3.8).
    Moment(u32),
    /// A pedestrian's Gaussian tail bound (§3.11).
    Tail,
}

impl BoundKind {
    /// `cantelli`, `support`, `moment4`, `moment6`, `moment8` (`moment` for other orders).
    pub fn as_str(&self) -> &'static str {
        match self {
            BoundKind::Cantelli => "cantelli",
            BoundKind::Support => "support",
            BoundKind::Moment(4) => "moment4",
            BoundKind::Moment(6) => "moment6",
            BoundKind::Moment(8) => "moment8",
            BoundKind::Moment(_) => "moment",
            BoundKind::Tail => "tail",
        }
    }
}

impl std::fmt::Display for BoundKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for BoundKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl BoundKind {
    /// The kinds a report names (what [`BoundKind`]'s `Deserialize` reads).
    pub const NAMED: [BoundKind; 6] = [
        BoundKind::Cantelli,
        BoundKind::Support,
        BoundKind::Moment(4),
        BoundKind::Moment(6),
        BoundKind::Moment(8),
        BoundKind::Tail,
    ];
}

impl schemars::JsonSchema for BoundKind {
    fn inline_schema() -> bool {
        true
    }

    fn schema_name() -> std::borrow::Cow<'static, str> {
        "BoundKind".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        let names: Vec<&str> = BoundKind::NAMED.iter().map(BoundKind::as_str).collect();
        schemars::json_schema!({ "type": "string", "enum": names })
    }
}

impl<'de> Deserialize<'de> for BoundKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        BoundKind::NAMED
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| serde::de::Error::custom(format!("unknown bound kind '{s}'")))
    }
}

/// Why an obstacle has fewer moment bounds than [`MAX_MOMENT_ORDER`].
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum HigherLimit {
    /// A parameter's moment of this order is not known (a moment list that stops early).
    #[error("the moment E[{param}^{order}] is not available")]
    MissingMoment {
        /// Parameter name.
        param: String,
        /// Moment order.
        order: u32,
    },
    /// Expanding the next power of P − E\[P\] would exceed [`MAX_HIGHER_MOMENT_WORK`].
    #[error("E[(P - E[P])^{order}] needs {needed} exact term products, over the limit {limit}")]
    Work {
        /// The order not built.
        order: u32,
        /// Term products it would need in all.
        needed: usize,
        /// [`MAX_HIGHER_MOMENT_WORK`].
        limit: usize,
    },
}

/// The central moments cⱼ = E\[(P − E\[P\])ʲ\] of an obstacle as polynomials in (x, t) with
/// outward-rounded interval coefficients, for j = 0 … `max_order` (c₀ = 1, c₁ = 0).
///
/// They are computed from the exact raw moments of the parameters, with every coefficient
/// an interval that encloses the exact one (each operation rounded outward, §1.3): the
/// exact rational expansion of E\[(P − μ)⁸\] costs about 0.2 s per disk of example-d1 (its
/// σ = 0.0316… is a 17-digit decimal, so the 16th moments have hundreds of digits), the
/// enclosure well under a millisecond. Every use is a proof on the enclosures (§5.13) or a
/// sound upper bound at a point (§3.10); [`exact_central`] gives the exact polynomials
/// (tests check the enclosure against it).
#[derive(Clone, Debug)]
pub struct HigherMoments {
    central_i: Vec<Poly<Interval>>,
    central_f: Vec<Poly<f64>>,
    /// Why orders above `max_order()` are missing (`None` when all of
    /// [`MAX_MOMENT_ORDER`] are there).
    pub limit: Option<HigherLimit>,
}

impl HigherMoments {
    /// The highest even order available (0 when none beyond the mean).
    pub fn max_order(&self) -> u32 {
        let top = self.central_i.len().saturating_sub(1) as u32;
        top - top % 2
    }

    /// The orders of [`MOMENT_ORDERS`] available for this obstacle.
    pub fn orders(&self) -> impl Iterator<Item = u32> + '_ {
        MOMENT_ORDERS.into_iter().filter(move |&o| o <= self.max_order())
    }

    /// The enclosures (each coefficient encloses the exact one).
    pub fn interval(&self) -> &[Poly<Interval>] {
        &self.central_i
    }

    /// The central moments at `vals` (x, t, padded) in floating point, from the
    /// enclosures' midpoints (for choosing shifts and for displays, never for decisions).
    pub fn eval_f64(&self, vals: &[f64]) -> Vec<f64> {
        self.central_f.iter().map(|c| c.eval(vals)).collect()
    }
}

/// The central moments of Z = P − E\[P\] up to [`MAX_MOMENT_ORDER`], generic over the
/// coefficient ring: by independent parameter groups where Z splits into several
/// ([`central_moments_by_groups`]), else by expanding the powers of Z.
fn central_moments<C: crate::poly::Ring>(
    z: &Poly<C>,
    is_param: impl Fn(Var) -> bool + Copy,
    moment: impl Fn(Var, u32) -> Option<C> + Copy,
    name: impl Fn(Var) -> String,
) -> (Vec<Poly<C>>, Option<HigherLimit>) {
    if let Some(central) = central_moments_by_groups(z, is_param, moment) {
        return (central, None);
    }
    central_moments_expanded(z, is_param, moment, name)
}

/// The central moments when Z's terms fall into two or more groups whose parameters are
/// disjoint (the parameters are independent, as everywhere in riskplan: E[ω^β] is the product
/// of each parameter's moment): Z = G₀ + G₁ + … + G_m with G₀ free of parameters and the G_i
/// independent, so E[(S + G)^k] = Σ_l C(k,l)·E[S^l]·E[G^(k−l)] adds one group at a time —
/// products of small polynomials in (x, t) instead of the expansion of Z^8 (which would
/// dominate the first plan of a scene of Gaussian disks). `None` (the caller expands)
/// with fewer than two parameter groups, a missing moment, or beyond the work budget. The
/// first moment is set to 0 exactly (E[Z] = 0), as the expansion does.
fn central_moments_by_groups<C: crate::poly::Ring>(
    z: &Poly<C>,
    is_param: impl Fn(Var) -> bool + Copy,
    moment: impl Fn(Var, u32) -> Option<C> + Copy,
) -> Option<Vec<Poly<C>>> {
    // union-find over the parameters that occur together in a term
    let mut parent: std::collections::BTreeMap<Var, Var> = std::collections::BTreeMap::new();
    fn root(parent: &mut std::collections::BTreeMap<Var, Var>, v: Var) -> Var {
        let mut r = v;
        while let Some(&p) = parent.get(&r) {
            if p == r {
                break;
            }
            r = p;
        }
        parent.insert(v, r);
        r
    }
    for (m, _) in z.terms() {
        let params: Vec<Var> = m.pairs().iter().map(|p| p.0).filter(|&v| is_param(v)).collect();
        for &v in &params {
            parent.entry(v).or_insert(v);
        }
        for w in params.windows(2) {
            let (a, b) = (root(&mut parent, w[0]), root(&mut parent, w[1]));
            if a != b {
                parent.insert(a, b);
            }
        }
    }
    let mut groups: std::collections::BTreeMap<Option<Var>, Poly<C>> = std::collections::BTreeMap::new();
    for (m, c) in z.terms() {
        let g = m.pairs().iter().map(|p| p.0).find(|&v| is_param(v)).map(|v| root(&mut parent, v));
        groups.entry(g).or_insert_with(Poly::zero).add_term(m.clone(), c.clone());
    }
    let deterministic = groups.remove(&None).unwrap_or_else(Poly::zero);
    if groups.len() < 2 {
        return None;
    }
    let top = MAX_MOMENT_ORDER as usize;
    let mut work = 0usize;
    // E[S^k] for S = G₀: G₀^k itself
    let mut acc: Vec<Poly<C>> = vec![Poly::constant(C::one())];
    for k in 1..=top {
        let next = acc[k - 1].mul(&deterministic);
        acc.push(next);
    }
    for g in groups.values() {
        // E[G^k], k = 0 … top
        let mut eg: Vec<Poly<C>> = vec![Poly::constant(C::one())];
        let mut power = Poly::constant(C::one());
        for _ in 1..=top {
            work += power.len() * g.len();
            power = power.mul(g);
            eg.push(power.expect(is_param, moment).ok()?);
        }
        let mut next: Vec<Poly<C>> = Vec::with_capacity(top + 1);
        for k in 0..=top {
            let mut sum = Poly::zero();
            for l in 0..=k {
                work += acc[l].len() * eg[k - l].len();
                let binom = C::from_rational(&BigRational::from_integer(binomial_exact(k as u32, l as u32).into()));
                sum = sum.add(&acc[l].mul(&eg[k - l]).scale(&binom));
            }
            next.push(sum);
        }
        if work > MAX_HIGHER_MOMENT_WORK {
            return None;
        }
        acc = next;
    }
    let mut central = vec![Poly::constant(C::one()), Poly::zero()];
    central.extend(acc.into_iter().skip(2));
    Some(central)
}

/// `C(n, k)` exactly.
fn binomial_exact(n: u32, k: u32) -> u64 {
    (0..k).fold(1u64, |acc, i| acc * u64::from(n - i) / u64::from(i + 1))
}

/// Powers of Z = P − E\[P\] and their expectations, generic over the coefficient ring, within
/// [`MAX_HIGHER_MOMENT_WORK`] term products.
fn central_moments_expanded<C: crate::poly::Ring>(
    z: &Poly<C>,
    is_param: impl Fn(Var) -> bool + Copy,
    moment: impl Fn(Var, u32) -> Option<C> + Copy,
    name: impl Fn(Var) -> String,
) -> (Vec<Poly<C>>, Option<HigherLimit>) {
    let mut central = vec![Poly::constant(C::one()), Poly::zero()];
    let mut limit = None;
    let mut power = z.clone();
    let mut work = 0usize;
    for j in 2..=MAX_MOMENT_ORDER {
        work += power.len() * z.len();
        if work > MAX_HIGHER_MOMENT_WORK {
            limit = Some(HigherLimit::Work { order: j, needed: work, limit: MAX_HIGHER_MOMENT_WORK });
            break;
        }
        power = power.mul(z);
        match power.expect(is_param, moment) {
            Ok(m) => central.push(m),
            Err((v, k)) => {
                limit = Some(HigherLimit::MissingMoment { param: name(v), order: k });
                break;
            }
        }
    }
    // an odd top order is of no use to the even bounds
    if central.len() % 2 == 0 {
        central.pop();
    }
    (central, limit)
}

pub(super) fn build_higher(c: &RiskContour) -> HigherMoments {
    build_higher_of(c, &c.poly, &c.mean)
}

/// `build_higher` for P and E\[P\] given in other coordinates of (x, t) (the parameters
/// untouched): the central moments of the same obstacle, in those coordinates (the
/// compiled fast path's centred frame, docs/design.md §5.13). Z = P − E\[P\] is formed
/// exactly before it is enclosed: its terms free of parameters cancel to nothing, where
/// enclosures of the two would leave rounding residues that every power multiplies out.
pub fn build_higher_of(c: &RiskContour, poly: &QPoly, mean: &QPoly) -> HigherMoments {
    let layout = c.layout();
    let z = poly.sub(mean).map_coeffs(Interval::enclose_rational);
    let moment = |v: Var, k: u32| c.param_moment_interval(v, k);
    let (central_i, limit) = central_moments(&z, |v| layout.is_param(v), moment, |v| c.param_name(v));
    HigherMoments { central_f: central_i.iter().map(|p| p.map_coeffs(|i| i.mid())).collect(), central_i, limit }
}

/// The exact central moments of `c` up to [`MAX_MOMENT_ORDER`] (slow for parameters with long
/// decimals; for tests and references).
pub fn exact_central(c: &RiskContour) -> Vec<QPoly> {
    let layout = c.layout();
    let z = c.poly.sub(&c.mean);
    central_moments(&z, |v| layout.is_param(v), |v, k| c.raw_moment(v, k), |v| c.param_name(v)).0
}

/// One term of the support form: ω^β as (parameter, exponent) pairs, a_β exactly and with
/// interval coefficients.
pub type SupportTerm = (Vec<(Var, u32)>, QPoly, Poly<Interval>);

/// P split by its parameter monomials, P = Σ_β a_β(x, t)·ω^β, with the bounded support of
/// every parameter (docs/design.md §3.7).
#[derive(Clone, Debug)]
pub struct SupportForm {
    /// (ω^β as (parameter, exponent) pairs, a_β exact, a_β with interval coefficients).
    pub terms: Vec<SupportTerm>,
    /// The parameters' supports, exactly: (parameter, lo, hi).
    pub support: Vec<(Var, BigRational, BigRational)>,
    /// The same supports as one box of outward-rounded intervals (converted once: the
    /// proofs on every sub-interval start from it).
    pub support_box: Vec<Interval>,
}

impl SupportForm {
    /// The form of `p`, when every parameter of `p` has a support in `support`.
    pub fn new(p: &QPoly, is_param: impl Fn(Var) -> bool, support: &[(Var, BigRational, BigRational)]) -> Option<Self> {
        let mut parts: std::collections::BTreeMap<Monomial, QPoly> = std::collections::BTreeMap::new();
        for (m, c) in p.terms() {
            let (params, rest) = m.split(&is_param);
            if params.pairs().iter().any(|(v, _)| !support.iter().any(|s| s.0 == *v)) {
                return None;
            }
            parts.entry(params).or_insert_with(QPoly::zero).add_term(rest, c.clone());
        }
        let used: Vec<Var> = p.vars().into_iter().filter(|&v| is_param(v)).collect();
        Some(SupportForm {
            terms: parts
                .into_iter()
                .map(|(m, a)| {
                    let ai = a.map_coeffs(Interval::enclose_rational);
                    (m.pairs().to_vec(), a, ai)
                })
                .collect(),
            support_box: support
                .iter()
                .filter(|s| used.contains(&s.0))
                .map(|(_, lo, hi)| Interval::new(Interval::enclose_rational(lo).lo, Interval::enclose_rational(hi).hi))
                .collect(),
            support: support.iter().filter(|s| used.contains(&s.0)).cloned().collect(),
        })
    }
}

/// The range of `w^e` for `w` in `[lo, hi]`, enclosed (outward-rounded).
pub fn power_range(w: Interval, e: u32) -> Interval {
    if e == 0 {
        return Interval::point(1.0);
    }
    let mut acc = w;
    for _ in 1..e {
        acc = acc * w;
    }
    if e % 2 == 0 {
        // an even power of an interval that contains 0 has minimum 0 (the repeated
        // product would also allow negative values)
        if w.lo <= 0.0 && w.hi >= 0.0 {
            return Interval::new(0.0, acc.hi.max(0.0));
        }
        return Interval::new(acc.lo.max(0.0), acc.hi);
    }
    acc
}

/// The range of the monomial ω^β over a box of parameter ranges (independent variables:
/// the product of the ranges of the powers is the exact range, enclosed).
pub fn monomial_range(beta: &[(Var, u32)], range_of: impl Fn(Var) -> Interval) -> Interval {
    beta.iter().fold(Interval::point(1.0), |acc, &(v, e)| acc * power_range(range_of(v), e))
}

/// `x^e` by repeated outward-rounded products (an enclosure; for the small orders here).
pub fn interval_pow(x: Interval, e: u32) -> Interval {
    (0..e).fold(Interval::point(1.0), |acc, _| acc * x)
}

/// `C(n, k)` as a float (exact for the small orders used here).
pub fn binomial_f64(n: u32, k: u32) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1))
}

/// The shifted Markov bound of order `2k` with shift `b` (< 1) from μ < 0 and the central
/// moments `c[j]`, in floating point: Σⱼ C(2k,j)·(−b)^(2k−j)·κⱼ / (1 − b)^2k with
/// κⱼ = cⱼ/(−μ)ʲ (docs/design.md §3.8). For choosing shifts and displays only.
pub fn moment_bound_f64(mu: f64, c: &[f64], order: u32, b: f64) -> f64 {
    let m = -mu;
    if m.is_nan() || m <= 0.0 || b.is_nan() || b >= 1.0 || c.len() <= order as usize {
        return f64::INFINITY;
    }
    let mut sum = (-b).powi(order as i32); // j = 0: c₀ = 1
    let mut inv = 1.0;
    for j in 1..=order {
        inv /= m;
        if j == 1 {
            continue;
        }
        sum += binomial_f64(order, j) * (-b).powi((order - j) as i32) * c[j as usize] * inv;
    }
    let v = sum / (1.0 - b).powi(order as i32);
    if v.is_nan() {
        f64::INFINITY
    } else {
        v
    }
}

/// Range searched for the shift b (docs/design.md §3.8): the optimum is near −κ₂ (Cantelli's
/// for order 2), negative and small when the bound is small; −4 … 0.9 leaves room on both sides.
pub const SHIFT_RANGE: (f64, f64) = (-4.0, 0.9);

/// The shift b minimising [`moment_bound_f64`] (a grid then golden-section refinement; a
/// heuristic — any b < 1 gives a sound bound) and its value. `None` when μ ≥ 0.
pub fn best_shift(mu: f64, c: &[f64], order: u32) -> Option<(f64, f64)> {
    best_shift_until(mu, c, order, f64::NEG_INFINITY)
}

/// [`best_shift`], stopping at the first shift whose value is at most `stop` (for a
/// question such as "is some bound below Δ here?", where any such shift answers it).
pub fn best_shift_until(mu: f64, c: &[f64], order: u32, stop: f64) -> Option<(f64, f64)> {
    shift_search(mu, c, order, stop, SHIFT_SEARCH_FINE)
}

/// Grid points and golden-section steps of a shift search.
#[derive(Clone, Copy, Debug)]
pub struct ShiftSearch {
    /// Grid intervals over [`SHIFT_RANGE`].
    pub grid: usize,
    /// Golden-section steps around the best grid point.
    pub golden: usize,
}

/// The search of [`best_shift`] (reported bounds: 24 grid intervals, then 24 golden
/// steps narrow b to about 10⁻⁵ of the range).
pub const SHIFT_SEARCH_FINE: ShiftSearch = ShiftSearch { grid: 24, golden: 24 };

/// A coarser search for the certifier's choices and give-up tests (half the
/// evaluations; b to about 10⁻³ of the range, where the bound is flat to a fraction of a
/// percent): any b < 1 gives a sound constraint, and a give-up test that sees a
/// slightly larger minimum only gives up slightly earlier.
pub const SHIFT_SEARCH_COARSE: ShiftSearch = ShiftSearch { grid: 12, golden: 12 };

/// The shift search with its effort `search`, stopping at the first value at most `stop`.
pub fn shift_search(mu: f64, c: &[f64], order: u32, stop: f64, search: ShiftSearch) -> Option<(f64, f64)> {
    if mu.is_nan() || mu >= 0.0 || c.len() <= order as usize {
        return None;
    }
    // the bound as a polynomial in u = −b over (1 + u)^2k: Σⱼ C(2k,j)·κⱼ·u^(2k−j) with
    // κⱼ = cⱼ/(−μ)^j (κ₀ = 1, κ₁ = 0), evaluated by Horner (the same value as
    // [`moment_bound_f64`], a few flops per shift)
    let m = -mu;
    let mut coef = [0.0f64; MAX_MOMENT_ORDER as usize + 1]; // coef[i]: factor of u^i
    let mut inv = 1.0;
    for j in 0..=order {
        if j > 0 {
            inv /= m;
        }
        if j != 1 {
            coef[(order - j) as usize] = binomial_f64(order, j) * c[j as usize] * inv;
        }
    }
    coef[order as usize] = 1.0;
    let f = |b: f64| {
        let u = -b;
        let num = coef[..=order as usize].iter().rev().fold(0.0, |acc, &a| acc * u + a);
        let v = num / (1.0 - b).powi(order as i32);
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    let (lo, hi) = SHIFT_RANGE;
    let n = search.grid.max(2);
    let grid = |i: usize| lo + (hi - lo) * i as f64 / n as f64;
    let (mut best_i, mut best) = (0, f64::INFINITY);
    for i in 0..=n {
        let v = f(grid(i));
        if v <= stop {
            return Some((grid(i), v));
        }
        if v < best {
            best = v;
            best_i = i;
        }
    }
    // golden-section search between the grid neighbours of the best grid point, one new
    // evaluation per step
    let (mut a, mut b) = (grid(best_i.saturating_sub(1)), grid((best_i + 1).min(n)));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..search.golden {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = f(x2);
        }
    }
    let bm = 0.5 * (a + b);
    let vm = f(bm);
    let (b, v) = if vm < best { (bm, vm) } else { (grid(best_i), best) };
    v.is_finite().then_some((b, v))
}

/// The shifted Markov bound at a point, exactly: `Σⱼ C(2k,j)(bμ)^(2k−j)cⱼ / ((1−b)μ)^2k`,
/// or 1 when μ ≥ 0 or b ≥ 1 (no bound).
pub fn moment_bound_exact(mu: &BigRational, c: &[BigRational], order: u32, b: &BigRational) -> BigRational {
    let one = BigRational::one();
    if !mu.is_negative() || b >= &one || c.len() <= order as usize {
        return one;
    }
    let bm = b * mu;
    let mut num = BigRational::zero();
    for j in 0..=order {
        if j == 1 {
            continue;
        }
        let cj = if j == 0 { one.clone() } else { c[j as usize].clone() };
        num += crate::moments::binomial(order, j) * pow_q(&bm, order - j) * cj;
    }
    let den = pow_q(&((&one - b) * mu), order);
    let v = num / den;
    if v > one {
        one
    } else {
        v
    }
}

fn pow_q(x: &BigRational, e: u32) -> BigRational {
    (0..e).fold(BigRational::one(), |acc, _| acc * x)
}

/// One shifted Markov bound at a point.
#[derive(Clone, Debug, PartialEq)]
pub struct MomentAtPoint {
    /// Its order 2k.
    pub order: u32,
    /// The shift b used (the minimiser found by [`best_shift`], exact as a float).
    pub shift: f64,
    /// A proven upper bound of the bound's value at the point (the interval evaluation's
    /// upper end, a float taken exactly), at most 1.
    pub value: BigRational,
}

/// Every bound at one point (docs/design.md §3.10).
#[derive(Clone, Debug, PartialEq)]
pub struct PointBounds {
    /// Cantelli's, exact (1 where E\[P\] > 0).
    pub cantelli: BigRational,
    /// `Some(true)`: P < 0 for every parameter in the bounded support, proven (risk 0);
    /// `Some(false)`: not proven; `None`: some parameter's support is unbounded.
    pub support_zero: Option<bool>,
    /// The shifted Markov bounds of each available order.
    pub moments: Vec<MomentAtPoint>,
    /// Why orders are missing, if they are.
    pub moment_limit: Option<HigherLimit>,
}

impl PointBounds {
    /// The smallest bound and its kind.
    pub fn best(&self) -> (BoundKind, BigRational) {
        if self.support_zero == Some(true) {
            return (BoundKind::Support, BigRational::zero());
        }
        let mut best = (BoundKind::Cantelli, self.cantelli.clone());
        for m in &self.moments {
            if m.value < best.1 {
                best = (BoundKind::Moment(m.order), m.value.clone());
            }
        }
        best
    }
}

/// An upper bound of the shifted Markov bound of order `2k` with shift `b` from enclosures
/// of μ (< 0) and the central moments, in interval arithmetic (`None` if μ is not
/// proven negative or the result is not finite).
pub fn moment_bound_upper(mu: Interval, c: &[Interval], order: u32, b: f64) -> Option<f64> {
    if mu.hi.is_nan() || mu.hi >= 0.0 || b.is_nan() || b >= 1.0 || c.len() <= order as usize {
        return None;
    }
    let pow = interval_pow;
    let bm = Interval::point(b) * mu;
    let mut num = pow(bm, order);
    for (j, cj) in c.iter().enumerate().take(order as usize + 1).skip(2) {
        num = num + Interval::point(binomial_f64(order, j as u32)) * pow(bm, order - j as u32) * *cj;
    }
    let den = pow((Interval::point(1.0) - Interval::point(b)) * mu, order);
    if den.lo.is_nan() || den.lo <= 0.0 || !num.hi.is_finite() {
        return None;
    }
    let up = (num.hi.max(0.0) / den.lo).next_up();
    up.is_finite().then_some(up)
}

/// Enclosures of the central moments c₀ … c_top at the point `xt`, formed without the
/// dependency problem of evaluating the expanded cⱼ(x, t): P = Σ_β a_β(x, t)·ω^β is split by
/// its parameter monomials, each a_β is evaluated exactly at the point, and
/// Z = Σ_{β≠0} a_β·(ω^β − E\[ω^β\]) (its parameter-free part cancels exactly) is raised to
/// powers in the parameters alone, in interval arithmetic, within the same work budget.
/// `None` when the orders stop before 4.
pub fn central_at_point(c: &RiskContour, xt: &[BigRational]) -> Option<Vec<Interval>> {
    let layout = c.layout();
    let vals = c.pad(xt, BigRational::zero());
    let mut parts: std::collections::BTreeMap<Monomial, BigRational> = std::collections::BTreeMap::new();
    for (m, coef) in c.poly.terms() {
        let (params, rest) = m.split(|v| layout.is_param(v));
        if params.pairs().is_empty() {
            continue;
        }
        let mut v = coef.clone();
        for &(var, e) in rest.pairs() {
            v *= num_traits::Pow::pow(&vals[var as usize], e);
        }
        *parts.entry(params).or_insert_with(BigRational::zero) += v;
    }
    let moment = |v: Var, k: u32| c.param_moment_interval(v, k);
    let mut z: Poly<Interval> = Poly::zero();
    let mut shift = Interval::point(0.0);
    for (m, a) in &parts {
        let ai = Interval::enclose_rational(a);
        let mut mom = Interval::point(1.0);
        for &(v, e) in m.pairs() {
            mom = mom * moment(v, e)?;
        }
        z.add_term(m.clone(), ai);
        shift = shift + ai * mom;
    }
    z.add_term(Monomial::one(), -shift);
    let (central, _) = central_moments(&z, |v| layout.is_param(v), moment, |v| c.param_name(v));
    let out: Vec<Interval> = central.iter().map(|p| p.eval(&[])).collect();
    (out.len() > MOMENT_ORDERS[0] as usize).then_some(out)
}

/// Every bound at `xt` (x1..xn, t): Cantelli's exactly, the moment bounds as proven upper
/// bounds from the enclosures, and `support_negative` (the support proof at the point,
/// done by the caller).
pub fn point_bounds(c: &RiskContour, xt: &[BigRational], support_negative: Option<bool>) -> PointBounds {
    let r = c.risk_at(xt);
    let cantelli = cantelli_bound(&r.mean, &r.second_moment);
    let hm = c.higher();
    let mut moments = Vec::new();
    if r.mean.is_negative() && hm.max_order() >= MOMENT_ORDERS[0] {
        // at the point first (tight), else the expanded enclosures evaluated there
        let enc: Vec<Interval> = central_at_point(c, xt).unwrap_or_else(|| {
            let mut vals: Vec<Interval> = xt.iter().map(Interval::enclose_rational).collect();
            vals.resize(c.layout().xt_len(), Interval::point(0.0));
            hm.interval().iter().map(|p| p.eval(&vals)).collect()
        });
        let mid: Vec<f64> = enc.iter().map(|i| i.mid()).collect();
        let mu = Interval::enclose_rational(&r.mean);
        for order in hm.orders() {
            let Some((b, _)) = best_shift(rational_to_f64(&r.mean), &mid, order) else { continue };
            let Some(up) = moment_bound_upper(mu, &enc, order, b) else { continue };
            let value = BigRational::from_float(up.min(1.0)).unwrap_or_else(BigRational::one);
            moments.push(MomentAtPoint { order, shift: b, value });
        }
    }
    PointBounds { cantelli, support_zero: support_negative, moments, moment_limit: hm.limit.clone() }
}

/// Whether `r`, a polynomial in the parameters of the contour's obstacle, is proven
/// negative on their bounded support (every parameter of `r` has one): the interval hull
/// of its terms over the support box is below 0 (§3.7). Then P(r ≥ 0) = 0.
pub fn support_negative(c: &RiskContour, r: &QPoly) -> bool {
    let Some(support) = c.support() else { return false };
    let range_of = |v: Var| {
        support
            .support
            .iter()
            .find(|s| s.0 == v)
            .map(|(_, lo, hi)| Interval::new(Interval::enclose_rational(lo).lo, Interval::enclose_rational(hi).hi))
    };
    if !r.vars().into_iter().all(|v| range_of(v).is_some()) {
        return false;
    }
    let mut hull = Interval::point(0.0);
    for (m, k) in r.terms() {
        let range =
            monomial_range(m.pairs(), |v| range_of(v).unwrap_or(Interval::new(f64::NEG_INFINITY, f64::INFINITY)));
        hull = hull + Interval::enclose_rational(k) * range;
    }
    hull.hi < 0.0
}

/// An upper bound on Prob(r(ω) ≥ 0) for a polynomial `r` in the parameters of the contour's
/// obstacle alone (no x, no t), from their moments: the smallest of Cantelli's bound
/// Var(r)/(Var(r) + E\[r\]²) when E\[r\] < 0 (Theorem 1), the shifted Markov bounds of the
/// orders of [`MOMENT_ORDERS`] (§3.8; any shift b < 1 is sound, the shift is chosen in
/// floating point), and 0 when every parameter has a bounded support on which `r` is proven
/// negative (§3.7); 1 when E\[r\] ≥ 0. Used for the Bernstein coefficients of a piece's
/// restriction (docs/design.md §5.14). E\[r\] is exact; r − E\[r\] is formed exactly and
/// then enclosed, so the central moments are enclosures (as in [`build_higher_of`]), and
/// each bound is an upper end of an outward-rounded evaluation. `None` when `r` contains a
/// variable that is not a parameter, or a moment it needs is unknown.
pub fn exceedance_bound(c: &RiskContour, r: &QPoly) -> Option<(BoundKind, BigRational)> {
    let layout = c.layout();
    let is_param = |v: Var| layout.is_param(v);
    if r.vars().into_iter().any(|v| !is_param(v)) {
        return None;
    }
    let mean = r.expect(is_param, |v, k| c.raw_moment(v, k)).ok()?.constant_term();
    let one = BigRational::one();
    if !mean.is_negative() {
        return Some((BoundKind::Cantelli, one));
    }
    if support_negative(c, r) {
        return Some((BoundKind::Support, BigRational::zero()));
    }
    let z = r.sub(&QPoly::constant(mean.clone())).map_coeffs(Interval::enclose_rational);
    let (central, _) = central_moments(&z, is_param, |v, k| c.param_moment_interval(v, k), |v| c.param_name(v));
    let cs: Vec<Interval> = central.iter().map(|p| p.constant_term()).collect();
    // Cantelli from an upper end of the variance, exactly: v/(v + μ²) grows with v
    let mut best = (BoundKind::Cantelli, one.clone());
    if let Some(var) = cs.get(2).and_then(|v| crate::poly::f64_to_rational(v.hi.max(0.0))) {
        let denom = &var + &mean * &mean;
        if denom.is_positive() {
            best.1 = (var / denom).min(one.clone());
        }
    }
    let mu_i = Interval::enclose_rational(&mean);
    let mu_f = rational_to_f64(&mean);
    let cf: Vec<f64> = cs.iter().map(|i| i.mid()).collect();
    for order in MOMENT_ORDERS {
        if cs.len() <= order as usize {
            break;
        }
        let Some((b, _)) = best_shift(mu_f, &cf, order) else { continue };
        if let Some(v) = moment_bound_upper(mu_i, &cs, order, b).and_then(crate::poly::f64_to_rational) {
            if v < best.1 {
                best = (BoundKind::Moment(order), v);
            }
        }
    }
    Some(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names serde (and so the scene files and the JSON Schemas) use for a bound
    /// choice are its `as_str` names, in `ALL`'s order.
    #[test]
    fn bound_choice_serde_names_are_its_names() {
        // documented variants: one `const` per variant under `oneOf` (else an `enum`)
        let schema = schemars::schema_for!(BoundChoice);
        let names: Vec<&str> = match (schema.get("enum"), schema.get("oneOf")) {
            (Some(e), _) => e.as_array().expect("a list").iter().filter_map(|v| v.as_str()).collect(),
            (None, Some(o)) => o.as_array().expect("a list").iter().filter_map(|v| v.get("const")?.as_str()).collect(),
            _ => panic!("no names in {schema:?}"),
        };
        assert_eq!(names, BoundChoice::ALL.map(|b| b.as_str()));
        for b in BoundChoice::ALL {
            assert_eq!(b.as_str().parse::<BoundChoice>(), Ok(b));
        }
    }

    /// Central moments by independent parameter groups equal the expansion of the powers of
    /// Z, exactly (rationals), for Gaussian, uniform and discrete parameters in two to three
    /// groups, one group with two coupled parameters, and a moving centre.
    #[test]
    fn moments_by_groups_equal_the_expansion_exactly() {
        use crate::moments::Distribution;
        use crate::poly::{parse, parse_decimal, VarTable};
        let q = |v: &str| parse_decimal(v).unwrap();
        // a contour in 2-D over named parameters (x1, x2, t, then the parameters)
        let contour = |text: &str, params: &[(&str, Distribution)]| {
            let mut names: Vec<String> = ["x1", "x2", "t"].map(String::from).to_vec();
            names.extend(params.iter().map(|(n, _)| n.to_string()));
            let vars = VarTable::new(names);
            let p = parse(text, &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).unwrap();
            let moments: Vec<Vec<BigRational>> = params.iter().map(|(_, d)| d.raw_moments(64).unwrap()).collect();
            let lookup = |v: Var, k: u32| moments.get(v as usize - 3).and_then(|m| m.get(k as usize)).cloned();
            RiskContour::new(super::super::Layout { dim: 2 }, &p, &lookup, &|v| vars.name(v)).unwrap()
        };
        let n = || Distribution::Normal { mean: q("0.1"), std: q("0.05") };
        let u = || Distribution::Uniform { low: q("0.3"), high: q("0.4") };
        let cases: Vec<(&str, Vec<(&str, Distribution)>)> = vec![
            ("0.09 - (x1 - 2 - a)^2 - (x2 - 2.7 - b)^2", vec![("a", n()), ("b", n())]),
            ("r^2 - (x1 - a - 0.5*t)^2 - (x2 - b*t)^2", vec![("r", u()), ("a", n()), ("b", u())]),
            ("r^2*(1 + a*b) - x1^2 - (x2 - c)^2", vec![("r", u()), ("a", n()), ("b", n()), ("c", n())]),
        ];
        for (text, params) in cases {
            let c = contour(text, &params);
            let layout = c.layout();
            let z = c.poly.sub(&c.mean);
            let moment = |v: Var, k: u32| c.raw_moment(v, k);
            let by_groups = central_moments_by_groups(&z, |v| layout.is_param(v), moment).expect("two or more groups");
            let (expanded, limit) = central_moments_expanded(&z, |v| layout.is_param(v), moment, |v| c.param_name(v));
            assert!(limit.is_none(), "{text}: {limit:?}");
            assert_eq!(by_groups.len(), expanded.len(), "{text}");
            for (j, (g, e)) in by_groups.iter().zip(&expanded).enumerate() {
                assert!(g.sub(e).is_zero(), "{text}: order {j} differs");
            }
        }
    }

    /// Order 2 with the optimal shift b = −σ²/μ² is Cantelli's bound (docs/design.md §3.8).
    #[test]
    fn order_two_with_the_optimal_shift_is_cantelli() {
        let (mu, var) = (-1.5f64, 0.7f64);
        let c = [1.0, 0.0, var];
        let b = -var / (mu * mu);
        let v = moment_bound_f64(mu, &c, 2, b);
        assert!((v - var / (var + mu * mu)).abs() < 1e-15);
        let (_, best) = best_shift(mu, &c, 2).unwrap();
        assert!((best - var / (var + mu * mu)).abs() < 1e-9, "{best}");
    }

    /// The Horner form that [`best_shift`] minimises is [`moment_bound_f64`]: its value at
    /// the shift it returns agrees, and no grid shift is lower.
    #[test]
    fn best_shift_value_is_the_formula_at_its_shift() {
        let c = [1.0, 0.0, 0.3, -0.05, 0.4, 0.02, 0.9, 0.1, 3.0];
        for mu in [-0.4f64, -1.5, -7.0] {
            for order in [4, 6, 8] {
                let (b, v) = best_shift(mu, &c, order).unwrap();
                let direct = moment_bound_f64(mu, &c, order, b);
                assert!((v - direct).abs() <= 1e-12 * direct.abs(), "{mu} {order}: {v} vs {direct}");
                for i in 0..=200 {
                    let g = SHIFT_RANGE.0 + (SHIFT_RANGE.1 - SHIFT_RANGE.0) * i as f64 / 200.0;
                    assert!(v <= moment_bound_f64(mu, &c, order, g) * (1.0 + 1e-9), "{mu} {order} at {g}");
                }
            }
        }
    }

    /// The exact bound equals the float one and the central-moment Markov bound at b = 0.
    #[test]
    fn exact_bound_matches_its_formula() {
        let q = |n: i64, d: i64| BigRational::new(n.into(), d.into());
        let mu = q(-3, 2);
        let c = vec![q(1, 1), q(0, 1), q(1, 2), q(1, 10), q(3, 4), q(0, 1), q(2, 1), q(0, 1), q(9, 1)];
        assert_eq!(moment_bound_exact(&mu, &c, 4, &q(0, 1)), q(3, 4) / pow_q(&mu, 4));
        assert_eq!(moment_bound_exact(&mu, &c, 8, &q(0, 1)), q(9, 1) / pow_q(&mu, 8));
        let b = q(-1, 8);
        let fl: Vec<f64> = c.iter().map(rational_to_f64).collect();
        let e = rational_to_f64(&moment_bound_exact(&mu, &c, 6, &b));
        assert!((e - moment_bound_f64(-1.5, &fl, 6, -0.125)).abs() < 1e-14 * e.max(1.0));
        // μ ≥ 0: no bound
        assert_eq!(moment_bound_exact(&q(0, 1), &c, 4, &b), q(1, 1));
    }

    #[test]
    fn power_and_monomial_ranges() {
        let w = Interval::new(-0.5, 2.0);
        let r2 = power_range(w, 2);
        assert!(r2.lo == 0.0 && r2.hi >= 4.0 && r2.hi < 4.0 + 1e-12);
        let r3 = power_range(w, 3);
        assert!(r3.lo <= -0.125 && r3.hi >= 8.0);
        let m =
            monomial_range(
                &[(3, 2), (4, 1)],
                |v| if v == 3 { Interval::new(1.0, 2.0) } else { Interval::new(-1.0, 1.0) },
            );
        assert!(m.lo <= -4.0 && m.hi >= 4.0 && m.lo > -4.0 - 1e-12);
    }
}
