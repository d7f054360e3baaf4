//! Rigorous enclosures of a parameter's probability of lying in an interval — for the
//! whole-path bound's partition of the parameter space (docs/design.md §5.14). Three
//! families have a distribution function that can be evaluated with a proof:
//!
//! - **uniform** on [L, H]: (min(b, H) − max(a, L))/(H − L), outward-rounded;
//! - **normal** N(μ, σ²): Φ((x − μ)/σ) with Φ(z) = ½ + ½·erf(z/√2) by the alternating
//!   Maclaurin series of erf (|z| ≤ [`SERIES_LIMIT`]; the first omitted term bounds the
//!   remainder once the terms decrease) in outward-rounded interval arithmetic, and beyond
//!   it the Mills-ratio bound 1 − Φ(z) ≤ φ(z)/z;
//! - **beta** with integer α, β ≤ [`MAX_BETA_INTEGER`] on [L, H]: the regularised
//!   incomplete beta function is then the binomial tail
//!   Σ_{j=α}^{n} C(n, j)·uʲ(1 − u)^(n−j), n = α + β − 1, a polynomial in u.
//!
//! - **discrete**: the atoms (an atom that may equal x counts in the upper end only);
//! - **exponential** and **Laplace**: 1 − e^(−λx) and ½e^z / 1 − ½e^(−z), the platform's
//!   `exp` widened by [`TAIL_REL_MARGIN`], over [`EXP_SPAN_RATES`] scales;
//! - **gamma with an integer shape** k ≤ 64 (Erlang): 1 − e^(−y)·Σ_{j<k} yʲ/j!.
//!
//! Gamma and beta with real shapes in [`incomplete::MIN_SHAPE`, `incomplete::MAX_SHAPE`]
//! use the rigorous series of [`incomplete`]; parameters known only by their moments (moment
//! lists, shapes outside that range) get a moment law ([`CdfLaw::from_moments`]): F enclosed
//! by Cantelli and even-order Markov bounds about the mean (design.md §5.14).

use super::incomplete;
use super::Distribution;
use crate::poly::Interval;
use num_rational::BigRational;
use num_traits::{One, Signed, ToPrimitive, Zero};

/// |z| up to which Φ(z) comes from the erf series: erf's argument is then at most 2.9, the
/// largest term of the series about 5·10², so cancellation costs at most about 10⁻¹¹ of
/// absolute width.
pub const SERIES_LIMIT: f64 = 4.1;

/// A normal parameter's partition covers μ ± this many σ; the mass outside,
/// 2·(1 − Φ(9)) < 2.3·10⁻¹⁹, is added to every bound that uses it.
pub const NORMAL_SPAN_SIGMAS: f64 = 9.0;

/// Relative widening of the Mills-ratio tail, computed with the platform's `exp` (within
/// a few ulps) and four roundings: 10⁻¹² covers them with a margin of 10³ — the same
/// margin as the incomplete gamma and beta functions' elementary functions.
pub const TAIL_REL_MARGIN: f64 = incomplete::ELEMENTARY_REL_MARGIN;

/// The least tail [`mills_upper`] returns: 10⁻³⁰⁰ is above every normal tail beyond
/// z = 37.1 (where the quotient nears the subnormal range), and negligible beside any
/// probability a plan uses.
pub const MILLS_FLOOR: f64 = 1e-300;

/// Largest integer shape of a beta parameter handled by its binomial-tail form (the
/// polynomial has α + β terms).
pub const MAX_BETA_INTEGER: u64 = 64;

/// `a + b` rounded up (both ≥ 0): sums of upper bounds of probabilities stay upper bounds
/// (exact when either is 0).
pub fn add_up(a: f64, b: f64) -> f64 {
    if a == 0.0 {
        b
    } else if b == 0.0 {
        a
    } else {
        (a + b).next_up()
    }
}

/// A parameter's law, in the form the partition needs: its range and the probability of
/// any sub-interval, bounded from above.
#[derive(Clone, Debug, PartialEq)]
pub struct CdfLaw {
    /// The range partitioned (the support, or μ ± [`NORMAL_SPAN_SIGMAS`]·σ).
    pub lo: f64,
    /// Upper end of the range.
    pub hi: f64,
    /// An upper bound of the probability outside `[lo, hi]`.
    pub outside: f64,
    kind: Kind,
}

#[derive(Clone, Debug, PartialEq)]
enum Kind {
    /// Uniform on [a, b] (enclosures of the exact ends; `a.lo`, `b.hi` are `lo`, `hi`).
    Uniform { a: Interval, b: Interval },
    /// Normal: μ and 1/σ enclosed.
    Normal { mu: Interval, inv_sigma: Interval },
    /// Beta(α, β) with integer shapes on [low, low + width].
    Beta { alpha: u32, beta: u32, low: Interval, inv_width: Interval },
    /// A point mass (σ = 0, or a uniform of zero width).
    Point { at: Interval },
    /// Finitely many atoms (value and weight enclosed), sorted by value.
    Discrete { atoms: Vec<(Interval, Interval)> },
    /// Exponential with rate λ (λ enclosed).
    Exponential { rate: Interval },
    /// Laplace: μ and 1/b enclosed.
    Laplace { mu: Interval, inv_scale: Interval },
    /// Gamma with an integer shape k (Erlang) and 1/θ enclosed.
    Erlang { shape: u32, inv_scale: Interval },
    /// Gamma with another shape a (enclosed), 1/θ and Γ(a) enclosed.
    Gamma { shape: Interval, inv_scale: Interval, gamma: Interval },
    /// Beta(α, β) with other shapes on [low, low + width]; B(α, β) enclosed.
    BetaReal { alpha: Interval, beta: Interval, b: Interval, low: Interval, inv_width: Interval },
    /// Known by its moments only: the mean, the variance and the even central moments of
    /// order ≥ 4 (enclosed), and the support when one is known (floats at or beyond its ends).
    Moments {
        mean: Interval,
        var: Interval,
        central: Vec<(u32, Interval)>,
        support: (Option<f64>, Option<f64>),
        /// Distances ρₖ from the mean where the moment bound falls to 2⁻ᵏ, k = 1, 2, …:
        /// the partition's split points (see [`CdfLaw::split`]).
        grid: Vec<f64>,
    },
}

/// The probability a parameter known by its moments only is given outside its range: the
/// range is μ ± r with r the least radius whose moment bound τ(r) is at most this
/// (negligible beside any risk level; added to every bound that uses the parameter).
pub const MOMENT_LAW_TAIL: f64 = 1e-12;

/// Raw moments used for a gamma or beta parameter known by its moments only (orders up to
/// 8: the Markov bound of order 8 decays as d⁻⁸).
pub const MOMENT_LAW_ORDER: u32 = 8;

impl CdfLaw {
    /// The law of a distribution, when it is one of the families above (module docs).
    pub fn of(d: &Distribution) -> Option<CdfLaw> {
        let enc = Interval::enclose_rational;
        // (an inverse that overflows would leave the law useless: none then)
        let inv =
            |q: &BigRational| (q.is_positive()).then(|| enc(&(BigRational::one() / q))).filter(|i| i.hi.is_finite());
        match d {
            Distribution::Uniform { low, high } => {
                let (a, b) = (enc(low), enc(high));
                if low == high {
                    return Some(CdfLaw { lo: a.lo, hi: a.hi, outside: 0.0, kind: Kind::Point { at: a } });
                }
                finite(CdfLaw { lo: a.lo, hi: b.hi, outside: 0.0, kind: Kind::Uniform { a, b } })
            }
            Distribution::Normal { mean, std } => {
                let mu = enc(mean);
                if std.is_zero() {
                    return finite(CdfLaw { lo: mu.lo, hi: mu.hi, outside: 0.0, kind: Kind::Point { at: mu } });
                }
                let span = Interval::point(NORMAL_SPAN_SIGMAS) * enc(std);
                let (lo, hi) = ((mu - span).lo, (mu + span).hi);
                // 1 − Φ(9) on each side, bounded by the Mills ratio
                let outside = 2.0 * mills_upper(NORMAL_SPAN_SIGMAS);
                finite(CdfLaw { lo, hi, outside, kind: Kind::Normal { mu, inv_sigma: inv(std)? } })
            }
            Distribution::Beta { alpha, beta, low, high } => {
                let int = |q: &BigRational| {
                    (q.is_integer() && q.is_positive())
                        .then(|| q.to_integer().to_u64())
                        .flatten()
                        .filter(|&k| k <= MAX_BETA_INTEGER)
                };
                let (l, h) = (enc(low), enc(high));
                let (Some(a), Some(b)) = (int(alpha), int(beta)) else {
                    let (a, b) = (enc(alpha), enc(beta));
                    let Some(bf) = incomplete::beta_fn(a, b) else {
                        let raw = d.raw_moments(MOMENT_LAW_ORDER).ok()?;
                        return CdfLaw::from_moments(&raw[1..], Some(l.lo), Some(h.hi));
                    };
                    return finite(CdfLaw {
                        lo: l.lo,
                        hi: h.hi,
                        outside: 0.0,
                        kind: Kind::BetaReal { alpha: a, beta: b, b: bf, low: l, inv_width: inv(&(high - low))? },
                    });
                };
                let (a, b) = (a as u32, b as u32);
                finite(CdfLaw {
                    lo: l.lo,
                    hi: h.hi,
                    outside: 0.0,
                    kind: Kind::Beta { alpha: a, beta: b, low: l, inv_width: inv(&(high - low))? },
                })
            }
            Distribution::Discrete { values, weights } => {
                let mut atoms: Vec<(Interval, Interval)> =
                    values.iter().zip(weights).map(|(v, w)| (enc(v), enc(w))).collect();
                atoms.sort_by(|a, b| a.0.lo.total_cmp(&b.0.lo));
                let lo = atoms.iter().map(|a| a.0.lo).fold(f64::INFINITY, f64::min);
                let hi = atoms.iter().map(|a| a.0.hi).fold(f64::NEG_INFINITY, f64::max);
                finite(CdfLaw { lo, hi, outside: 0.0, kind: Kind::Discrete { atoms } })
            }
            Distribution::Exponential { rate } => {
                // [0, EXP_SPAN_RATES/λ]: the mass beyond is e^(−45) < 2.9·10⁻²⁰
                let inv = inv(rate)?;
                let hi = (Interval::point(EXP_SPAN_RATES) * inv).hi;
                let outside = exp_upper(-EXP_SPAN_RATES);
                finite(CdfLaw { lo: 0.0, hi, outside, kind: Kind::Exponential { rate: enc(rate) } })
            }
            Distribution::Laplace { mean, scale } => {
                let mu = enc(mean);
                let span = Interval::point(EXP_SPAN_RATES) * enc(scale);
                let (lo, hi) = ((mu - span).lo, (mu + span).hi);
                let outside = exp_upper(-EXP_SPAN_RATES);
                finite(CdfLaw { lo, hi, outside, kind: Kind::Laplace { mu, inv_scale: inv(scale)? } })
            }
            Distribution::Gamma { shape, scale } => {
                let Some(k) = (shape.is_integer() && shape.is_positive())
                    .then(|| shape.to_integer().to_u64())
                    .flatten()
                    .filter(|&k| k <= MAX_BETA_INTEGER)
                else {
                    // [0, Y·θ] with Y = incomplete::gamma_split(a): the tail beyond is
                    // Γ(a, Y)/Γ(a), bounded from its enclosures
                    let a = enc(shape);
                    let Some(gamma) = incomplete::gamma_fn(a) else {
                        return CdfLaw::from_moments(&d.raw_moments(MOMENT_LAW_ORDER).ok()?[1..], Some(0.0), None);
                    };
                    let y = incomplete::gamma_split(a.hi);
                    let hi = (Interval::point(y) * enc(scale)).hi;
                    let tail = incomplete::upper_gamma_tail(a, y)?;
                    let outside = incomplete::div_pos(Interval::point(tail), gamma).hi.min(1.0);
                    return finite(CdfLaw {
                        lo: 0.0,
                        hi,
                        outside,
                        kind: Kind::Gamma { shape: a, inv_scale: inv(scale)?, gamma },
                    });
                };
                let k = k as u32;
                // [0, y·θ] with y = k + 10√k + 50: the tail e^(−y)·Σ_{j<k} y^j/j! is below
                // 10⁻²⁰ for every k ≤ 64 (bounded here from its enclosure)
                let y = f64::from(k) + 10.0 * f64::from(k).sqrt() + 50.0;
                let hi = (Interval::point(y) * enc(scale)).hi;
                let outside = erlang_tail_upper(k, y);
                finite(CdfLaw { lo: 0.0, hi, outside, kind: Kind::Erlang { shape: k, inv_scale: inv(scale)? } })
            }
            // only the longest prefix that is a moment sequence (the Hankel check of
            // raw_moments, as the scene's moments use): a list whose higher orders no law
            // has would otherwise make the moment inequalities claim too much
            Distribution::Moments { raw } => {
                let k = (2..=raw.len()).rev().find(|&k| d.raw_moments(k as u32).is_ok())?;
                CdfLaw::from_moments(&raw[..k], None, None)
            }
        }
    }

    /// The law of a parameter known by its raw moments `raw[k − 1]` = E[ω^k] (at least the
    /// mean and the second moment), with a support [low, high] when one is known (module
    /// docs). `None` when the variance is not positive and finite.
    pub fn from_moments(raw: &[BigRational], low: Option<f64>, high: Option<f64>) -> Option<CdfLaw> {
        if raw.len() < 2 {
            return None;
        }
        let mean = &raw[0];
        // central moments c_j = Σᵢ C(j, i)·mᵢ·(−μ)^(j−i), exactly
        let central = |j: usize| -> BigRational {
            let mut c = BigRational::zero();
            let minus_mu = -mean.clone();
            for i in 0..=j {
                let m_i = if i == 0 { BigRational::one() } else { raw[i - 1].clone() };
                c += super::binomial(j as u32, i as u32) * m_i * num_traits::pow(minus_mu.clone(), j - i);
            }
            c
        };
        let enc = Interval::enclose_rational;
        let var = enc(&central(2));
        if (var.lo.is_nan() || var.lo <= 0.0) || !var.hi.is_finite() {
            return None;
        }
        let higher: Vec<(u32, Interval)> = (4..=raw.len())
            .step_by(2)
            .map(|j| (j as u32, enc(&central(j))))
            .filter(|(_, c)| c.lo >= 0.0 && c.hi.is_finite())
            .collect();
        let mu = enc(mean);
        // the least radius where one of the bounds is at most p (a float estimate: split
        // points and the range's radius may be any numbers, the masses are computed after)
        let radius = |p: f64| {
            let mut r = (var.hi * (1.0 / p - 1.0)).sqrt();
            for (j, c) in &higher {
                r = r.min((c.hi / p).powf(1.0 / f64::from(*j)));
            }
            r
        };
        let grid: Vec<f64> = (1..)
            .map(|k| (-(k as f64)).exp2())
            .take_while(|&p| p >= MOMENT_LAW_TAIL)
            .map(radius)
            .filter(|r| r.is_finite() && *r > 0.0)
            .collect();
        let r = radius(MOMENT_LAW_TAIL) * (1.0 + 1e-9);
        let kind = Kind::Moments { mean: mu, var, central: higher, support: (low, high), grid };
        let (mut lo, mut hi) = ((mu - Interval::point(r)).lo, (mu + Interval::point(r)).hi);
        let (mut out_lo, mut out_hi) = (true, true);
        if let Some(l) = low.filter(|&l| l >= lo) {
            lo = l;
            out_lo = false;
        }
        if let Some(h) = high.filter(|&h| h <= hi) {
            hi = h;
            out_hi = false;
        }
        let law = CdfLaw { lo, hi, outside: 0.0, kind };
        // P(ω < lo) + P(ω > hi), each side by the moment bound at its distance from μ
        let left = if out_lo { law.moment_tail((mu - Interval::point(lo)).lo) } else { 0.0 };
        let right = if out_hi { law.moment_tail((Interval::point(hi) - mu).lo) } else { 0.0 };
        let outside = (left + right).next_up().min(1.0);
        finite(CdfLaw { outside, ..law })
    }

    /// τ(d) ≥ P(ω − μ ≥ d) and ≥ P(ω − μ ≤ −d), for a law known by its moments (1 for
    /// other laws, or d ≤ 0).
    fn moment_tail(&self, d: f64) -> f64 {
        let Kind::Moments { var, central, .. } = &self.kind else { return 1.0 };
        if d.is_nan() || d <= 0.0 {
            return 1.0;
        }
        let di = Interval::point(d);
        // Cantelli: σ²/(σ² + d²), increasing in σ²
        let v = Interval::point(var.hi);
        let mut best = incomplete::div_pos(v, v + di * di).hi;
        // Markov on (ω − μ)^j: c_j/d^j
        for (j, c) in central {
            let dj = (0..*j).fold(Interval::point(1.0), |acc, _| acc * di);
            if dj.lo > 0.0 {
                best = best.min(incomplete::div_pos(Interval::point(c.hi), dj).hi);
            }
        }
        best.clamp(0.0, 1.0)
    }

    /// Where the partition halves a side [a, b] of a box: the middle, or for a law known by
    /// its moments the point of its grid μ ± ρₖ inside (a, b) in the middle of those inside —
    /// along a chain of boxes in a tail the bounds τ(ρₖ) = 2⁻ᵏ then add up to at most twice
    /// the first (a dyadic split would add nearly equal tails, one per halving). `None`
    /// when no point lies strictly inside (the side is not split).
    pub fn split(&self, a: f64, b: f64) -> Option<f64> {
        if let Kind::Moments { mean, grid, .. } = &self.kind {
            let m = mean.mid();
            let inside: Vec<f64> = grid
                .iter()
                .rev()
                .map(|r| m - r)
                .chain(std::iter::once(m))
                .chain(grid.iter().map(|r| m + r))
                .filter(|&x| x > a && x < b)
                .collect();
            return inside.get(inside.len() / 2).copied();
        }
        let mid = 0.5 * a + 0.5 * b;
        (mid > a && mid < b).then_some(mid)
    }

    /// An enclosure of the distribution function F(x) = P(ω ≤ x), within [0, 1].
    pub fn cdf(&self, x: f64) -> Interval {
        let unit = Interval::new(0.0, 1.0);
        if x.is_nan() {
            return unit;
        }
        let v = match &self.kind {
            Kind::Point { at } => {
                if x < at.lo {
                    Interval::point(0.0)
                } else if x > at.hi {
                    Interval::point(1.0)
                } else {
                    unit
                }
            }
            Kind::Uniform { a, b } => {
                if x <= a.lo {
                    Interval::point(0.0)
                } else if x >= b.hi {
                    Interval::point(1.0)
                } else {
                    // (x − a)/(b − a), each end taken on the wide side
                    let num = Interval::point(x) - *a;
                    let den = *b - *a;
                    if den.lo <= 0.0 {
                        unit
                    } else {
                        Interval::new((num.lo / den.hi).next_down(), (num.hi / den.lo).next_up())
                    }
                }
            }
            Kind::Normal { mu, inv_sigma } => {
                let z = (Interval::point(x) - *mu) * *inv_sigma;
                Interval::new(phi(z.lo).lo, phi(z.hi).hi)
            }
            Kind::Beta { alpha, beta, low, inv_width } => {
                let u = (Interval::point(x) - *low) * *inv_width;
                Interval::new(beta_cdf(*alpha, *beta, u.lo).lo, beta_cdf(*alpha, *beta, u.hi).hi)
            }
            Kind::Discrete { atoms } => {
                // an atom surely at or below x counts in both ends, one that may be (x
                // inside its enclosure) in the upper end only: F(x⁻) ≥ the lower end
                let (mut lo, mut hi) = (Interval::point(0.0), Interval::point(0.0));
                for (v, w) in atoms {
                    if v.hi < x {
                        lo = lo + *w;
                    }
                    if v.lo <= x {
                        hi = hi + *w;
                    }
                }
                Interval::new(lo.lo, hi.hi)
            }
            Kind::Exponential { rate } => {
                if x <= 0.0 {
                    Interval::point(0.0)
                } else {
                    // 1 − e^(−λx), monotone in λx
                    let y = Interval::point(x) * *rate;
                    Interval::new(1.0 - exp_upper(-y.lo), 1.0 - exp_lower(-y.hi))
                }
            }
            Kind::Laplace { mu, inv_scale } => {
                let z = (Interval::point(x) - *mu) * *inv_scale;
                // F = ½e^z below μ, 1 − ½e^(−z) above: monotone, each end from its side
                let f_lo = |z: f64| if z < 0.0 { 0.5 * exp_lower(z) } else { 1.0 - 0.5 * exp_upper(-z) };
                let f_hi = |z: f64| if z < 0.0 { 0.5 * exp_upper(z) } else { 1.0 - 0.5 * exp_lower(-z) };
                Interval::new(f_lo(z.lo).next_down(), f_hi(z.hi).next_up())
            }
            Kind::Erlang { shape, inv_scale } => {
                if x <= 0.0 {
                    Interval::point(0.0)
                } else {
                    erlang_cdf(*shape, Interval::point(x) * *inv_scale)
                }
            }
            Kind::Gamma { shape, inv_scale, gamma } => {
                if x <= 0.0 {
                    Interval::point(0.0)
                } else {
                    // P(a, ·) is increasing: each end from its end of y
                    let y = Interval::point(x) * *inv_scale;
                    let (l, h) = (
                        incomplete::gamma_p(*shape, *gamma, Interval::point(y.lo)),
                        incomplete::gamma_p(*shape, *gamma, Interval::point(y.hi)),
                    );
                    Interval::new(l.lo, h.hi)
                }
            }
            Kind::Moments { mean, support, .. } => {
                if support.0.is_some_and(|l| x < l) {
                    Interval::point(0.0)
                } else if support.1.is_some_and(|h| x >= h) {
                    Interval::point(1.0)
                } else if (*mean - Interval::point(x)).lo > 0.0 {
                    // x < μ: F(x) ≤ P(ω − μ ≤ −(μ − x))
                    Interval::new(0.0, self.moment_tail((*mean - Interval::point(x)).lo))
                } else if (Interval::point(x) - *mean).lo > 0.0 {
                    // x > μ: 1 − F(x) = P(ω > x) ≤ P(ω − μ ≥ x − μ)
                    Interval::new((1.0 - self.moment_tail((Interval::point(x) - *mean).lo)).next_down(), 1.0)
                } else {
                    unit
                }
            }
            Kind::BetaReal { alpha, beta, b, low, inv_width } => {
                let u = (Interval::point(x) - *low) * *inv_width;
                Interval::new(
                    incomplete::beta_i(*alpha, *beta, *b, u.lo).lo,
                    incomplete::beta_i(*alpha, *beta, *b, u.hi).hi,
                )
            }
        };
        Interval::new(v.lo.max(0.0), v.hi.min(1.0))
    }

    /// An upper bound of P(a ≤ ω ≤ b), in [0, 1], from the enclosures of F at the ends
    /// (a point mass at a counts: F(a) is taken just below a by its lower end).
    pub fn mass_upper(&self, a: f64, b: f64) -> f64 {
        if a.is_nan() || b.is_nan() {
            return 1.0;
        }
        if a > b {
            return 0.0;
        }
        mass_between(self.cdf(a), self.cdf(b))
    }
}

/// An upper bound of F(b) − F(a⁻) from enclosures of F(a) and F(b): F(b).hi − F(a).lo,
/// rounded up, in [0, 1]. For a point mass at a itself, [`CdfLaw::cdf`] encloses both
/// F(a⁻) and F(a) (its interval there is [0, 1]).
pub fn mass_between(fa: Interval, fb: Interval) -> f64 {
    let v = fb.hi - fa.lo;
    if v.is_nan() {
        1.0
    } else if v <= 0.0 {
        0.0
    } else {
        v.next_up().min(1.0)
    }
}

fn finite(l: CdfLaw) -> Option<CdfLaw> {
    (l.lo.is_finite() && l.hi.is_finite() && l.lo <= l.hi).then_some(l)
}

/// An upper bound of 1 − Φ(z) for z > 0: φ(z)/z (Mills' ratio), widened by
/// [`TAIL_REL_MARGIN`]; 1 for z ≤ 0.
pub fn mills_upper(z: f64) -> f64 {
    if z.is_nan() || z <= 0.0 {
        return 1.0;
    }
    let v = (-0.5 * z * z).exp() / (z * (2.0 * std::f64::consts::PI).sqrt());
    // beyond z ≈ 37.5 the quotient is subnormal (its relative error no longer covered by
    // the margin) and then 0: the true tail is positive, so never below MILLS_FLOOR
    (v * (1.0 + TAIL_REL_MARGIN)).clamp(MILLS_FLOOR, 1.0)
}

/// An enclosure of Φ(z), the standard normal distribution function, at the float `z`.
pub fn phi(z: f64) -> Interval {
    if z.is_nan() {
        return Interval::new(0.0, 1.0);
    }
    if z > SERIES_LIMIT {
        return Interval::new((1.0 - mills_upper(z)).next_down().max(0.0), 1.0);
    }
    if z < -SERIES_LIMIT {
        return Interval::new(0.0, mills_upper(-z));
    }
    // x = z/√2, enclosed (1/√2 correctly rounded, widened by an ulp)
    let r2 = Interval::new(std::f64::consts::FRAC_1_SQRT_2.next_down(), std::f64::consts::FRAC_1_SQRT_2.next_up());
    let x = Interval::point(z) * r2;
    let e = erf_series(x);
    let half = Interval::point(0.5);
    let v = half + half * e;
    Interval::new(v.lo.max(0.0), v.hi.min(1.0))
}

/// erf(x) for |x| ≤ 3 enclosed: (2/√π)·Σₙ (−1)ⁿ x^(2n+1)/(n!(2n+1)), summed until the terms
/// decrease and fall below 2⁻⁶⁰; the alternating remainder is at most the next term.
fn erf_series(x: Interval) -> Interval {
    let x2 = x * x;
    let mut power = x; // x^(2n+1)/n!
    let mut sum = Interval::point(0.0);
    let mag = |i: Interval| i.lo.abs().max(i.hi.abs());
    let mut closed = false;
    for n in 0..ERF_MAX_TERMS {
        if n > 0 {
            power = power * x2 * recip(n as f64);
        }
        let term = power * recip((2 * n + 1) as f64);
        // once n ≥ x², |term| decreases in n: the rest is within ± the next term
        if f64::from(n) >= x2.hi && mag(term) < ERF_NEGLIGIBLE_TERM {
            let r = mag(term);
            sum = sum + Interval::new(-r, r);
            closed = true;
            break;
        }
        sum = if n % 2 == 0 { sum + term } else { sum - term };
    }
    if !closed {
        return Interval::new(-1.0, 1.0);
    }
    let two_over_sqrt_pi =
        Interval::new(std::f64::consts::FRAC_2_SQRT_PI.next_down(), std::f64::consts::FRAC_2_SQRT_PI.next_up());
    let v = two_over_sqrt_pi * sum;
    Interval::new(v.lo.max(-1.0), v.hi.min(1.0))
}

/// The series stops at a term below 2⁻⁶⁰ (its remainder, added as ± that term, is then
/// far below the sum's rounding width of about 10⁻¹⁶).
const ERF_NEGLIGIBLE_TERM: f64 = 8.673617379884035e-19;

/// Most terms of the erf series: for |x| ≤ 2.9 the terms fall below 2⁻¹⁰⁶ by n ≈ 70.
const ERF_MAX_TERMS: u32 = 200;

/// The exponential and Laplace ranges cover EXP_SPAN_RATES scales (the mass outside is
/// e^(−45) < 2.9·10⁻²⁰ per side).
pub const EXP_SPAN_RATES: f64 = 45.0;

/// An upper bound of e^y ([`incomplete::exp`]: the platform's `exp` widened by
/// [`TAIL_REL_MARGIN`], never below the least positive float; +∞ for NaN).
fn exp_upper(y: f64) -> f64 {
    incomplete::exp(Interval::point(y)).hi
}

/// A lower bound of e^y (≥ 0; 0 for NaN).
fn exp_lower(y: f64) -> f64 {
    incomplete::exp(Interval::point(y)).lo
}

/// The Erlang distribution function 1 − e^(−y)·Σ_{j<k} yʲ/j! at y ≥ 0 (in scale units),
/// enclosed: the sum in intervals, e^(−y) by [`incomplete::exp`].
fn erlang_cdf(k: u32, y: Interval) -> Interval {
    let y = Interval::new(y.lo.max(0.0), y.hi.max(0.0));
    let mut term = Interval::point(1.0);
    let mut sum = Interval::point(1.0);
    for j in 1..k {
        term = term * y * recip(f64::from(j));
        sum = sum + term;
    }
    let e = incomplete::exp(-y);
    let v = Interval::point(1.0) - e * sum;
    Interval::new(v.lo.max(0.0), v.hi.min(1.0))
}

/// An upper bound of the Erlang tail e^(−y)·Σ_{j<k} yʲ/j! at the float y ≥ 0 (formed
/// directly: 1 − F would cancel to an ulp of 1).
fn erlang_tail_upper(k: u32, y: f64) -> f64 {
    let yi = Interval::point(y.max(0.0));
    let (mut term, mut sum) = (Interval::point(1.0), Interval::point(1.0));
    for j in 1..k {
        term = term * yi * recip(f64::from(j));
        sum = sum + term;
    }
    (Interval::point(exp_upper(-y)) * sum).hi.min(1.0)
}

/// 1/k enclosed, for a positive integer k (below 2⁵³).
fn recip(k: f64) -> Interval {
    let q = 1.0 / k;
    Interval::new(q.next_down(), q.next_up())
}

/// The regularised incomplete beta function I_u(α, β) for integer shapes, enclosed: the
/// binomial tail Σ_{j=α}^{n} C(n, j)·uʲ(1 − u)^(n−j), n = α + β − 1 (u clamped to [0, 1]).
fn beta_cdf(alpha: u32, beta: u32, u: f64) -> Interval {
    if u.is_nan() {
        return Interval::new(0.0, 1.0);
    }
    if u <= 0.0 {
        return Interval::point(0.0);
    }
    if u >= 1.0 {
        return Interval::point(1.0);
    }
    let n = alpha + beta - 1;
    let (ui, vi) = (Interval::point(u), Interval::point(1.0) - Interval::point(u));
    let mut sum = Interval::point(0.0);
    for j in alpha..=n {
        let c = Interval::enclose_rational(&super::binomial(n, j));
        sum = sum + c * pow(ui, j) * pow(vi, n - j);
    }
    Interval::new(sum.lo.max(0.0), sum.hi.min(1.0))
}

fn pow(x: Interval, k: u32) -> Interval {
    (0..k).fold(Interval::point(1.0), |acc, _| acc * x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use statrs::distribution::{Beta, ContinuousCDF, Normal};

    fn q(s: &str) -> BigRational {
        crate::poly::parse_decimal(s).unwrap()
    }

    /// Φ's enclosure contains statrs' value (an independent implementation, accurate to
    /// about 10⁻¹⁵) and is narrow; the Mills tail is above the true tail.
    #[test]
    fn phi_encloses_an_independent_cdf() {
        let n = Normal::new(0.0, 1.0).unwrap();
        for i in -1200..=1200 {
            let z = i as f64 / 100.0;
            let e = phi(z);
            let v = n.cdf(z);
            // statrs errs by up to ~10⁻¹⁰ relatively (scipy agrees with the
            // enclosure): a coarse sweep; the table below, from scipy's ndtr, holds it to 2 ulps
            let slack = 1e-14 + 1e-9 * v;
            assert!(e.lo <= v + slack && v - slack <= e.hi, "Φ({z}) = {v} not in {e:?}");
            if z.abs() <= SERIES_LIMIT {
                assert!(e.width() < 1e-10, "Φ({z}): width {}", e.width());
            }
        }
        // scipy.special.ndtr (Cephes), correctly rounded or within an ulp
        let table: [(f64, f64); 17] = [
            (-4.1, 2.0657506912546717e-05),
            (-3.5, 0.00023262907903552502),
            (-2.87, 0.0020523589949397536),
            (-2.72, 0.003264095815891309),
            (-2.0, 0.022750131948179195),
            (-1.3, 0.09680048458561036),
            (-0.74, 0.22964999716479056),
            (-0.3, 0.3820885778110474),
            (0.0, 0.5),
            (0.2, 0.579259709439103),
            (0.74, 0.7703500028352095),
            (1.1, 0.8643339390536173),
            (1.7, 0.955434537241457),
            (2.4, 0.9918024640754038),
            (2.9, 0.998134186699616),
            (3.6, 0.9998408914098424),
            (4.1, 0.9999793424930875),
        ];
        for (z, v) in table {
            let e = phi(z);
            let ulp2 = 2.0 * (v.next_up() - v);
            assert!(e.lo <= v + ulp2 && v - ulp2 <= e.hi, "Φ({z}) = {v} (scipy) not in {e:?}");
        }
        for z in [4.2, 5.0, 8.0, 9.0, 20.0] {
            assert!(mills_upper(z) >= n.sf(z), "{z}");
        }
    }

    /// Masses: uniform exactly, normal and integer beta against statrs; a box's mass is at
    /// least the true one.
    #[test]
    fn masses_are_upper_bounds() {
        let u = CdfLaw::of(&Distribution::Uniform { low: q("0.3"), high: q("0.4") }).unwrap();
        assert!((u.mass_upper(0.35, 1.0) - 0.5).abs() < 1e-12 && u.mass_upper(0.35, 1.0) >= 0.5);
        assert_eq!(u.mass_upper(0.5, 0.6), 0.0);
        let nl = CdfLaw::of(&Distribution::Normal { mean: q("1"), std: q("0.2") }).unwrap();
        let n = Normal::new(1.0, 0.2).unwrap();
        for (a, b) in [(0.8, 1.25), (-1.0, 0.5), (1.9, 3.0), (nl.lo, nl.hi)] {
            let m = nl.mass_upper(a, b);
            let t = n.cdf(b) - n.cdf(a);
            // within 6 % beyond SERIES_LIMIT σ (the Mills ratio), else a few 10⁻¹¹
            assert!(m >= t - 1e-14 && m <= 1.06 * t + 5e-11, "[{a}, {b}]: {m} vs {t}");
        }
        assert!(nl.outside < 1e-18 && (nl.lo - (1.0 - 1.8)).abs() < 1e-12);
        let bl = CdfLaw::of(&Distribution::Beta { alpha: q("3"), beta: q("3"), low: q("0"), high: q("1") }).unwrap();
        let b = Beta::new(3.0, 3.0).unwrap();
        for (a, c) in [(0.1, 0.4), (0.0, 1.0), (0.45, 0.46)] {
            let m = bl.mass_upper(a, c);
            let t = b.cdf(c) - b.cdf(a);
            assert!(m >= t - 1e-15 && m <= t + 1e-12, "[{a}, {c}]: {m} vs {t}");
        }
        assert!(CdfLaw::of(&Distribution::Beta { alpha: q("9"), beta: q("0.5"), low: q("0"), high: q("1") }).is_some());
        assert!(matches!(
            CdfLaw::of(&Distribution::Beta { alpha: q("90.5"), beta: q("0.5"), low: q("0"), high: q("1") }),
            Some(CdfLaw { kind: Kind::Moments { .. }, .. })
        ));
        // exponential, Laplace, Erlang against statrs (accurate to ~10⁻¹⁰ here)
        use statrs::distribution::{Exp, Gamma, Laplace};
        let check = |law: &CdfLaw, f: &dyn Fn(f64) -> f64, pts: &[(f64, f64)]| {
            for &(a, c) in pts {
                let m = law.mass_upper(a, c);
                let t = f(c) - f(a);
                assert!(m >= t - 1e-12 && m <= t + 1e-9, "[{a}, {c}]: {m} vs {t}");
            }
        };
        let e = CdfLaw::of(&Distribution::Exponential { rate: q("2") }).unwrap();
        let ed = Exp::new(2.0).unwrap();
        check(&e, &|x| ed.cdf(x), &[(0.0, 0.5), (0.3, 1.7), (2.0, 5.0)]);
        assert!(e.outside < 3e-20 && (e.hi - 22.5).abs() < 1e-9);
        let l = CdfLaw::of(&Distribution::Laplace { mean: q("1"), scale: q("0.5") }).unwrap();
        let ld = Laplace::new(1.0, 0.5).unwrap();
        check(&l, &|x| ld.cdf(x), &[(-1.0, 0.5), (0.8, 1.3), (1.2, 4.0)]);
        let g = CdfLaw::of(&Distribution::Gamma { shape: q("3"), scale: q("0.5") }).unwrap();
        let gd = Gamma::new(3.0, 2.0).unwrap(); // statrs: shape and rate
        check(&g, &|x| gd.cdf(x), &[(0.0, 0.5), (0.7, 2.0), (3.0, 9.0)]);
        assert!(g.outside < 1e-19, "{}", g.outside);
        assert!(matches!(
            CdfLaw::of(&Distribution::Gamma { shape: q("64.5"), scale: q("1") }),
            Some(CdfLaw { kind: Kind::Moments { .. }, .. })
        ));
        // other shapes by the series (incomplete.rs holds them to mpmath's values)
        let g = CdfLaw::of(&Distribution::Gamma { shape: q("2.5"), scale: q("0.5") }).unwrap();
        let gd = Gamma::new(2.5, 2.0).unwrap();
        check(&g, &|x| gd.cdf(x), &[(0.0, 0.5), (0.7, 2.0), (3.0, 9.0)]);
        assert!(g.outside < 1e-19, "{}", g.outside);
        let bl =
            CdfLaw::of(&Distribution::Beta { alpha: q("3.39"), beta: q("4.93"), low: q("-1"), high: q("1") }).unwrap();
        let bd = Beta::new(3.39, 4.93).unwrap();
        check(&bl, &|x| bd.cdf((x + 1.0) / 2.0), &[(-1.0, -0.5), (-0.2, 0.3), (0.5, 1.0)]);
        // discrete: an atom at a box's end counts
        let d = CdfLaw::of(&Distribution::Discrete {
            values: vec![q("0.5"), q("1"), q("2")],
            weights: vec![q("0.25"), q("0.5"), q("0.25")],
        })
        .unwrap();
        assert!(d.mass_upper(1.0, 1.0) >= 0.5 && d.mass_upper(1.0, 1.0) < 0.5 + 1e-12);
        assert!(d.mass_upper(0.5, 2.0) >= 1.0);
        assert!(d.mass_upper(1.1, 1.9) < 1e-15); // between atoms: the rounding of the two ends only
        assert!(d.mass_upper(0.0, 0.9) >= 0.25 && d.mass_upper(0.0, 0.9) < 0.25 + 1e-12);
    }

    /// Laws known by moments only enclose the true distribution function (statrs, an
    /// independent implementation): a moment list of N(0, 1) (orders 2, 4, 6, 8), a gamma
    /// of shape 80 and a beta of shapes (90.5, 3) from their moments; the mass outside the
    /// range is above the true tail and at most MOMENT_LAW_TAIL; a box's mass is at least its
    /// probability.
    #[test]
    fn moment_laws_enclose_the_distribution_function() {
        use statrs::distribution::Gamma;
        let normal_raw: Vec<BigRational> = ["0", "1", "0", "3", "0", "15", "0", "105"].iter().map(|s| q(s)).collect();
        let nl = CdfLaw::of(&Distribution::Moments { raw: normal_raw }).unwrap();
        let n = Normal::new(0.0, 1.0).unwrap();
        assert!(nl.outside <= 2.0 * MOMENT_LAW_TAIL * 1.0001 && nl.outside >= 2.0 * n.cdf(nl.lo), "{nl:?}");
        let gl = CdfLaw::of(&Distribution::Gamma { shape: q("80"), scale: q("0.5") }).unwrap();
        let g = Gamma::new(80.0, 2.0).unwrap();
        assert!(gl.lo >= 0.0 && gl.outside >= g.cdf(gl.lo) + g.sf(gl.hi), "{gl:?}");
        let bl = CdfLaw::of(&Distribution::Beta { alpha: q("90.5"), beta: q("3"), low: q("2"), high: q("4") }).unwrap();
        let b = Beta::new(90.5, 3.0).unwrap();
        let bcdf = |x: f64| b.cdf(((x - 2.0) / 2.0).clamp(0.0, 1.0));
        assert!(bl.hi <= 4.0 && bl.lo >= 2.0 && bl.outside >= bcdf(bl.lo), "{bl:?}");
        for (law, f) in [(&nl, &(|x: f64| n.cdf(x)) as &dyn Fn(f64) -> f64), (&gl, &|x: f64| g.cdf(x)), (&bl, &bcdf)] {
            let (lo, hi) = (law.lo.max(-50.0), law.hi.min(200.0));
            for i in 0..=400 {
                let x = lo + (hi - lo) * f64::from(i) / 400.0;
                let e = law.cdf(x);
                let v = f(x);
                assert!(e.lo <= v + 1e-12 && v - 1e-12 <= e.hi, "F({x}) = {v} not in {e:?} ({law:?})");
                let y = x + (hi - lo) / 97.0;
                assert!(law.mass_upper(x, y) >= f(y) - v - 1e-12, "[{x}, {y}]");
            }
        }
        // no law without a variance
        assert!(CdfLaw::of(&Distribution::Moments { raw: vec![q("1"), q("1")] }).is_none());
        // orders that no law has are not used (c₄ < σ⁴ would claim P(ω ≥ 1) ≤ 0.01 where a
        // law of mean 0 and variance 1 may put 1/2)
        let bad = CdfLaw::of(&Distribution::Moments { raw: vec![q("0"), q("1"), q("0"), q("0.01")] }).unwrap();
        assert!(bad.mass_upper(1.0, 10.0) >= 0.5, "{bad:?}");
    }
}
