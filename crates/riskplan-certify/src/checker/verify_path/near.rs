//! An obstacle's box tests (`Near`): polynomials bounded over a piece's hull that clear the obstacle without a proof on the piece (docs/design.md §5.12).

use super::*;

/// One obstacle's contour polynomials around a point of its own (`y = x − c`), with
/// interval coefficients: evaluated over a piece's bounding box they bound E\[P\] and
/// E\[P²\] there.
#[derive(Clone, Debug)]
pub struct Near {
    pub(super) center: Vec<f64>,
    pub(super) mean: riskplan_math::poly::Poly<Interval>,
    pub(super) second: riskplan_math::poly::Poly<Interval>,
}

/// What the box tests of one obstacle at one Δ evaluate (`Near::cantelli`).
#[derive(Clone, Debug)]
pub struct NearBound {
    /// g₁ = E\[P\]² − (1−Δ)·E\[P²\], expanded.
    g1: riskplan_math::poly::Poly<Interval>,
    /// Var(P) = E\[P²\] − E\[P\]², expanded.
    var: riskplan_math::poly::Poly<Interval>,
    /// Δ and 1 − Δ, enclosed.
    delta: Interval,
    one_minus_delta: Interval,
}

impl Near {
    /// The point the box tests are written about ([`crate::checker::cover_index::obstacle_center`]).
    pub(crate) fn center(&self) -> &[f64] {
        &self.center
    }

    /// The polynomials of the box tests at Δ (1 − Δ enclosed in `one_minus_delta`): the
    /// Cantelli polynomial g₁ = E\[P\]² − (1−Δ)·E\[P²\] around the centre, formed before any
    /// evaluation so that its leading terms cancel symbolically (evaluating E\[P\]² and
    /// E\[P²\] separately over a box cannot prove g₁ > 0 a few box-widths away), and the
    /// variance E\[P²\] − E\[P\]², formed the same way, for the equivalent form
    /// g₁ = Δ·E\[P\]² − (1−Δ)·Var(P).
    pub(super) fn cantelli(&self, one_minus_delta: Interval) -> NearBound {
        let square = self.mean.mul(&self.mean);
        NearBound {
            g1: square.sub(&self.second.scale(&one_minus_delta)),
            var: self.second.sub(&square),
            delta: Interval::point(1.0) - one_minus_delta,
            one_minus_delta,
        }
    }

    /// Whether both constraints of eq. (15) are proven over the box `bbox × t` by naive
    /// interval evaluation: E\[P\] < 0, and g₁ > 0 either expanded or as
    /// Δ·E\[P\]² − (1−Δ)·Var(P) with E\[P\]² the square of E\[P\]'s enclosure (tight: it
    /// lies below 0) — the expanded g₁ loses its digits to cancellation over a box a few
    /// radii from the obstacle, where E\[P\]² is far above the variance (identical
    /// polynomials, both enclosures sound).
    pub(super) fn clears(&self, bbox: &[Interval], t: Interval, b: &NearBound) -> bool {
        let mut vals: Vec<Interval> = bbox.iter().zip(&self.center).map(|(&b, &c)| b - Interval::point(c)).collect();
        vals.push(t - Interval::point(self.center[bbox.len()]));
        let mut powers = Powers::new(&vals);
        let m = powers.eval(&self.mean);
        // NaN-safe: a NaN bound is not below 0
        if m.hi.partial_cmp(&0.0) != Some(std::cmp::Ordering::Less) {
            return false;
        }
        if powers.eval(&b.g1).lo > 0.0 {
            return true;
        }
        (b.delta * (m * m) - b.one_minus_delta * powers.eval(&b.var)).lo > 0.0
    }
}

/// The powers of a box's sides for the box tests' evaluations, each formed once and
/// shared by the three polynomials of a test: `w^e` as [`power_range`] forms it (repeated
/// outward-rounded products; an even power of a side that contains 0 from 0), so a
/// polynomial's enclosure is Σ c·Π w_v^e over its terms, sound term by term. (The general
/// `Poly::eval` formed every power of every term anew: most of the final check's time on
/// crowded scenes.)
///
/// [`power_range`]: riskplan_math::contour::bounds::power_range
struct Powers<'a> {
    vals: &'a [Interval],
    /// `chain[v][k]` = w_v^(k+1) by repeated products, for the first `len[v]` exponents.
    chain: [[Interval; Powers::KEPT]; Powers::VARS],
    len: [usize; Powers::VARS],
}

impl<'a> Powers<'a> {
    /// Sides whose powers are kept (space up to 3 dimensions and time).
    const VARS: usize = 4;
    /// Exponents kept per side (higher ones are formed directly).
    const KEPT: usize = 12;

    fn new(vals: &'a [Interval]) -> Self {
        Powers { vals, chain: [[Interval::point(0.0); Self::KEPT]; Self::VARS], len: [0; Self::VARS] }
    }

    /// The enclosure of `w_v^e`.
    fn power(&mut self, v: usize, e: u32) -> Interval {
        let Some(&w) = self.vals.get(v) else { return Interval::new(f64::NEG_INFINITY, f64::INFINITY) };
        let k = e as usize;
        if e == 0 || v >= Self::VARS || k > Self::KEPT {
            return riskplan_math::contour::bounds::power_range(w, e);
        }
        while self.len[v] < k {
            let next = if self.len[v] == 0 { w } else { self.chain[v][self.len[v] - 1] * w };
            self.chain[v][self.len[v]] = next;
            self.len[v] += 1;
        }
        let acc = self.chain[v][k - 1];
        if e % 2 == 0 {
            if w.lo <= 0.0 && w.hi >= 0.0 {
                return Interval::new(0.0, acc.hi.max(0.0));
            }
            return Interval::new(acc.lo.max(0.0), acc.hi);
        }
        acc
    }

    /// The enclosure of `p` over the box.
    fn eval(&mut self, p: &riskplan_math::poly::Poly<Interval>) -> Interval {
        let mut acc = Interval::point(0.0);
        for (m, c) in p.terms() {
            let mut t = *c;
            for &(v, e) in m.pairs() {
                t = t * self.power(v as usize, e);
            }
            acc = acc + t;
        }
        acc
    }
}
