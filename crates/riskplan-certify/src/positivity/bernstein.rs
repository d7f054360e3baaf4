//! Positivity on [0, 1] without an SDP: Bernstein subdivision (docs/design.md §5.3).
//!
//! The continuous-time safety condition of the paper, eq. (15) (`SOS_Cond`), asks
//! whether a constraint restricted to a trajectory piece, `p(τ)`, is positive for
//! every τ in [0, 1] (§5.1). Instead of an SOS certificate this module decides it
//! directly from the Bernstein form of `p` on [0, 1]:
//!
//! ```text
//! p(τ) = Σ_k b_k C(n,k) τ^k (1−τ)^(n−k),   b_k = Σ_{i≤k} C(k,i)/C(n,i) a_i
//! ```
//!
//! On [0, 1], `min_k b_k ≤ p ≤ max_k b_k`, `b_0 = p(0)` and `b_n = p(1)`. A work-list
//! of dyadic sub-intervals is refined by de Casteljau halving (exact at ½ up to the
//! rounding of one addition):
//!
//! * every `b_k > 0`: the sub-interval is certified, and `min_k b_k` is a proven lower
//!   bound on `p` there, so the smallest one over all leaves is the reported margin;
//! * `b_0 ≤ 0` or `b_n ≤ 0`: `p` is non-positive at an end of the sub-interval, a
//!   dyadic (hence exactly representable) τ — a witness of "unsafe". Touching, `p = 0`,
//!   is unsafe by policy (§5.1);
//! * otherwise the sub-interval is halved, until [`DEFAULT_MAX_DEPTH`].
//!
//! Three entry points: [`check_interval`] (outward-rounded `f64` intervals, no heap
//! allocation up to [`MAX_DEGREE`]), [`check_exact`] (exact rationals, kept as integers
//! over a common denominator and a power of two), and [`check`], which runs the fast
//! one and redoes only undecided cases exactly.

use crate::positivity::verdict::{Undecided, Verdict, Witness};
use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::BigRational;
use num_traits::{One, Signed};
use riskplan_math::poly::{rational_to_f64, Interval, UPoly};
use std::sync::OnceLock;

/// Default subdivision depth: leaves are `2^-40` wide.
///
/// A polynomial with a strictly positive minimum `μ` is certified once the leaves are
/// narrow enough that the control polygon is within `μ` of the curve, which needs width
/// about `sqrt(μ / |p''|)`; at `2^-40` that covers `μ` down to about `2^-80·|p''|`,
/// far below the f64 resolution of the interval path. What remains undecided at this
/// depth is, in practice, only a tangency (`min p = 0` at a point that is not a dyadic
/// rational, so no sub-interval end can prove it). Deeper subdivision would only cost
/// time; undecided always counts as unsafe.
pub const DEFAULT_MAX_DEPTH: u32 = 40;

/// Largest subdivision depth honoured; larger requests are clamped to it.
///
/// A sub-interval at depth `d` has ends `j/2^d` with `j ≤ 2^d`; for `d ≤ 52` every such
/// point is an `f64` exactly, so a witness τ is always exact. Beyond that the witness
/// could not be reported as a float.
pub const MAX_DEPTH_LIMIT: u32 = 52;

/// Largest degree handled by [`check_interval`] in fixed-size stack buffers, with the
/// reciprocal binomials `1/C(n, i)` enclosed once in a table (no heap allocation per
/// call). Higher degrees are still decided soundly, with heap buffers and binomials
/// enclosed from exact integers on each call.
pub const MAX_DEGREE: usize = 32;

/// Node budget of [`check_interval`]. Each node costs `O(n²)` interval operations; a
/// search that needs more than this many nodes is handed to the exact path (as
/// `Undecided(DepthLimit)`) rather than allowed to run long. Far above what any
/// decidable case of degree ≤ [`MAX_DEGREE`] needs (a tangency costs a few nodes per
/// level).
pub const MAX_INTERVAL_NODES: usize = 1 << 16;

/// Node budget of [`check_exact`]: beyond it the answer is `Undecided(DepthLimit)`.
/// Exact subdivision near a tangency keeps a bounded number of nodes per level, so
/// this only stops pathological inputs from running for minutes.
pub const MAX_EXACT_NODES: usize = 1 << 18;

/// The zero polynomial vanishes everywhere: unsafe, witness at τ = 0.
const ZERO_WITNESS: Witness = Witness { tau: 0.0, value: 0.0 };

/// Decides `p > 0` on [0, 1] in outward-rounded interval arithmetic.
///
/// Sound for every input: `Safe` only when every leaf's Bernstein lower bounds are
/// `> 0` (the margin is the smallest of them), `Unsafe` only with a τ at which an
/// enclosure of `p(τ)` has `hi ≤ 0`. Non-finite or inverted coefficients give
/// `Undecided(NonFinite)`.
///
/// The search stops at the first node still undecided at `max_depth` (clamped to
/// [`MAX_DEPTH_LIMIT`]) or after [`MAX_INTERVAL_NODES`] nodes, with
/// `Undecided(DepthLimit)`. Continuing would not pay: once the rounding noise exceeds
/// the values near a tangency, *every* node there stays undecided and their number
/// doubles per level; the exact path ([`check`]) decides those cases in a few nodes
/// per level.
pub fn check_interval(p: &UPoly<Interval>, max_depth: u32) -> Verdict {
    check_interval_coeffs(p.coeffs(), max_depth)
}

/// [`check_interval`] on monomial coefficients `a[k]` of `τ^k` given as a slice (no
/// polynomial object: the compiled restriction of [`crate::compiled`] produces these).
pub fn check_interval_coeffs(a: &[Interval], max_depth: u32) -> Verdict {
    if a.iter().any(|x| !(x.lo.is_finite() && x.hi.is_finite() && x.lo <= x.hi)) {
        return Verdict::Undecided(Undecided::NonFinite);
    }
    if a.is_empty() {
        return Verdict::Unsafe(ZERO_WITNESS);
    }
    if let [c] = a {
        // a constant: subdivision cannot change its enclosure
        return if c.lo > 0.0 {
            Verdict::Safe { margin: c.lo }
        } else if c.hi <= 0.0 {
            Verdict::Unsafe(interval_witness(0.0, *c))
        } else {
            Verdict::Undecided(Undecided::DepthLimit)
        };
    }
    let max_depth = max_depth.min(MAX_DEPTH_LIMIT);
    let m = a.len();
    if m > MAX_DEGREE + 1 {
        let mut b = vec![Interval::point(0.0); m];
        bernstein_interval_into(a, &mut b);
        if let Some(v) = decide_root(a, &b, max_depth) {
            return v;
        }
        let (mut cur, mut tmp) = (b.clone(), b.clone());
        let mut stack = vec![b[0]; m * max_depth as usize];
        let mut work = Slices { cur: &mut cur, tmp: &mut tmp, stack: &mut stack };
        return subdivide_interval(a, &b, max_depth, &mut work);
    }
    let mut b = [Interval::point(0.0); MAX_DEGREE + 1];
    let b = &mut b[..m];
    bernstein_interval_into(a, b);
    // most pieces are decided by the root's coefficients: settle those before any
    // work buffer is set up (zeroing it costs more than the whole decision)
    if let Some(v) = decide_root(a, b, max_depth) {
        return v;
    }
    let need = m * max_depth as usize;
    if need <= 128 {
        run_in_stack_buffer::<128>(a, b, max_depth)
    } else if need <= 256 {
        run_in_stack_buffer::<256>(a, b, max_depth)
    } else if need <= 512 {
        run_in_stack_buffer::<512>(a, b, max_depth)
    } else {
        run_in_stack_buffer::<{ (MAX_DEGREE + 1) * MAX_DEPTH_LIMIT as usize }>(a, b, max_depth)
    }
}

/// An enclosure of the range on [0, 1] of the polynomial with monomial coefficients
/// `a` (outward-rounded intervals), from the hull of its Bernstein coefficients (the
/// convex hull property); `None` above [`MAX_DEGREE`] or for non-finite input.
pub fn bernstein_enclosure(a: &[Interval]) -> Option<Interval> {
    if a.is_empty() {
        return Some(Interval::point(0.0));
    }
    if a.len() > MAX_DEGREE + 1 || a.iter().any(|x| !(x.lo.is_finite() && x.hi.is_finite())) {
        return None;
    }
    let mut b = [Interval::point(0.0); MAX_DEGREE + 1];
    let b = &mut b[..a.len()];
    bernstein_interval_into(a, b);
    let lo = b.iter().map(|x| x.lo).fold(f64::INFINITY, f64::min);
    let hi = b.iter().map(|x| x.hi).fold(f64::NEG_INFINITY, f64::max);
    (lo.is_finite() && hi.is_finite() && b.iter().all(|x| !x.lo.is_nan() && !x.hi.is_nan()))
        .then_some(Interval { lo, hi })
}

/// [`bernstein_enclosure`] for any degree (a heap buffer above [`MAX_DEGREE`]): an
/// enclosure of the range on [0, 1] of the polynomial with monomial coefficients `a`;
/// `None` for non-finite input or results.
pub fn bernstein_hull(a: &[Interval]) -> Option<Interval> {
    if a.len() <= MAX_DEGREE + 1 {
        return bernstein_enclosure(a);
    }
    if a.iter().any(|x| !(x.lo.is_finite() && x.hi.is_finite())) {
        return None;
    }
    let mut b = vec![Interval::point(0.0); a.len()];
    bernstein_interval_into(a, &mut b);
    let lo = b.iter().map(|x| x.lo).fold(f64::INFINITY, f64::min);
    let hi = b.iter().map(|x| x.hi).fold(f64::NEG_INFINITY, f64::max);
    (lo.is_finite() && hi.is_finite()).then_some(Interval { lo, hi })
}

/// Decides `p > 0` on [0, 1] in exact rational arithmetic (same algorithm as
/// [`check_interval`]). Every witness value is exact (reported rounded to nearest);
/// the margin is an exact leaf bound rounded down. `Undecided(DepthLimit)` remains
/// only for tangencies at non-dyadic points and minima below about `2^(−2·max_depth)`.
/// (The margin is `0.0` only if `min p` is below the smallest positive `f64`.)
pub fn check_exact(p: &UPoly<BigRational>, max_depth: u32) -> Verdict {
    if p.is_zero() {
        return Verdict::Unsafe(ZERO_WITNESS);
    }
    let max_depth = max_depth.min(MAX_DEPTH_LIMIT);
    let (b, den) = bernstein_integer(p.coeffs());
    let n = b.len() - 1;
    let mut stack = vec![ExactNode { c: b, shift: 0, depth: 0, index: 0 }];
    let mut margin: Option<BigRational> = None;
    let mut undecided = false;
    let mut budget = MAX_EXACT_NODES;
    while let Some(node) = stack.pop() {
        if budget == 0 {
            return Verdict::Undecided(Undecided::DepthLimit);
        }
        budget -= 1;
        let value = |k: usize| BigRational::new(node.c[k].clone(), &den << node.shift);
        if !node.c[0].is_positive() {
            return Verdict::Unsafe(Witness { tau: dyadic(node.index, node.depth), value: rational_to_f64(&value(0)) });
        }
        if !node.c[n].is_positive() {
            return Verdict::Unsafe(Witness {
                tau: dyadic(node.index + 1, node.depth),
                value: rational_to_f64(&value(n)),
            });
        }
        if node.c.iter().all(Signed::is_positive) {
            let k = (0..=n).min_by(|&i, &j| node.c[i].cmp(&node.c[j])).unwrap_or(0);
            let v = value(k);
            if margin.as_ref().is_none_or(|m| v < *m) {
                margin = Some(v);
            }
        } else if node.depth >= max_depth {
            undecided = true;
        } else {
            let (left, right) = node.split();
            stack.push(right);
            stack.push(left);
        }
    }
    match margin {
        _ if undecided => Verdict::Undecided(Undecided::DepthLimit),
        Some(m) => Verdict::Safe { margin: f64_below(&m) },
        // unreachable: a finished search without undecided leaves certified at least one
        None => Verdict::Undecided(Undecided::DepthLimit),
    }
}

/// The recommended checker: [`check_interval`] at [`DEFAULT_MAX_DEPTH`], and only when
/// that is undecided, [`check_exact`] on the exact polynomial (built lazily by `exact`,
/// which must be the polynomial that `p` encloses).
pub fn check(p: &UPoly<Interval>, exact: impl FnOnce() -> UPoly<BigRational>) -> Verdict {
    match check_interval(p, DEFAULT_MAX_DEPTH) {
        Verdict::Undecided(_) => check_exact(&exact(), DEFAULT_MAX_DEPTH),
        decided => decided,
    }
}

/// The Bernstein coefficients of `p` on [0, 1], exactly (`b_0 = p(0)`, `b_n = p(1)`;
/// `max |b_k|` bounds `|p|` on [0, 1], the normalisation of docs/design.md §5.5).
/// Empty for the zero polynomial.
pub fn bernstein_coefficients(p: &UPoly<BigRational>) -> Vec<BigRational> {
    if p.is_zero() {
        return Vec::new();
    }
    let (b, den) = bernstein_integer(p.coeffs());
    b.into_iter().map(|c| BigRational::new(c, den.clone())).collect()
}

/// The largest `f64` that is `≤ r` (a sound lower bound; `-∞` below the range): the
/// lower end of the tightest float enclosure of `r`.
pub(crate) fn f64_below(r: &BigRational) -> f64 {
    Interval::enclose_rational(r).lo
}

/// `j / 2^d` as an `f64`, exact for `d ≤ 52` and `j ≤ 2^d` (see [`MAX_DEPTH_LIMIT`]).
fn dyadic(j: u64, d: u32) -> f64 {
    j as f64 / (1u64 << d) as f64
}

// ---------------------------------------------------------------------------------
// interval path

/// Bernstein coefficients of the interval polynomial `a` into `out` (same length):
/// `ã_i = a_i · [1/C(n, i)]` (an outward-rounded product with an enclosure of the
/// reciprocal binomial), then the binomial transform `b_k = Σ_{i≤k} C(k,i) ã_i` by
/// `n(n+1)/2` interval additions.
fn bernstein_interval_into(a: &[Interval], out: &mut [Interval]) {
    let n = a.len() - 1;
    for (i, (o, &ai)) in out.iter_mut().zip(a).enumerate() {
        *o = if i == 0 || i == n { ai } else { ai * reciprocal_binomial(n, i) };
    }
    for s in 0..n {
        for i in (s + 1..=n).rev() {
            out[i] = out[i] + out[i - 1];
        }
    }
}

/// Degrees whose reciprocal binomials are tabulated: the moment bounds' restricted
/// constraints reach 8·deg P·deg piece (docs/design.md §3.8), 64 for a quadratic obstacle
/// on a quartic piece.
const TABLE_DEGREE: usize = 64;

/// An enclosure of `1/C(n, i)`: from a table built once for `n ≤ TABLE_DEGREE`, and from
/// exact integers above. The table's rows are built from exact 128-bit binomials
/// ([`reciprocal_enclosure`]); building it with rationals cost milliseconds, paid by the
/// first proof of every process (a CLI call's first plan).
fn reciprocal_binomial(n: usize, i: usize) -> Interval {
    static ROWS: [OnceLock<Vec<Interval>>; TABLE_DEGREE + 1] = [const { OnceLock::new() }; TABLE_DEGREE + 1];
    if n > TABLE_DEGREE {
        return Interval::enclose_rational(&BigRational::new(BigInt::one(), binomial_big(n, i)));
    }
    // one row per degree, on first use (a process proves at a few degrees only)
    let row = ROWS[n].get_or_init(|| {
        // C(n, i) by C(n, i+1) = C(n, i)·(n−i)/(i+1): exact, and below 2^63 for n ≤ 64
        let mut c: u128 = 1;
        (0..=n)
            .map(|i| {
                let r = reciprocal_enclosure(c as u64);
                c = c * (n - i) as u128 / (i + 1) as u128;
                r
            })
            .collect()
    });
    row[i]
}

/// The tightest float interval around `1/c` for an integer `c ≥ 1`: the quotient in
/// floating point, moved to the floats on either side of `1/c` by comparing `r·c` with 1
/// exactly in integers (`r = m·2^(−k)` with a 53-bit `m` and `k ≤ 116`, so `m·c < 2^128`).
fn reciprocal_enclosure(c: u64) -> Interval {
    if c <= 1 {
        return Interval::point(1.0);
    }
    // sign of r·c − 1 for a positive float r ≤ 1 (r ≥ 2^−64 here: normal)
    let cmp = |r: f64| -> std::cmp::Ordering {
        let bits = r.to_bits();
        let exp = ((bits >> 52) & 0x7ff) as i64;
        let mant = (bits & ((1u64 << 52) - 1)) | (1u64 << 52);
        let k = 1075 - exp; // r = mant·2^(−k), 52 ≤ k ≤ 116 for 2^−64 ≤ r ≤ 1
        (mant as u128 * c as u128).cmp(&(1u128 << k))
    };
    let r = 1.0 / c as f64;
    let mut lo = r;
    while cmp(lo) == std::cmp::Ordering::Greater {
        lo = lo.next_down();
    }
    while cmp(lo.next_up()) != std::cmp::Ordering::Greater {
        lo = lo.next_up();
    }
    if cmp(lo) == std::cmp::Ordering::Equal {
        return Interval::point(lo);
    }
    Interval::new(lo, lo.next_up())
}

/// `C(n, k)` exactly.
fn binomial_big(n: usize, k: usize) -> BigInt {
    let mut c = BigInt::one();
    for i in 1..=k {
        c = c * BigInt::from(n - i + 1) / BigInt::from(i);
    }
    c
}

/// De Casteljau at ½ in place: `c` becomes the right half's coefficients
/// (`β^(n−k)_k`), `left` receives the left half's (`β^(k)_0`).
fn split_interval(c: &mut [Interval], left: &mut [Interval]) {
    let n = c.len() - 1;
    left[0] = c[0];
    for (r, l) in left.iter_mut().enumerate().skip(1) {
        for j in 0..=n - r {
            c[j] = (c[j] + c[j + 1]).half();
        }
        *l = c[0];
    }
}

/// Interval Horner evaluation of the power-basis coefficients `a` at the float `t`.
fn horner(a: &[Interval], t: f64) -> Interval {
    let t = Interval::point(t);
    a.iter().rev().fold(Interval::point(0.0), |acc, &c| acc * t + c)
}

/// Working memory of one subdivision: the current node, the left half being built,
/// and the pending right halves (at most one per depth level, `max_depth` rows).
struct Slices<'a> {
    cur: &'a mut [Interval],
    tmp: &'a mut [Interval],
    stack: &'a mut [Interval],
}

/// [`subdivide_interval`] with all working memory on the stack; `K ≥ m·max_depth`.
fn run_in_stack_buffer<const K: usize>(a: &[Interval], b: &[Interval], max_depth: u32) -> Verdict {
    let zero = Interval::point(0.0);
    let mut cur = [zero; MAX_DEGREE + 1];
    let mut tmp = [zero; MAX_DEGREE + 1];
    let mut stack = [zero; K];
    subdivide_interval(a, b, max_depth, &mut Slices { cur: &mut cur, tmp: &mut tmp, stack: &mut stack })
}

/// The depth-first work-list of §5.3 on interval Bernstein coefficients `b` of `a`.
fn subdivide_interval(a: &[Interval], b: &[Interval], max_depth: u32, w: &mut Slices<'_>) -> Verdict {
    let m = b.len();
    let cur = &mut w.cur[..m];
    let tmp = &mut w.tmp[..m];
    cur.copy_from_slice(b);
    // (depth, index) of the pending right halves; node = [j/2^d, (j+1)/2^d]
    let mut pending = [(0u32, 0u64); MAX_DEPTH_LIMIT as usize];
    let mut sp = 0usize;
    let (mut depth, mut index) = (0u32, 0u64);
    let mut margin = f64::INFINITY;
    for _ in 0..MAX_INTERVAL_NODES {
        match visit(a, cur, index, depth, max_depth) {
            Node::Decided(v) => return v,
            Node::Certified(lo) => margin = margin.min(lo),
            Node::Split => {
                split_interval(cur, tmp);
                w.stack[sp * m..(sp + 1) * m].copy_from_slice(cur);
                pending[sp] = (depth + 1, 2 * index + 1);
                sp += 1;
                cur.copy_from_slice(tmp);
                depth += 1;
                index *= 2;
                continue;
            }
        }
        if sp == 0 {
            return Verdict::Safe { margin };
        }
        sp -= 1;
        cur.copy_from_slice(&w.stack[sp * m..(sp + 1) * m]);
        (depth, index) = pending[sp];
    }
    Verdict::Undecided(Undecided::DepthLimit)
}

/// What one node of the work-list settles.
enum Node {
    /// The whole search ends: a witness, or undecided at the depth limit.
    Decided(Verdict),
    /// `p > 0` on the node, with this lower bound.
    Certified(f64),
    /// Undecided above the depth limit: halve it.
    Split,
}

/// The tests of §5.3 on one node `[index/2^depth, (index+1)/2^depth]` with interval
/// Bernstein coefficients `c` (of the polynomial with power coefficients `a`).
fn visit(a: &[Interval], c: &[Interval], index: u64, depth: u32, max_depth: u32) -> Node {
    let n = c.len() - 1;
    if c[0].hi <= 0.0 {
        return Node::Decided(Verdict::Unsafe(interval_witness(dyadic(index, depth), c[0])));
    }
    if c[n].hi <= 0.0 {
        return Node::Decided(Verdict::Unsafe(interval_witness(dyadic(index + 1, depth), c[n])));
    }
    let mut lo_min = f64::INFINITY;
    let positive = c.iter().all(|x| {
        lo_min = lo_min.min(x.lo);
        x.lo > 0.0
    });
    if positive {
        return Node::Certified(lo_min);
    }
    if depth < max_depth {
        return Node::Split;
    }
    // a last chance for a witness: direct evaluation at the leaf's midpoint (its own
    // rounding, not the accumulated subdivision error)
    let mid = dyadic(2 * index + 1, depth + 1);
    let at_mid = horner(a, mid);
    if at_mid.hi <= 0.0 {
        return Node::Decided(Verdict::Unsafe(interval_witness(mid, at_mid)));
    }
    let finite = c.iter().all(|x| x.lo.is_finite() && x.hi.is_finite());
    Node::Decided(Verdict::Undecided(if finite { Undecided::DepthLimit } else { Undecided::NonFinite }))
}

/// The root node alone: `Some` verdict when it settles the question, `None` when the
/// search must subdivide. Non-finite Bernstein coefficients (overflow) are undecided.
fn decide_root(a: &[Interval], b: &[Interval], max_depth: u32) -> Option<Verdict> {
    if b.iter().any(|x| !(x.lo.is_finite() && x.hi.is_finite())) {
        return Some(Verdict::Undecided(Undecided::NonFinite));
    }
    match visit(a, b, 0, 0, max_depth) {
        Node::Decided(v) => Some(v),
        Node::Certified(lo) => Some(Verdict::Safe { margin: lo }),
        Node::Split => None,
    }
}

/// A witness from an enclosure `e` of `p(tau)` with `e.hi ≤ 0`; the reported value is
/// the enclosure's midpoint (≤ `hi` ≤ 0).
fn interval_witness(tau: f64, e: Interval) -> Witness {
    let value = if e.lo.is_finite() { e.mid().min(e.hi) } else { e.hi };
    Witness { tau, value }
}

// ---------------------------------------------------------------------------------
// exact path

/// Exact Bernstein coefficients as integers over one positive denominator:
/// `b_k = B_k / den`. `a` must be non-empty.
fn bernstein_integer(a: &[BigRational]) -> (Vec<BigInt>, BigInt) {
    let n = a.len() - 1;
    let mut binom = BigInt::one();
    let mut scaled = Vec::with_capacity(n + 1);
    for (i, ai) in a.iter().enumerate() {
        if i > 0 {
            binom = binom * BigInt::from(n - i + 1) / BigInt::from(i);
        }
        scaled.push(ai / BigRational::from_integer(binom.clone()));
    }
    let den = scaled.iter().fold(BigInt::one(), |l, x| l.lcm(x.denom()));
    let mut z: Vec<BigInt> = scaled.iter().map(|x| x.numer() * (&den / x.denom())).collect();
    for s in 0..n {
        for i in (s + 1..=n).rev() {
            let (lo, hi) = z.split_at_mut(i);
            hi[0] += &lo[i - 1];
        }
    }
    (z, den)
}

/// A node of the exact work-list: coefficient `k` is `c[k] / (den · 2^shift)` on
/// `[index/2^depth, (index+1)/2^depth]`.
struct ExactNode {
    c: Vec<BigInt>,
    shift: u64,
    depth: u32,
    index: u64,
}

impl ExactNode {
    /// De Casteljau at ½ without halving: the running sums `γ^(r)_j = 2^r β^(r)_j`
    /// stay integers, and both halves are scaled by `2^n` (then reduced by common
    /// factors of two).
    fn split(self) -> (ExactNode, ExactNode) {
        let n = self.c.len() - 1;
        let mut g = self.c;
        let mut left = Vec::with_capacity(n + 1);
        left.push(&g[0] << n);
        for r in 1..=n {
            for j in 0..=n - r {
                let (lo, hi) = g.split_at_mut(j + 1);
                lo[j] += &hi[0];
            }
            left.push(&g[0] << (n - r));
        }
        let right: Vec<BigInt> = g.into_iter().enumerate().map(|(k, x)| x << k).collect();
        let shift = self.shift + n as u64;
        let (depth, index) = (self.depth + 1, 2 * self.index);
        (ExactNode::reduced(left, shift, depth, index), ExactNode::reduced(right, shift, depth, index + 1))
    }

    /// Divides out the common power of two (at most `shift`).
    fn reduced(mut c: Vec<BigInt>, shift: u64, depth: u32, index: u64) -> ExactNode {
        let tz = c.iter().filter_map(BigInt::trailing_zeros).min().unwrap_or(0).min(shift);
        if tz > 0 {
            for x in &mut c {
                *x >>= tz;
            }
        }
        ExactNode { c, shift: shift - tz, depth, index }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_traits::Zero;
    use proptest::prelude::*;

    fn q(n: i64, d: i64) -> BigRational {
        BigRational::new(n.into(), d.into())
    }

    fn qp(c: &[(i64, i64)]) -> UPoly<BigRational> {
        UPoly::new(c.iter().map(|&(n, d)| q(n, d)).collect())
    }

    fn ip(p: &UPoly<BigRational>) -> UPoly<Interval> {
        p.map(Interval::enclose_rational)
    }

    fn binom(n: usize, k: usize) -> BigRational {
        BigRational::from_integer(binomial_big(n, k))
    }

    /// The table of reciprocal binomials, built in integers, is the tightest enclosure of
    /// each exact rational 1/C(n, i) (the oracle: rationals, as the table was built before).
    #[test]
    fn reciprocal_binomials_are_the_tightest_enclosures() {
        for n in 0..=TABLE_DEGREE + 2 {
            for i in 0..=n {
                let exact = BigRational::new(BigInt::one(), binomial_big(n, i));
                assert_eq!(reciprocal_binomial(n, i), Interval::enclose_rational(&exact), "1/C({n}, {i})");
            }
        }
        for c in [3u64, 7, 1 << 40, (1 << 53) + 1, u64::MAX / 3, (1 << 62) - 1] {
            let exact = BigRational::new(BigInt::one(), BigInt::from(c));
            assert_eq!(reciprocal_enclosure(c), Interval::enclose_rational(&exact), "1/{c}");
        }
    }

    /// `Σ b_k C(n,k) τ^k (1−τ)^(n−k)` at `t`.
    fn bernstein_eval(b: &[BigRational], t: &BigRational) -> BigRational {
        let n = b.len() - 1;
        let one = BigRational::one();
        b.iter().enumerate().fold(BigRational::zero(), |acc, (k, bk)| {
            acc + bk * binom(n, k) * num_traits::pow(t.clone(), k) * num_traits::pow(&one - t, n - k)
        })
    }

    fn assert_witness(p: &UPoly<BigRational>, v: &Verdict) {
        let Verdict::Unsafe(w) = v else { panic!("expected unsafe, got {v:?}") };
        let t = BigRational::from_float(w.tau).unwrap();
        assert!(p.eval(&t) <= BigRational::zero(), "witness {w:?} does not refute");
        assert!((0.0..=1.0).contains(&w.tau));
    }

    #[test]
    fn fixtures() {
        // (τ − 3/10)² touches zero: never safe; exactly undecided or unsafe
        let sq = qp(&[(9, 100), (-3, 5), (1, 1)]);
        for v in [
            check_interval(&ip(&sq), DEFAULT_MAX_DEPTH),
            check_exact(&sq, DEFAULT_MAX_DEPTH),
            check(&ip(&sq), || sq.clone()),
        ] {
            assert!(!v.is_safe(), "{v:?}");
        }
        // (τ − 1/2)² touches at a dyadic point: the exact path proves it
        let half = qp(&[(1, 4), (-1, 1), (1, 1)]);
        assert_eq!(check_exact(&half, DEFAULT_MAX_DEPTH), Verdict::Unsafe(Witness { tau: 0.5, value: 0.0 }));
        // + 1e-9: safe, margin a lower bound on the true minimum 1e-9
        let plus = sq.add(&UPoly::constant(q(1, 1_000_000_000)));
        for v in [check_interval(&ip(&plus), DEFAULT_MAX_DEPTH), check_exact(&plus, DEFAULT_MAX_DEPTH)] {
            let Verdict::Safe { margin } = v else { panic!("{v:?}") };
            assert!(margin > 0.0 && margin <= 1e-9, "{margin}");
        }
        // − 1e-12: unsafe with an exact witness
        let minus = sq.sub(&UPoly::constant(q(1, 1_000_000_000_000)));
        assert_witness(&minus, &check_interval(&ip(&minus), DEFAULT_MAX_DEPTH));
        assert_witness(&minus, &check_exact(&minus, DEFAULT_MAX_DEPTH));
        // −τ(1−τ): zero at both ends
        let ends = qp(&[(0, 1), (-1, 1), (1, 1)]);
        assert_witness(&ends, &check_interval(&ip(&ends), DEFAULT_MAX_DEPTH));
        assert_witness(&ends, &check_exact(&ends, DEFAULT_MAX_DEPTH));
    }

    #[test]
    fn constants_and_zero() {
        let zero = UPoly::<BigRational>::zero();
        let z = Verdict::Unsafe(Witness { tau: 0.0, value: 0.0 });
        assert_eq!(check_exact(&zero, 40), z);
        assert_eq!(check_interval(&ip(&zero), 40), z);
        let c = UPoly::constant(q(3, 10));
        let Verdict::Safe { margin } = check_interval(&ip(&c), 40) else { panic!() };
        assert!(margin > 0.29 && margin <= 0.3);
        assert_eq!(check_exact(&c, 0), Verdict::Safe { margin: f64_below(&q(3, 10)) });
        let neg = UPoly::constant(q(-1, 3));
        assert!(check_interval(&ip(&neg), 40).is_unsafe());
        assert!(check_exact(&neg, 40).is_unsafe());
        // an enclosure straddling 0 cannot be decided
        let straddle = UPoly::constant(Interval::new(-1e-300, 1e-300));
        assert_eq!(check_interval(&straddle, 40), Verdict::Undecided(Undecided::DepthLimit));
    }

    #[test]
    fn non_finite_is_undecided() {
        for bad in [
            Interval { lo: f64::NAN, hi: 1.0 },
            Interval::new(0.0, f64::INFINITY),
            Interval::ENTIRE,
            Interval { lo: 2.0, hi: 1.0 },
        ] {
            let p = UPoly::new(vec![Interval::point(1.0), bad]);
            assert_eq!(check_interval(&p, 40), Verdict::Undecided(Undecided::NonFinite));
        }
        // overflow in the Bernstein sums
        let p = UPoly::new(vec![Interval::point(f64::MAX); 3]);
        assert_eq!(check_interval(&p, 40), Verdict::Undecided(Undecided::NonFinite));
    }

    #[test]
    fn depth_zero_and_huge_depths() {
        let p = qp(&[(1, 1), (-2, 1), (3, 2)]); // min 1/3 at τ = 2/3
        assert!(!check_exact(&p, 0).is_safe()); // b = (1, 0, 1/2) at the root
        assert!(check_exact(&p, 1).is_safe());
        assert!(check_interval(&ip(&p), u32::MAX).is_safe());
        let sq = qp(&[(9, 100), (-3, 5), (1, 1)]);
        assert!(!check_interval(&ip(&sq), u32::MAX).is_safe());
    }

    #[test]
    fn high_degree_uses_heap_path_soundly() {
        // (τ − 1/3)^2 · (1 + τ)^38 + 1/1000: degree 40 > MAX_DEGREE
        let base = qp(&[(1, 9), (-2, 3), (1, 1)]);
        let mut p = base.clone();
        for _ in 0..38 {
            p = p.mul(&qp(&[(1, 1), (1, 1)]));
        }
        let safe = p.add(&UPoly::constant(q(1, 1000)));
        assert!(safe.degree() > MAX_DEGREE);
        assert!(check_interval(&ip(&safe), 40).is_safe());
        assert!(check_exact(&safe, 40).is_safe());
        let unsafe_ = p.sub(&UPoly::constant(q(1, 1000)));
        assert_witness(&unsafe_, &check_interval(&ip(&unsafe_), 40));
        assert_witness(&unsafe_, &check_exact(&unsafe_, 40));
    }

    #[test]
    fn check_falls_back_to_exact() {
        // 1e-300·(τ − 1/2)² + 1e-320: the interval path underflows into undecided; the
        // exact one certifies
        let tiny = BigRational::from_float(1e-300).unwrap();
        let p =
            qp(&[(1, 4), (-1, 1), (1, 1)]).scale(&tiny).add(&UPoly::constant(BigRational::from_float(1e-320).unwrap()));
        assert!(!check_interval(&ip(&p), 40).is_safe());
        let mut called = false;
        let v = check(&ip(&p), || {
            called = true;
            p.clone()
        });
        assert!(called && v.is_safe(), "{v:?}");
        // a decided interval verdict never builds the exact polynomial
        let easy = qp(&[(1, 1)]);
        assert!(check(&ip(&easy), || unreachable!()).is_safe());
    }

    #[test]
    fn f64_below_is_a_lower_bound() {
        for r in [q(1, 10), q(-1, 10), q(1, 3), q(1, 4), q(0, 1)] {
            let f = f64_below(&r);
            assert!(BigRational::from_float(f).unwrap() <= r);
            assert!(BigRational::from_float(f.next_up()).unwrap() > r);
        }
    }

    fn small_poly() -> impl Strategy<Value = UPoly<BigRational>> {
        proptest::collection::vec((-50i64..50, 1i64..12), 1..9)
            .prop_map(|c| UPoly::new(c.into_iter().map(|(n, d)| q(n, d)).collect()))
    }

    proptest! {
        /// The Bernstein form reproduces p (exact), and the interval coefficients enclose it.
        #[test]
        fn bernstein_form_is_exact(p in small_poly(), tn in 0i64..=64) {
            prop_assume!(!p.is_zero());
            let b = bernstein_coefficients(&p);
            let t = q(tn, 64);
            prop_assert_eq!(bernstein_eval(&b, &t), p.eval(&t));
            let pi = ip(&p);
            let mut bi = vec![Interval::point(0.0); b.len()];
            bernstein_interval_into(pi.coeffs(), &mut bi);
            for (e, x) in b.iter().zip(&bi) {
                prop_assert!(BigRational::from_float(x.lo).unwrap() <= *e && *e <= BigRational::from_float(x.hi).unwrap());
            }
        }

        /// Both halves of a split represent p on [0, ½] and [½, 1].
        #[test]
        fn split_halves(p in small_poly(), tn in 0i64..=64) {
            prop_assume!(!p.is_zero());
            let (b, den) = bernstein_integer(p.coeffs());
            let (l, r) = ExactNode { c: b, shift: 0, depth: 0, index: 0 }.split();
            let t = q(tn, 64);
            let as_q = |nd: &ExactNode| nd.c.iter().map(|c| BigRational::new(c.clone(), &den << nd.shift)).collect::<Vec<_>>();
            prop_assert_eq!(bernstein_eval(&as_q(&l), &t), p.eval(&(&t / q(2, 1))));
            prop_assert_eq!(bernstein_eval(&as_q(&r), &t), p.eval(&((&t + q(1, 1)) / q(2, 1))));
        }

        /// Interval and exact paths never contradict each other; witnesses refute exactly;
        /// margins are below every sampled value.
        #[test]
        fn interval_and_exact_agree(p in small_poly()) {
            let vi = check_interval(&ip(&p), DEFAULT_MAX_DEPTH);
            let ve = check_exact(&p, DEFAULT_MAX_DEPTH);
            prop_assert!(!(vi.is_safe() && ve.is_unsafe() || vi.is_unsafe() && ve.is_safe()));
            for v in [&vi, &ve] {
                match v {
                    Verdict::Unsafe(_) => assert_witness(&p, v),
                    Verdict::Safe { margin } => {
                        for k in 0..=32 {
                            prop_assert!(BigRational::from_float(*margin).unwrap() <= p.eval(&q(k, 32)));
                        }
                    }
                    Verdict::Undecided(_) => {}
                }
            }
        }
    }
}
