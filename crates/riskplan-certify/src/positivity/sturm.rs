//! Exact oracle for positivity on [0, 1]: Sturm sequences (docs/design.md §5.7).
//!
//! Slow but complete, this is the reference the fast certifiers of eq. (15)
//! (`SOS_Cond`) are tested against (§5.8) and the source of exact minima for reports.
//!
//! All arithmetic is exact. Polynomials are kept as primitive integer polynomials
//! (a positive rational multiple of the input, so signs are unchanged); the Sturm
//! sequence is built from the square-free part `s = p / gcd(p, p')`, whose distinct
//! roots are those of `p`, with pseudo-remainders whose sign is corrected so that each
//! term is a *positive* multiple of `−rem(s_{j−1}, s_j)`. Because `s` is square-free the
//! sequence ends in a non-zero constant and the sign-change count `V(x)` is valid at
//! every `x`: the number of distinct roots in `(a, b]` is `V(a) − V(b)`.

use crate::positivity::bernstein::f64_below;
use crate::positivity::verdict::{Undecided, Verdict, Witness};
use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use riskplan_math::poly::{rational_to_f64, UPoly};
use std::cmp::Ordering;

/// Relative accuracy of the margin [`decide`] reports, as a power of two: the margin
/// `μ̂` satisfies `(1 − 2^-10)·min p ≤ μ̂ ≤ min p`. Only the lower-bound direction
/// matters for soundness; this constant only controls how much tighter than that it is.
pub const MARGIN_REL_TOL_BITS: u32 = 10;

/// [`MARGIN_REL_TOL_BITS`] as a number, `2^-10`.
pub const MARGIN_REL_TOL: f64 = 1.0 / (1u64 << MARGIN_REL_TOL_BITS) as f64;

/// Bisection depth (in bits) at which root isolation gives up. Distinct roots of an
/// integer polynomial are separated by a positive amount, so isolation always ends;
/// this cap only bounds the time spent on absurd inputs (it is far beyond any root
/// separation of the degree ≤ 32, moderate-coefficient polynomials riskplan builds).
/// Hitting it yields `Undecided(DepthLimit)`, never a wrong answer.
pub const MAX_ISOLATION_BITS: u32 = 4096;

/// Refinement cap (bits) of [`min_on_unit`] around each critical point; reaching it
/// only leaves [`MinEnclosure::converged`] false (the bounds stay valid).
pub const MAX_MIN_REFINE_BITS: u32 = 512;

/// Most bisections between two Taylor bounds in [`min_on_unit`]; each halving shrinks
/// the bound's gap about fourfold near a critical point, so 32 covers a factor 2^64.
const MAX_BISECTIONS_PER_BOUND: u32 = 32;

/// Decides `p > 0` on [0, 1] exactly.
///
/// * `Unsafe` with a witness τ where `p(τ) ≤ 0` exactly (an end, a gap between roots
///   where `p < 0`, or a root that is a float);
/// * `Safe { margin }` with `(1 − MARGIN_REL_TOL)·min p ≤ margin ≤ min p`;
/// * `Undecided(DepthLimit)` only when `p ≥ 0` on [0, 1] with zeros none of which is
///   an `f64` (a proven touch, unsafe by policy, but no float τ has `p(τ) ≤ 0`), when
///   a negative gap between roots holds no float, or at [`MAX_ISOLATION_BITS`].
pub fn decide(p: &UPoly<BigRational>) -> Verdict {
    if p.is_zero() {
        return Verdict::Unsafe(Witness { tau: 0.0, value: 0.0 });
    }
    let (z, scale) = to_integer(p.coeffs());
    // z(0) = z_0 and z(1) = Σ z_i, with the signs of p(0), p(1) (scale > 0)
    let ends = [(0.0, z[0].clone()), (1.0, z.iter().sum::<BigInt>())];
    for (t, v) in ends {
        if !v.is_positive() {
            let value = rational_to_f64(&(BigRational::from_integer(v) * &scale));
            return Verdict::Unsafe(Witness { tau: t, value });
        }
    }
    if p.degree() == 0 {
        return Verdict::Safe { margin: f64_below(&p.coeff(0)) };
    }
    let sqf = square_free(&z);
    let seq = SturmSeq::new(&sqf);
    if seq.count_unit() == 0 {
        let rel = BigRational::new(BigInt::one(), BigInt::one() << MARGIN_REL_TOL_BITS as usize);
        let min = min_enclosure(p, &Tol::Relative(rel));
        return Verdict::Safe { margin: f64_below(&min.lower) };
    }
    let Some(roots) = seq.isolate_unit() else {
        return Verdict::Undecided(Undecided::DepthLimit);
    };
    // p keeps one sign between consecutive distinct roots; the right end of each
    // isolating interval lies in the gap after its root (or is the root itself). The
    // gaps before the first and after the last root are positive (p(0), p(1) > 0).
    for cell in roots.iter().take(roots.len().saturating_sub(1)) {
        let b = cell.right();
        if eval_sign(&z, &b) != Ordering::Greater {
            return witness_near(p, &b);
        }
    }
    // p ≥ 0 with zeros (touches). A rational root of the primitive integer polynomial
    // `sqf` has a denominator dividing its leading coefficient, so a dyadic root k/2^e
    // has e ≤ v2(lc): bisecting each cell down to that resolution finds it if it exists.
    let v2 = sqf.last().and_then(BigInt::trailing_zeros).unwrap_or(0);
    let bits = u32::try_from(v2).unwrap_or(u32::MAX);
    for cell in roots {
        if let Some(r) = cell.find_dyadic_root(&sqf, bits) {
            if let Some(t) = r.to_f64_exact() {
                return Verdict::Unsafe(Witness { tau: t, value: 0.0 });
            }
        }
    }
    Verdict::Undecided(Undecided::DepthLimit)
}

/// Number of distinct real roots of `p` in `(a, b]` (0 when `a ≥ b`; `usize::MAX` for
/// the zero polynomial, which vanishes everywhere).
pub fn count_roots_in(p: &UPoly<BigRational>, a: &BigRational, b: &BigRational) -> usize {
    if p.is_zero() {
        return usize::MAX;
    }
    if a >= b || p.degree() == 0 {
        return 0;
    }
    let seq = SturmSeq::new(&square_free(&to_integer(p.coeffs()).0));
    seq.variations(&|v| eval_sign_rational(v, a)).saturating_sub(seq.variations(&|v| eval_sign_rational(v, b)))
}

/// An enclosure of `min_{[0,1]} p`: `lower ≤ min p ≤ upper = p(argmin)`.
#[derive(Clone, Debug, PartialEq)]
pub struct MinEnclosure {
    /// Proven lower bound on the minimum.
    pub lower: BigRational,
    /// An attained value, `p(argmin)`, hence an upper bound on the minimum.
    pub upper: BigRational,
    /// Where `upper` is attained (a dyadic rational in [0, 1]).
    pub argmin: BigRational,
    /// Whether `upper − lower` reached the requested tolerance (it does unless the
    /// tolerance is 0 or [`MAX_MIN_REFINE_BITS`] ran out).
    pub converged: bool,
}

/// Tolerance for [`min_enclosure`].
#[derive(Clone, Debug)]
enum Tol {
    /// `upper − lower ≤ tol`.
    Absolute(BigRational),
    /// `upper − lower ≤ tol·|upper|`.
    Relative(BigRational),
}

impl Tol {
    /// The lowest acceptable lower bound given the best value found so far.
    fn floor(&self, upper: &BigRational) -> BigRational {
        match self {
            Tol::Absolute(t) => upper - t,
            Tol::Relative(t) => upper - t * upper.abs(),
        }
    }
}

/// `min_{[0,1]} p` to within `tol` (absolute): the exact values at 0 and 1, and around
/// each critical point (root of `p'` in (0, 1), isolated with Sturm sequences) a Taylor
/// bound `p(m) − Σ_{k≥1} |p^(k)(m)/k!| r^k` on `[m − r, m + r]`, refined by bisection
/// until it is within `tol` of the best value found. This is the exact `min p` of
/// docs/design.md §5.8 for the `|γ − min p|` checks of the SDP path.
pub fn min_on_unit(p: &UPoly<BigRational>, tol: &BigRational) -> MinEnclosure {
    min_enclosure(p, &Tol::Absolute(tol.abs()))
}

fn min_enclosure(p: &UPoly<BigRational>, tol: &Tol) -> MinEnclosure {
    let (z, scale) = to_integer(p.coeffs());
    let at = |v: BigInt| BigRational::from_integer(v) * &scale;
    let (p0, p1) = (at(z.first().cloned().unwrap_or_default()), at(z.iter().sum()));
    let mut lower = if p1 < p0 { p1.clone() } else { p0.clone() };
    let mut best = Best { upper: p0, argmin: BigRational::zero() };
    best.offer(p1, BigRational::one);
    if p.degree() == 0 {
        return MinEnclosure { lower, upper: best.upper, argmin: best.argmin, converged: true };
    }
    let dz = square_free(&derivative(&z));
    let Some(crit) = SturmSeq::new(&dz).isolate_unit() else {
        // |p| ≤ Σ|a_i| on [0, 1]: crude but sound
        let bound: BigRational = p.coeffs().iter().map(Signed::abs).sum();
        return MinEnclosure { lower: -bound, upper: best.upper, argmin: best.argmin, converged: false };
    };
    let search = MinSearch { z: &z, scale: &scale, dz: &dz, tol };
    // first pass: the value at each critical cell's midpoint lowers `upper` early, so
    // that fewer cells need refining
    for cell in &crit {
        search.offer_at(&cell.mid(), &mut best);
    }
    let mut converged = true;
    for cell in crit {
        let (lb, ok) = search.refine(cell, &mut best);
        converged &= ok;
        if lb < lower {
            lower = lb;
        }
    }
    if lower > best.upper {
        lower = best.upper.clone();
    }
    converged &= lower >= tol.floor(&best.upper);
    MinEnclosure { lower, upper: best.upper, argmin: best.argmin, converged }
}

/// The smallest value of `p` found so far and where.
struct Best {
    upper: BigRational,
    argmin: BigRational,
}

impl Best {
    fn offer(&mut self, v: BigRational, at: impl FnOnce() -> BigRational) {
        if v < self.upper {
            self.upper = v;
            self.argmin = at();
        }
    }
}

/// `p = scale·z` and the square-free part `dz` of `z'`, whose roots are the critical
/// points.
struct MinSearch<'a> {
    z: &'a [BigInt],
    scale: &'a BigRational,
    dz: &'a [BigInt],
    tol: &'a Tol,
}

impl MinSearch<'_> {
    fn value(&self, x: &Dyadic) -> BigRational {
        let den = BigInt::one() << (x.e as usize * (self.z.len() - 1));
        BigRational::new(x.eval(self.z), den) * self.scale
    }

    /// Offers `p(x)` to `best`; returns it.
    fn offer_at(&self, x: &Dyadic, best: &mut Best) -> BigRational {
        let v = self.value(x);
        best.offer(v.clone(), || x.to_rational());
        v
    }

    /// A lower bound of `p` around the one critical point in `cell` that is within the
    /// tolerance of `best.upper`, and whether that was reached before
    /// [`MAX_MIN_REFINE_BITS`]. Bisects by the sign of `dz` (a simple root in the cell).
    fn refine(&self, mut cell: Cell, best: &mut Best) -> (BigRational, bool) {
        let sign_b = eval_sign(self.dz, &cell.right());
        if sign_b == Ordering::Equal {
            // the critical point is exactly the cell's right end
            return (self.offer_at(&cell.right(), best), true);
        }
        loop {
            let (lb, at_m) = cell.taylor_bounds(self.z, self.scale);
            best.offer(at_m.clone(), || cell.mid().to_rational());
            let floor = self.tol.floor(&best.upper);
            if lb >= floor {
                return (lb, true);
            }
            if cell.e >= MAX_MIN_REFINE_BITS {
                return (lb, false);
            }
            // the gap shrinks about 4× per halving near a critical point
            let room = &at_m - &floor;
            let ratio = if room.is_positive() { rational_to_f64(&((&at_m - &lb) / room)) } else { f64::INFINITY };
            let steps =
                if ratio.is_finite() { (ratio.log2() / 2.0).ceil() as u32 + 1 } else { MAX_BISECTIONS_PER_BOUND };
            for _ in 0..steps.clamp(1, MAX_BISECTIONS_PER_BOUND) {
                let m = cell.mid();
                match eval_sign(self.dz, &m) {
                    Ordering::Equal => return (self.offer_at(&m, best), true),
                    s if s == sign_b => cell = cell.left_half(),
                    _ => cell = cell.right_half(),
                }
            }
        }
    }
}

/// A witness at the dyadic `x` where `p(x) ≤ 0`: `x` itself when it is a float, else
/// the nearest float if `p` is still `≤ 0` there.
fn witness_near(p: &UPoly<BigRational>, x: &Dyadic) -> Verdict {
    let t = x.to_f64_exact().unwrap_or_else(|| rational_to_f64(&x.to_rational()));
    if let Some(exact) = BigRational::from_float(t) {
        let v = p.eval(&exact);
        if !v.is_positive() {
            return Verdict::Unsafe(Witness { tau: t, value: rational_to_f64(&v) });
        }
    }
    Verdict::Undecided(Undecided::DepthLimit)
}

// ---------------------------------------------------------------------------------
// dyadic points and cells

/// The dyadic rational `n / 2^e`.
#[derive(Clone, Debug, PartialEq)]
struct Dyadic {
    n: BigInt,
    e: u32,
}

impl Dyadic {
    fn to_rational(&self) -> BigRational {
        BigRational::new(self.n.clone(), BigInt::one() << self.e as usize)
    }

    /// The `f64` equal to this number, if there is one.
    fn to_f64_exact(&self) -> Option<f64> {
        let r = self.to_rational();
        let t = rational_to_f64(&r);
        (BigRational::from_float(t).as_ref() == Some(&r)).then_some(t)
    }

    /// `2^(e·deg) · v(n/2^e)`, an integer with the sign of `v` here.
    fn eval(&self, v: &[BigInt]) -> BigInt {
        let Some(last) = v.last() else {
            return BigInt::zero();
        };
        let mut acc = last.clone();
        for (k, c) in v.iter().rev().skip(1).enumerate() {
            acc = acc * &self.n + (c << (self.e as usize * (k + 1)));
        }
        acc
    }
}

/// The cell `(j/2^e, (j+1)/2^e]`.
#[derive(Clone, Debug)]
struct Cell {
    j: BigInt,
    e: u32,
}

impl Cell {
    fn unit() -> Self {
        Cell { j: BigInt::zero(), e: 0 }
    }
    fn left(&self) -> Dyadic {
        Dyadic { n: self.j.clone(), e: self.e }
    }
    fn right(&self) -> Dyadic {
        Dyadic { n: &self.j + 1, e: self.e }
    }
    fn mid(&self) -> Dyadic {
        Dyadic { n: (&self.j << 1usize) + 1, e: self.e + 1 }
    }
    fn left_half(&self) -> Cell {
        Cell { j: &self.j << 1usize, e: self.e + 1 }
    }
    fn right_half(&self) -> Cell {
        Cell { j: (&self.j << 1usize) + 1, e: self.e + 1 }
    }

    /// Bisects (by sign: `s` has one simple root in the cell) down to resolution
    /// `2^-bits`, returning a bisection point or right end that is exactly a root.
    fn find_dyadic_root(mut self, s: &[BigInt], bits: u32) -> Option<Dyadic> {
        let sign_b = eval_sign(s, &self.right());
        if sign_b == Ordering::Equal {
            return Some(self.right());
        }
        while self.e < bits {
            let m = self.mid();
            match eval_sign(s, &m) {
                Ordering::Equal => return Some(m),
                x if x == sign_b => self = self.left_half(),
                _ => self = self.right_half(),
            }
        }
        None
    }

    /// Taylor bounds of `p = scale·z` on the closed cell: `(lower bound, p(mid))`.
    ///
    /// With `m = M/2^E` the midpoint (`E = e + 1`) and radius `2^-E`,
    /// `H(u) = 2^(E·deg) z((M + u)/2^E) = Σ_i z_i (M + u)^i 2^(E(deg−i))` is an integer
    /// polynomial in `u ∈ [−1, 1]`, so `H ≥ H_0 − Σ_{k≥1} |H_k|` there.
    fn taylor_bounds(&self, z: &[BigInt], scale: &BigRational) -> (BigRational, BigRational) {
        let mid = self.mid();
        let deg = z.len() - 1;
        let mut h: Vec<BigInt> = vec![z[deg].clone()];
        for (k, c) in z.iter().rev().skip(1).enumerate() {
            // h ← h·(M + u) + c·2^(E(k+1))
            let mut next = vec![BigInt::zero(); h.len() + 1];
            for (i, hi) in h.iter().enumerate() {
                next[i] += hi * &mid.n;
                next[i + 1] += hi;
            }
            next[0] += c << (mid.e as usize * (k + 1));
            h = next;
        }
        let den = BigRational::from_integer(BigInt::one() << (mid.e as usize * deg));
        let h0 = h[0].clone();
        let spread: BigInt = h.iter().skip(1).map(Signed::abs).sum();
        let at_m = BigRational::from_integer(h0.clone()) / &den * scale;
        let lb = BigRational::from_integer(h0 - spread) / &den * scale;
        (lb, at_m)
    }
}

// ---------------------------------------------------------------------------------
// integer polynomials (coefficients in increasing powers, no trailing zeros)

/// The primitive integer polynomial `z` and the positive `scale` with `a = scale·z`.
fn to_integer(a: &[BigRational]) -> (Vec<BigInt>, BigRational) {
    let den = a.iter().fold(BigInt::one(), |l, x| l.lcm(x.denom()));
    let z: Vec<BigInt> = trim(a.iter().map(|x| x.numer() * (&den / x.denom())).collect());
    let g = content(&z);
    if g.is_zero() {
        return (z, BigRational::one());
    }
    let scale = BigRational::new(g.clone(), den);
    (z.into_iter().map(|c| c / &g).collect(), scale)
}

fn trim(mut v: Vec<BigInt>) -> Vec<BigInt> {
    while v.last().is_some_and(Zero::is_zero) {
        v.pop();
    }
    v
}

/// The gcd of the coefficients (≥ 0).
///
/// Euclid's algorithm from the smallest coefficient, stopping at 1: after one division
/// everything is at most the size of that coefficient. (`num_integer`'s gcd is binary,
/// which costs a pass over the big operand per bit even when the other one is 1.)
fn content(v: &[BigInt]) -> BigInt {
    let Some(start) = v.iter().filter(|c| !c.is_zero()).min_by_key(|c| c.bits()) else {
        return BigInt::zero();
    };
    let mut g = start.abs();
    for c in v {
        if g.is_one() {
            break;
        }
        let mut a = g;
        let mut b = c % &a;
        while !b.is_zero() {
            let r = &a % &b;
            a = b;
            b = r;
        }
        g = a.abs();
    }
    g
}

/// Divides by the (positive) gcd of the coefficients.
fn primitive(v: Vec<BigInt>) -> Vec<BigInt> {
    let v = trim(v);
    let g = content(&v);
    if g.is_zero() || g.is_one() {
        return v;
    }
    v.into_iter().map(|c| c / &g).collect()
}

fn derivative(v: &[BigInt]) -> Vec<BigInt> {
    trim(v.iter().enumerate().skip(1).map(|(i, c)| c * BigInt::from(i)).collect())
}

/// Pseudo-division: `lc(b)^δ · a = q·b + r` with `δ = deg a − deg b + 1` and
/// `deg r < deg b`. Returns `(q, r, lc(b)^δ > 0)`. `b` must be non-zero.
fn pseudo_divide(a: &[BigInt], b: &[BigInt]) -> (Vec<BigInt>, Vec<BigInt>, bool) {
    let Some(lc) = b.last() else {
        return (Vec::new(), a.to_vec(), true);
    };
    if a.len() < b.len() {
        return (Vec::new(), a.to_vec(), true);
    }
    let delta = a.len() - b.len() + 1;
    let mut r = a.to_vec();
    let mut q = vec![BigInt::zero(); delta];
    let mut steps = 0;
    while r.len() >= b.len() {
        let s = r.len() - b.len();
        let t = r.last().cloned().unwrap_or_default();
        for c in q.iter_mut().chain(r.iter_mut()) {
            *c *= lc;
        }
        q[s] += &t;
        for (i, bc) in b.iter().enumerate() {
            r[s + i] -= &t * bc;
        }
        r = trim(r);
        steps += 1;
    }
    // the remaining factor lc^(δ − steps), so that the multiplier is always lc^δ
    for _ in steps..delta {
        for c in q.iter_mut().chain(r.iter_mut()) {
            *c *= lc;
        }
    }
    let positive = !(lc.is_negative() && delta % 2 == 1);
    (trim(q), r, positive)
}

/// Primitive gcd (up to sign) by the primitive pseudo-remainder sequence.
fn gcd(a: &[BigInt], b: &[BigInt]) -> Vec<BigInt> {
    let (mut x, mut y) = (primitive(a.to_vec()), primitive(b.to_vec()));
    while !y.is_empty() {
        let (_, r, _) = pseudo_divide(&x, &y);
        x = y;
        y = primitive(r);
    }
    x
}

/// The square-free part `v / gcd(v, v')` (primitive, sign irrelevant for root counting).
fn square_free(v: &[BigInt]) -> Vec<BigInt> {
    let g = gcd(v, &derivative(v));
    if g.len() <= 1 {
        return primitive(v.to_vec());
    }
    primitive(pseudo_divide(v, &g).0)
}

fn sign_of(x: &BigInt) -> Ordering {
    x.sign().cmp(&num_bigint::Sign::NoSign)
}

/// Sign of `v` at a dyadic point.
fn eval_sign(v: &[BigInt], x: &Dyadic) -> Ordering {
    sign_of(&x.eval(v))
}

/// Sign of `v(x)` for a rational `x = n/d` (`d > 0`): the sign of the homogenised
/// Horner sum `Σ v_i n^i d^(deg−i)`, an integer.
fn eval_sign_rational(v: &[BigInt], x: &BigRational) -> Ordering {
    let (n, d) = (x.numer(), x.denom());
    let Some(last) = v.last() else {
        return Ordering::Equal;
    };
    let mut acc = last.clone();
    let mut dpow = BigInt::one();
    for c in v.iter().rev().skip(1) {
        dpow *= d;
        acc = acc * n + c * &dpow;
    }
    sign_of(&acc)
}

/// A Sturm sequence of a square-free polynomial.
struct SturmSeq {
    seq: Vec<Vec<BigInt>>,
}

impl SturmSeq {
    fn new(s: &[BigInt]) -> Self {
        let mut seq = vec![s.to_vec()];
        let d = primitive(derivative(s));
        if !d.is_empty() {
            seq.push(d);
        }
        while seq.len() >= 2 {
            let (a, b) = (&seq[seq.len() - 2], &seq[seq.len() - 1]);
            let (_, r, positive) = pseudo_divide(a, b);
            if r.is_empty() {
                break;
            }
            // a positive multiple of −rem(a, b)
            let next = if positive { r.into_iter().map(|c| -c).collect() } else { r };
            seq.push(primitive(next));
        }
        SturmSeq { seq }
    }

    /// Sign changes of the sequence, zeros skipped, for a sign oracle.
    fn variations(&self, sign: &dyn Fn(&[BigInt]) -> Ordering) -> usize {
        let mut last = Ordering::Equal;
        let mut changes = 0;
        for s in &self.seq {
            let sg = sign(s);
            if sg != Ordering::Equal {
                if last != Ordering::Equal && sg != last {
                    changes += 1;
                }
                last = sg;
            }
        }
        changes
    }

    fn variations_at(&self, x: &Dyadic) -> usize {
        self.variations(&|v| eval_sign(v, x))
    }

    /// Distinct roots in (0, 1].
    fn count_unit(&self) -> usize {
        let c = Cell::unit();
        self.variations_at(&c.left()).saturating_sub(self.variations_at(&c.right()))
    }

    /// Cells `(j/2^e, (j+1)/2^e]`, increasing, each holding exactly one root in (0, 1].
    /// `None` if [`MAX_ISOLATION_BITS`] ran out.
    fn isolate_unit(&self) -> Option<Vec<Cell>> {
        let unit = Cell::unit();
        let (v0, v1) = (self.variations_at(&unit.left()), self.variations_at(&unit.right()));
        let mut out = Vec::new();
        // (cell, V(left end), V(right end))
        let mut work = vec![(unit, v0, v1)];
        while let Some((cell, va, vb)) = work.pop() {
            match va.saturating_sub(vb) {
                0 => {}
                1 => out.push(cell),
                _ if cell.e >= MAX_ISOLATION_BITS => return None,
                _ => {
                    let vm = self.variations_at(&cell.mid());
                    work.push((cell.right_half(), vm, vb));
                    work.push((cell.left_half(), va, vm));
                }
            }
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn q(n: i64, d: i64) -> BigRational {
        BigRational::new(n.into(), d.into())
    }

    /// `c · Π (τ − r)^m`.
    fn from_roots(c: BigRational, roots: &[(BigRational, u32)]) -> UPoly<BigRational> {
        let mut p = UPoly::constant(c);
        for (r, m) in roots {
            for _ in 0..*m {
                p = p.mul(&UPoly::linear(-r.clone(), BigRational::one()));
            }
        }
        p
    }

    #[test]
    fn counts_distinct_roots() {
        let p = from_roots(q(3, 1), &[(q(1, 3), 2), (q(1, 2), 1), (q(2, 1), 3), (q(-1, 5), 1)]);
        assert_eq!(count_roots_in(&p, &q(0, 1), &q(1, 1)), 2);
        assert_eq!(count_roots_in(&p, &q(-1, 1), &q(3, 1)), 4);
        // half-open: (1/3, 1/2] holds 1/2 only
        assert_eq!(count_roots_in(&p, &q(1, 3), &q(1, 2)), 1);
        assert_eq!(count_roots_in(&p, &q(1, 2), &q(1, 1)), 0);
        assert_eq!(count_roots_in(&p, &q(1, 1), &q(0, 1)), 0);
        assert_eq!(count_roots_in(&UPoly::zero(), &q(0, 1), &q(1, 1)), usize::MAX);
        assert_eq!(count_roots_in(&UPoly::constant(q(2, 1)), &q(0, 1), &q(1, 1)), 0);
    }

    #[test]
    fn decides_fixtures() {
        let sq = from_roots(q(1, 1), &[(q(3, 10), 2)]);
        // a touch at a non-float point: proven, but without a float witness
        assert_eq!(decide(&sq), Verdict::Undecided(Undecided::DepthLimit));
        // a touch at a float: witnessed
        let half = from_roots(q(1, 1), &[(q(1, 2), 2)]);
        assert_eq!(decide(&half), Verdict::Unsafe(Witness { tau: 0.5, value: 0.0 }));
        let plus = sq.add(&UPoly::constant(q(1, 1_000_000_000)));
        let Verdict::Safe { margin } = decide(&plus) else { panic!() };
        assert!((1e-9 * (1.0 - MARGIN_REL_TOL)..=1e-9).contains(&margin), "{margin}");
        let minus = sq.sub(&UPoly::constant(q(1, 1_000_000_000_000)));
        let Verdict::Unsafe(w) = decide(&minus) else { panic!() };
        assert!(minus.eval(&BigRational::from_float(w.tau).unwrap()) < BigRational::zero());
        let ends = UPoly::new(vec![q(0, 1), q(-1, 1), q(1, 1)]);
        assert!(decide(&ends).is_unsafe());
        assert_eq!(decide(&UPoly::zero()), Verdict::Unsafe(Witness { tau: 0.0, value: 0.0 }));
        assert_eq!(decide(&UPoly::constant(q(1, 4))), Verdict::Safe { margin: 0.25 });
        assert!(decide(&UPoly::constant(q(-1, 4))).is_unsafe());
    }

    #[test]
    fn exact_minimum() {
        // (τ − 1/3)² + 1/7: min 1/7 at the non-dyadic 1/3
        let p = from_roots(q(1, 1), &[(q(1, 3), 2)]).add(&UPoly::constant(q(1, 7)));
        let tol = q(1, 1_000_000_000_000);
        let m = min_on_unit(&p, &tol);
        assert!(m.converged && m.lower <= q(1, 7) && q(1, 7) <= m.upper && &m.upper - &m.lower <= tol);
        assert_eq!(p.eval(&m.argmin), m.upper);
        // monotone: min at an end, exact
        let lin = UPoly::linear(q(2, 1), q(-1, 1));
        let m = min_on_unit(&lin, &tol);
        assert_eq!((m.lower, m.upper), (q(1, 1), q(1, 1)));
        // a degenerate critical point (p' has a double root at 1/2): (τ − 1/2)^4 − 1/3
        let p = from_roots(q(1, 1), &[(q(1, 2), 4)]).sub(&UPoly::constant(q(1, 3)));
        let m = min_on_unit(&p, &tol);
        assert_eq!(m.upper, q(-1, 3));
        assert!(m.lower <= q(-1, 3));
    }

    proptest! {
        /// Root counts match the construction; decisions match the known sign.
        #[test]
        fn matches_construction(
            roots in proptest::collection::vec((-20i64..40, 1i64..17, 1u32..4), 1..5),
            c in 1i64..9,
        ) {
            let rs: Vec<(BigRational, u32)> = roots.iter().map(|&(n, d, m)| (q(n, d), m)).collect();
            let p = from_roots(q(c, 1), &rs);
            let mut distinct: Vec<BigRational> = rs.iter().map(|(r, _)| r.clone()).filter(|r| *r > q(0, 1) && *r <= q(1, 1)).collect();
            distinct.sort();
            distinct.dedup();
            prop_assert_eq!(count_roots_in(&p, &q(0, 1), &q(1, 1)), distinct.len());
            let any_in = rs.iter().any(|(r, _)| *r >= q(0, 1) && *r <= q(1, 1));
            let v = decide(&p);
            if any_in {
                prop_assert!(!v.is_safe());
            } else {
                // constant sign on [0, 1]: that of p(0)
                prop_assert_eq!(v.is_safe(), p.eval(&q(0, 1)) > q(0, 1));
            }
            if let Verdict::Unsafe(w) = v {
                prop_assert!(p.eval(&BigRational::from_float(w.tau).unwrap()) <= q(0, 1));
            }
            if let Verdict::Safe { margin } = decide(&p) {
                let m = min_on_unit(&p, &q(1, 1_000_000));
                prop_assert!(BigRational::from_float(margin).unwrap() <= m.upper);
            }
        }
    }
}
