//! Rigorous enclosures of the regularised incomplete gamma and beta functions for real
//! (non-integer) shapes — the distribution functions of gamma and beta parameters, for the
//! whole-path bound's partition (docs/design.md §5.14, [`super::cdf`]).
//!
//! Both come from power series whose terms are all positive (no cancellation), summed in
//! outward-rounded interval arithmetic until the terms fall geometrically; the rest of the
//! series is then bounded by a geometric tail:
//!
//! - **gamma**: γ(a, y) = y^a·e^(−y)·Σₖ yᵏ/(a(a+1)…(a+k)); the ratio of consecutive terms
//!   y/(a+k+1) decreases in k, so once it is ρ < 1 the rest is at most the last term times
//!   ρ/(1 − ρ). Γ(a) = γ(a, Y) + Γ(a, Y) with the upper tail Γ(a, Y) ≤ Y^(a−1)·e^(−Y) for
//!   a ≤ 1 and ≤ Y^(a−1)·e^(−Y)/(1 − (a−1)/Y) for a > 1, Y > a − 1 (x^(a−1) ≤
//!   Y^(a−1)·e^((a−1)(x−Y)/Y) on [Y, ∞)). P(a, y) = γ(a, y)/Γ(a).
//! - **beta**: B_u(α, β) = u^α(1 − u)^β/α·Σₖ (α+β)ₖ/(α+1)ₖ·uᵏ (Pochhammer symbols), summed
//!   for u ≤ ½ (the ratio of consecutive terms u(α+β+k)/(α+1+k) tends to u; it decreases
//!   in k when β ≥ 1 and stays below u when β < 1, so ρ = max(ratio at the last term, u)
//!   bounds every later ratio); above ½ by the symmetry I_u(α, β) = 1 − I_(1−u)(β, α), and
//!   B(α, β) = B_½(α, β) + B_½(β, α) (the same symmetry at u = ½).
//!
//! The powers y^a, u^α(1 − u)^β are exp(a·ln y) etc., with the platform's `ln` and `exp`
//! (within an ulp or two) widened by [`ELEMENTARY_REL_MARGIN`].

use crate::poly::Interval;

/// Relative widening of the platform's `ln` and `exp` (both within a few ulps, about
/// 10⁻¹⁶; the margin covers them a thousand times over): the distribution functions' own.
pub const ELEMENTARY_REL_MARGIN: f64 = 1e-12;

/// Smallest shape handled (below it the distribution is nearly a point mass at 0 and the
/// first term 1/a of the series dwarfs the rest): such parameters keep the moment bounds.
pub const MIN_SHAPE: f64 = 1e-3;

/// Largest shape handled: Γ(64) ≈ 2·10⁸⁷ and 2^(α+β) stay far inside the float range.
pub const MAX_SHAPE: f64 = 64.0;

/// Most terms of a series (gamma up to y = a + 10√a + 50 ≤ 194 needs a few hundred; the
/// beta series at u ≤ ½ about 40 + 2(α + β)): beyond it the enclosure is [0, 1].
const MAX_TERMS: u32 = 4000;

/// A series stops once its terms fall geometrically and the last is below this fraction
/// of the sum (the geometric tail then adds about 2⁻⁶⁰ relatively).
const NEGLIGIBLE_TERM_REL: f64 = 8.673617379884035e-19;

/// ln of a positive interval, enclosed (monotone: each end from its float).
pub fn ln(v: Interval) -> Interval {
    if (v.lo.is_nan() || v.lo <= 0.0) || v.hi.is_nan() {
        return Interval::ENTIRE;
    }
    let widen_down = |l: f64| (l - l.abs() * ELEMENTARY_REL_MARGIN).next_down();
    let widen_up = |l: f64| (l + l.abs() * ELEMENTARY_REL_MARGIN).next_up();
    Interval::new(widen_down(v.lo.ln()), widen_up(v.hi.ln()))
}

/// exp of an interval, enclosed (never below 0; +∞ on overflow).
pub fn exp(v: Interval) -> Interval {
    if v.lo.is_nan() || v.hi.is_nan() {
        return Interval::new(0.0, f64::INFINITY);
    }
    let lo = (v.lo.exp() * (1.0 - ELEMENTARY_REL_MARGIN)).next_down().max(0.0);
    let hi = v.hi.exp();
    let hi = if hi.is_finite() { (hi * (1.0 + ELEMENTARY_REL_MARGIN)).next_up().max(f64::MIN_POSITIVE) } else { hi };
    Interval::new(lo, hi)
}

/// A product of non-negative factors, its lower end kept at 0 when the outward rounding of
/// an underflow took it below (the product itself is ≥ 0).
fn nonneg(v: Interval) -> Interval {
    Interval::new(v.lo.max(0.0), v.hi)
}

/// a/b for a ≥ 0 and b > 0 (b.lo > 0), outward-rounded; [0, ∞] otherwise.
pub fn div_pos(a: Interval, b: Interval) -> Interval {
    if (a.lo.is_nan() || a.lo < 0.0) || (b.lo.is_nan() || b.lo <= 0.0) || a.hi.is_nan() || b.hi.is_nan() {
        return Interval::new(0.0, f64::INFINITY);
    }
    let lo = (a.lo / b.hi).next_down().max(0.0);
    let hi = (a.hi / b.lo).next_up();
    Interval::new(lo, if hi.is_nan() { f64::INFINITY } else { hi })
}

/// Σ of positive terms t₀, t₁ = t₀·r₀, t₂ = t₁·r₁, … where `ratio(k)` encloses rₖ and
/// `tail_ratio(k)` is a float ≥ every rⱼ, j ≥ k (or ≥ 1 when none is known yet).
/// `None` when the series did not close within [`MAX_TERMS`].
fn positive_series(t0: Interval, ratio: &dyn Fn(u32) -> Interval, tail_ratio: &dyn Fn(u32) -> f64) -> Option<Interval> {
    let mut term = t0;
    let mut sum = t0;
    for k in 0..MAX_TERMS {
        let rho = tail_ratio(k);
        if rho < 1.0 && term.hi <= sum.lo * NEGLIGIBLE_TERM_REL {
            // the rest: Σ_{j>k} tⱼ ≤ tₖ·(ρ + ρ² + …) = tₖ·ρ/(1 − ρ)
            let rest = div_pos(nonneg(term * Interval::point(rho)), Interval::point(1.0) - Interval::point(rho));
            return Some(sum + Interval::new(0.0, rest.hi));
        }
        term = nonneg(term * ratio(k));
        sum = sum + term;
        if !sum.hi.is_finite() {
            return None;
        }
    }
    None
}

/// γ(a, y)·e^y·y^(−a) = Σₖ yᵏ/(a(a+1)…(a+k)) for y ≥ 0.
fn gamma_series(a: Interval, y: Interval) -> Option<Interval> {
    let one = Interval::point(1.0);
    let t0 = div_pos(one, a);
    let ratio = |k: u32| div_pos(y, a + Interval::point(f64::from(k) + 1.0));
    // y/(a + j + 1) ≤ y.hi/(a.lo + k + 1) for j ≥ k
    let tail = |k: u32| {
        let d = (a.lo + f64::from(k) + 1.0).next_down();
        (y.hi / d).next_up()
    };
    positive_series(t0, &ratio, &tail)
}

/// The lower incomplete gamma function γ(a, y) for y ≥ 0, enclosed.
fn lower_gamma(a: Interval, y: Interval) -> Option<Interval> {
    if y.hi <= 0.0 {
        return Some(Interval::point(0.0));
    }
    let y = Interval::new(y.lo.max(0.0), y.hi);
    let s = gamma_series(a, y)?;
    if y.lo == 0.0 {
        // y^a·e^(−y) ≤ y^a ≤ y.hi^a on [0, y.hi]
        let top = exp(a * ln(Interval::point(y.hi))).hi;
        return Some(Interval::new(0.0, (top * s.hi).next_up()));
    }
    Some(nonneg(exp(a * ln(y) - y) * s))
}

/// Γ(a) for a in [`MIN_SHAPE`, `MAX_SHAPE`], enclosed, and the Y it was split at.
pub fn gamma_fn(a: Interval) -> Option<Interval> {
    if !shape_in_range(a) {
        return None;
    }
    let y = gamma_split(a.hi);
    let low = lower_gamma(a, Interval::point(y))?;
    let tail = upper_gamma_tail(a, y)?;
    let v = Interval::new(low.lo, (low.hi + tail).next_up());
    (v.lo > 0.0 && v.hi.is_finite()).then_some(v)
}

/// Whether a shape's enclosure lies in [[`MIN_SHAPE`], [`MAX_SHAPE`]] (an ulp of slack
/// below: the enclosure of the decimal 0.001 starts at the float under it).
pub fn shape_in_range(a: Interval) -> bool {
    a.lo >= MIN_SHAPE.next_down() && a.hi <= MAX_SHAPE
}

/// The point Y = a + 10√a + 50 where Γ(a) is split: the upper tail beyond it is below
/// 10⁻²⁰·Γ(a) for every a ≤ [`MAX_SHAPE`] — also where a gamma parameter's range ends.
pub fn gamma_split(a: f64) -> f64 {
    a + 10.0 * a.sqrt() + 50.0
}

/// An upper bound of the upper incomplete gamma Γ(a, Y) = ∫_Y^∞ x^(a−1)e^(−x) dx for
/// Y > a − 1 (module docs); `None` otherwise.
pub fn upper_gamma_tail(a: Interval, y: f64) -> Option<f64> {
    let yi = Interval::point(y);
    let am1 = a - Interval::point(1.0);
    // Y^(a−1)·e^(−Y), at the end of a that makes it largest (Y ≥ 1: the upper end)
    let head = exp(am1 * ln(yi) - yi).hi;
    if am1.hi <= 0.0 {
        return Some(head);
    }
    let q = div_pos(Interval::new(am1.lo.max(0.0), am1.hi), yi);
    if q.hi >= 1.0 {
        return None;
    }
    Some(div_pos(Interval::point(head), Interval::point(1.0) - q).hi)
}

/// The regularised lower incomplete gamma P(a, y) = γ(a, y)/Γ(a) at y ≥ 0 (`gamma` an
/// enclosure of Γ(a)), within [0, 1]; [0, 1] when the series does not close.
pub fn gamma_p(a: Interval, gamma: Interval, y: Interval) -> Interval {
    let unit = Interval::new(0.0, 1.0);
    if y.lo.is_nan() || y.hi.is_nan() {
        return unit;
    }
    let Some(low) = lower_gamma(a, y) else { return unit };
    let v = div_pos(low, gamma);
    Interval::new(v.lo.clamp(0.0, 1.0), v.hi.clamp(0.0, 1.0))
}

/// The incomplete beta B_u(α, β) = ∫₀^u x^(α−1)(1 − x)^(β−1) dx for u in [0, ½]
/// (an interval within it), by the series of the module docs.
fn incomplete_beta_low(alpha: Interval, beta: Interval, u: Interval) -> Option<Interval> {
    if u.hi <= 0.0 {
        return Some(Interval::point(0.0));
    }
    if u.lo < 0.0 || u.hi > 0.5 {
        return None;
    }
    let one = Interval::point(1.0);
    let ab = alpha + beta;
    let ratio = |k: u32| {
        let kk = Interval::point(f64::from(k));
        div_pos(u * (ab + kk), alpha + one + kk)
    };
    // later ratios u(α+β+j)/(α+1+j), j ≥ k: at most their enclosure at k when β ≥ 1
    // (decreasing in j), and at most u when β ≤ 1 (each below u); for β straddling 1,
    // the larger of the two
    let tail = |k: u32| ratio(k).hi.max(u.hi);
    let s = positive_series(one, &ratio, &tail)?;
    // u^α (1 − u)^β / α
    let lead = if u.lo == 0.0 {
        // increasing in u on [0, ½] for the part u^α, (1 − u)^β ≤ 1
        Interval::new(0.0, exp(alpha * ln(Interval::point(u.hi))).hi)
    } else {
        exp(alpha * ln(u) + beta * ln(one - u))
    };
    Some(div_pos(nonneg(lead * s), alpha))
}

/// B(α, β) = B_½(α, β) + B_½(β, α), enclosed, for shapes in [`MIN_SHAPE`, `MAX_SHAPE`].
pub fn beta_fn(alpha: Interval, beta: Interval) -> Option<Interval> {
    if !shape_in_range(alpha) || !shape_in_range(beta) {
        return None;
    }
    let half = Interval::point(0.5);
    let v = incomplete_beta_low(alpha, beta, half)? + incomplete_beta_low(beta, alpha, half)?;
    (v.lo > 0.0 && v.hi.is_finite()).then_some(v)
}

/// The regularised incomplete beta I_u(α, β) at the float u (clamped to [0, 1]), `b` an
/// enclosure of B(α, β), within [0, 1].
pub fn beta_i(alpha: Interval, beta: Interval, b: Interval, u: f64) -> Interval {
    let unit = Interval::new(0.0, 1.0);
    if u.is_nan() {
        return unit;
    }
    if u <= 0.0 {
        return Interval::point(0.0);
    }
    if u >= 1.0 {
        return Interval::point(1.0);
    }
    let v = if u <= 0.5 {
        match incomplete_beta_low(alpha, beta, Interval::point(u)) {
            Some(x) => div_pos(x, b),
            None => return unit,
        }
    } else {
        // 1 − I_(1−u)(β, α); 1 − u is exact for u in [½, 1] (Sterbenz)
        match incomplete_beta_low(beta, alpha, Interval::point(1.0 - u)) {
            Some(x) => Interval::point(1.0) - div_pos(x, b),
            None => return unit,
        }
    };
    if v.lo.is_nan() || v.hi.is_nan() {
        return unit;
    }
    Interval::new(v.lo.clamp(0.0, 1.0), v.hi.clamp(0.0, 1.0))
}

#[cfg(test)]
// the reference values are mpmath's 17 significant digits as printed
#[allow(clippy::excessive_precision)]
mod tests {
    use super::*;

    fn pt(x: f64) -> Interval {
        Interval::point(x)
    }

    /// Reference values from mpmath at 40 digits (`gammainc(a, 0, y, regularized=True)`,
    /// `betainc(a, b, 0, u, regularized=True)`, `gamma(a)`, `beta(a, b)`), rounded to 17
    /// significant digits: an oracle sharing no code with the series.
    #[test]
    fn series_enclose_mpmath_values() {
        let gammas: [(f64, f64); 6] = [
            (0.5, 1.772453850905516),
            (1.53, 0.88756762784566387),
            (2.5, 1.329340388179137),
            (7.25, 1155.3810139199897),
            (0.01, 99.432585119150602),
            (63.5, 2.4929006008366564e86),
        ];
        for (a, g) in gammas {
            let e = gamma_fn(pt(a)).unwrap();
            assert!(e.lo <= g * (1.0 + 1e-15) && g * (1.0 - 1e-15) <= e.hi, "Γ({a}) = {g} not in {e:?}");
            assert!(e.width() <= 1e-9 * g, "Γ({a}): {e:?} too wide");
        }
        let ps: [(f64, f64, f64); 8] = [
            (0.5, 0.3, 0.56142197391900014),
            (1.53, 0.2, 0.05568616951616684),
            (1.53, 4.0, 0.95178486104131169),
            (2.5, 0.001, 9.5085345986079498e-9),
            (7.25, 7.0, 0.51220464639194533),
            (7.25, 30.0, 0.99999982719645694),
            (0.01, 1e-06, 0.87593375983235331),
            (63.5, 70.0, 0.79698871822966568),
        ];
        for (a, y, p) in ps {
            let e = gamma_p(pt(a), gamma_fn(pt(a)).unwrap(), pt(y));
            assert!(e.lo <= p * (1.0 + 1e-15) && p * (1.0 - 1e-15) <= e.hi, "P({a}, {y}) = {p} not in {e:?}");
            assert!(e.width() <= 1e-9, "P({a}, {y}): {e:?} too wide");
        }
        let bs: [(f64, f64, f64, f64); 7] = [
            (3.39, 4.93, 0.3, 0.27626733318617285),
            (3.39, 4.93, 0.8, 0.99284882042920752),
            (0.5, 0.5, 0.1, 0.20483276469913346),
            (0.5, 2.5, 0.95, 0.99980670495381837),
            (2.5, 0.7, 0.5, 0.11398345944666879),
            (40.5, 20.25, 0.66, 0.44444443456669472),
            (1.0, 1.0, 0.37, 0.37),
        ];
        for (a, b, u, v) in bs {
            let bf = beta_fn(pt(a), pt(b)).unwrap();
            let e = beta_i(pt(a), pt(b), bf, u);
            assert!(e.lo <= v * (1.0 + 1e-15) && v * (1.0 - 1e-15) <= e.hi, "I_{u}({a}, {b}) = {v} not in {e:?}");
            assert!(e.width() <= 1e-9, "I_{u}({a}, {b}): {e:?} too wide");
        }
    }

    /// Out of range shapes have no enclosure; the tail bound is above the true tail.
    #[test]
    fn limits() {
        assert!(gamma_fn(pt(1e-4)).is_none() && gamma_fn(pt(65.0)).is_none());
        assert!(beta_fn(pt(0.5), pt(70.0)).is_none());
        // Γ(2, 10) = 11·e^(−10)
        let t = upper_gamma_tail(pt(2.0), 10.0).unwrap();
        assert!(t >= 11.0 * (-10f64).exp());
        assert!(gamma_p(pt(2.0), gamma_fn(pt(2.0)).unwrap(), pt(0.0)).hi < 1e-300);
        // underflowing products keep a usable enclosure (true values 3.0·10⁻³⁷⁶ and
        // 1 − 10⁻³⁸⁰ or so)
        assert!(gamma_p(pt(2.5), gamma_fn(pt(2.5)).unwrap(), pt(1e-150)).hi < 1e-300);
        let b = beta_fn(pt(2.5), pt(63.5)).unwrap();
        assert!(beta_i(pt(2.5), pt(63.5), b, 0.999999).lo > 1.0 - 1e-12);
        assert!(gamma_fn(Interval::new(1e-3f64.next_down(), 1e-3)).is_some());
    }
}
