//! The compiled restriction: contour polynomials prepared once per obstacle so that
//! restricting them to a trajectory piece allocates nothing (docs/design.md §5.1, §5.6).
//!
//! [`super::restrict_interval`] composes the contour polynomials with a piece through
//! general polynomial objects, a heap allocation per product; for a planner's edge
//! that bookkeeping costs far more than the positivity proof itself. Here E[P] and
//! E[P²] are compiled once into a Horner tree ([`Compiled`]) over **centred**
//! variables `y = x − c`, `s = t − t_c`, and a piece's coordinates are substituted as
//! fixed-capacity univariate interval polynomials ([`FPoly`]), on the stack.
//!
//! Soundness is the same as the interval restriction's: the compiled coefficients are
//! outward-rounded enclosures of the *exact* centred polynomial (the shift is done in
//! rationals), every operation is outward rounded, so the resulting coefficients
//! enclose those of the exact restriction `e1(τ)`, `e2(τ)` of eq. (15). Centring
//! matters off the paper's unit scenes: a workspace at x ≈ 1000 makes the monomials of
//! the uncentred polynomial cancel by many orders of magnitude, and the enclosures
//! lose as many digits; in centred variables the coefficients stay at the scale of the
//! obstacle.

use super::bernstein::MAX_DEGREE;
use super::compose::PieceRef;
use crate::contour::RiskContour;
use crate::poly::{Interval, Poly, QPoly};
use num_rational::BigRational;
use num_traits::Zero;

/// Capacity of an [`FPoly`]: the Bernstein checker's stack-buffer degree plus one.
/// A restriction of higher degree is not compiled ([`Compiled::restrict`] returns
/// `None`) and the caller falls back to the general path.
pub const CAPACITY: usize = MAX_DEGREE + 1;

/// A univariate polynomial in τ with interval coefficients, of degree < [`CAPACITY`],
/// stored inline (no heap).
#[derive(Clone, Copy, Debug)]
pub struct FPoly {
    c: [Interval; CAPACITY],
    len: usize,
}

const ZERO: Interval = Interval { lo: 0.0, hi: 0.0 };

impl FPoly {
    /// The zero polynomial.
    pub fn zero() -> Self {
        FPoly { c: [ZERO; CAPACITY], len: 0 }
    }
    /// A constant.
    pub fn constant(v: Interval) -> Self {
        let mut p = Self::zero();
        p.c[0] = v;
        p.len = 1;
        p
    }
    /// `a + b·τ`.
    pub fn linear(a: Interval, b: Interval) -> Self {
        let mut p = Self::constant(a);
        p.c[1] = b;
        p.len = 2;
        p
    }
    /// Coefficients of `τ^0, τ^1, …` (no trailing zeros are removed).
    pub fn coeffs(&self) -> &[Interval] {
        &self.c[..self.len]
    }
    /// `self += o`.
    pub fn add_assign(&mut self, o: &FPoly) {
        for k in 0..o.len {
            self.c[k] = if k < self.len { self.c[k] + o.c[k] } else { o.c[k] };
        }
        self.len = self.len.max(o.len);
    }
    /// `self − o`.
    pub fn sub(&self, o: &FPoly) -> FPoly {
        let mut r = *self;
        r.add_assign(&o.neg());
        r
    }
    /// `−self`.
    pub fn neg(&self) -> FPoly {
        let mut r = *self;
        for v in &mut r.c[..r.len] {
            *v = -*v;
        }
        r
    }
    /// `s·self`.
    pub fn scale(&self, s: Interval) -> FPoly {
        let mut r = *self;
        for v in &mut r.c[..r.len] {
            *v = *v * s;
        }
        r
    }
    /// `self·o`, or `None` when the degree would reach [`CAPACITY`].
    pub fn mul(&self, o: &FPoly) -> Option<FPoly> {
        if self.len == 0 || o.len == 0 {
            return Some(FPoly::zero());
        }
        let len = self.len + o.len - 1;
        if len > CAPACITY {
            return None;
        }
        let mut r = FPoly { c: [ZERO; CAPACITY], len };
        for i in 0..self.len {
            let a = self.c[i];
            for j in 0..o.len {
                r.c[i + j] = r.c[i + j] + a * o.c[j];
            }
        }
        Some(r)
    }
    /// Degree (`len − 1`; 0 for the zero polynomial).
    pub fn degree(&self) -> usize {
        self.len.saturating_sub(1)
    }
}

/// A node of a Horner tree: `Σ_k coeffs[k]·v^k` with each coefficient a tree over the
/// later variables.
#[derive(Clone, Debug)]
enum Node {
    Zero,
    Const(Interval),
    Horner { var: usize, coeffs: Vec<Node> },
}

/// A polynomial in `n` variables compiled for repeated evaluation: a Horner tree with
/// outward-rounded interval coefficients.
#[derive(Clone, Debug)]
pub struct Compiled {
    root: Node,
    nvars: usize,
    degree: usize,
}

fn build(terms: &mut [(Vec<u32>, Interval)], var: usize, nvars: usize) -> Node {
    if terms.is_empty() {
        return Node::Zero;
    }
    if var == nvars {
        let mut acc = ZERO;
        for (_, c) in terms.iter() {
            acc = acc + *c;
        }
        return Node::Const(acc);
    }
    let top = terms.iter().map(|(e, _)| e[var]).max().unwrap_or(0) as usize;
    if top == 0 {
        return build(terms, var + 1, nvars);
    }
    terms.sort_by_key(|(e, _)| e[var]);
    let mut coeffs = Vec::with_capacity(top + 1);
    let mut i = 0;
    for k in 0..=top as u32 {
        let j = i + terms[i..].iter().take_while(|(e, _)| e[var] == k).count();
        coeffs.push(build(&mut terms[i..j], var + 1, nvars));
        i = j;
    }
    Node::Horner { var, coeffs }
}

impl Compiled {
    /// Compiles `p` (variables `0..nvars`; any other variable must not occur) with
    /// every coefficient enclosed.
    pub fn new(p: &QPoly, nvars: usize) -> Self {
        let mut terms: Vec<(Vec<u32>, Interval)> = p
            .terms()
            .map(|(m, c)| {
                let mut e = vec![0u32; nvars];
                for &(v, k) in m.pairs() {
                    if (v as usize) < nvars {
                        e[v as usize] = k;
                    }
                }
                (e, Interval::enclose_rational(c))
            })
            .collect();
        let degree = terms.iter().map(|(e, _)| e.iter().sum::<u32>() as usize).max().unwrap_or(0);
        Compiled { root: build(&mut terms, 0, nvars), nvars, degree }
    }

    /// Total degree.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Number of variables.
    pub fn nvars(&self) -> usize {
        self.nvars
    }

    /// The polynomial with every variable replaced by a univariate polynomial in τ
    /// (`subs[v]`), enclosed; `None` when a degree would reach [`CAPACITY`].
    pub fn compose(&self, subs: &[FPoly]) -> Option<FPoly> {
        fn go(n: &Node, subs: &[FPoly]) -> Option<FPoly> {
            match n {
                Node::Zero => Some(FPoly::zero()),
                Node::Const(c) => Some(FPoly::constant(*c)),
                Node::Horner { var, coeffs } => {
                    let mut acc = go(&coeffs[coeffs.len() - 1], subs)?;
                    for c in coeffs[..coeffs.len() - 1].iter().rev() {
                        acc = acc.mul(&subs[*var])?;
                        if !matches!(c, Node::Zero) {
                            acc.add_assign(&go(c, subs)?);
                        }
                    }
                    Some(acc)
                }
            }
        }
        go(&self.root, subs)
    }

    /// An enclosure of the polynomial's range over the box `vals` (naive interval
    /// Horner evaluation).
    pub fn eval_box(&self, vals: &[Interval]) -> Interval {
        fn go(n: &Node, vals: &[Interval]) -> Interval {
            match n {
                Node::Zero => ZERO,
                Node::Const(c) => *c,
                Node::Horner { var, coeffs } => {
                    let x = vals[*var];
                    let mut acc = go(&coeffs[coeffs.len() - 1], vals);
                    for c in coeffs[..coeffs.len() - 1].iter().rev() {
                        acc = acc * x + go(c, vals);
                    }
                    acc
                }
            }
        }
        go(&self.root, vals)
    }
}

/// `p(x + c)`: the polynomial in centred variables, exactly (`c[v]` for variables
/// `0..c.len()`).
pub fn shift(p: &QPoly, c: &[f64]) -> QPoly {
    let cs: Vec<BigRational> = c.iter().map(|&v| BigRational::from_float(v).unwrap_or_default()).collect();
    p.subst(&|v| {
        let v_ = v as usize;
        (v_ < cs.len() && !cs[v_].is_zero()).then(|| Poly::var(v).add(&Poly::constant(cs[v_].clone())))
    })
}

/// `∂p/∂x_v`, exactly.
pub fn derivative(p: &QPoly, v: usize) -> QPoly {
    let mut out = QPoly::zero();
    for (m, c) in p.terms() {
        let e = m.exp(v as crate::poly::Var);
        if e == 0 {
            continue;
        }
        let pairs = m.pairs().iter().map(|&(w, k)| if w as usize == v { (w, k - 1) } else { (w, k) });
        out.add_term(crate::poly::Monomial::from_pairs(pairs), c * BigRational::from_integer(e.into()));
    }
    out
}

/// One obstacle's E[P] and E[P²], compiled in centred variables
/// `(y_1..y_n, s) = (x − c, t − t_c)`.
#[derive(Clone, Debug)]
pub struct CompiledContour {
    /// The centre `(c_1..c_n, t_c)`: floats, used exactly.
    pub center: Vec<f64>,
    mean: Compiled,
    second: Compiled,
}

/// The two restricted moment polynomials of one obstacle on one piece.
#[derive(Clone, Copy, Debug)]
pub struct FastRestriction {
    /// `e1(τ) = E[P](x(t(τ)), t(τ))`.
    pub mean: FPoly,
    /// `e2(τ) = E[P²](…)`.
    pub second: FPoly,
}

impl FastRestriction {
    /// `g1 = e1² − (1−Δ)·e2` (Cantelli) and `g2 = −e1` (mean), for `1−Δ` enclosed in
    /// `one_minus_delta`; `None` when `e1²` exceeds the capacity.
    pub fn constraints(&self, one_minus_delta: Interval) -> Option<(FPoly, FPoly)> {
        let sq = self.mean.mul(&self.mean)?;
        Some((sq.sub(&self.second.scale(one_minus_delta)), self.mean.neg()))
    }
}

impl CompiledContour {
    /// Compiles a contour around `center` (`dim + 1` floats: space, then time).
    pub fn new(contour: &RiskContour, center: &[f64]) -> Self {
        let nv = contour.layout().xt_len();
        debug_assert_eq!(center.len(), nv);
        CompiledContour {
            center: center.to_vec(),
            mean: Compiled::new(&shift(&contour.mean, center), nv),
            second: Compiled::new(&shift(&contour.second, center), nv),
        }
    }

    /// The centred coordinates of a piece as polynomials in τ ∈ [0, 1]:
    /// `y_d(τ) = x_d(t0 + hτ) − c_d`, `s(τ) = t0 + hτ − t_c`. `None` when a piece's
    /// degree exceeds the capacity.
    pub fn substitutions(&self, piece: PieceRef<'_>) -> Option<[FPoly; 9]> {
        let nv = self.center.len();
        if nv > 9 {
            return None;
        }
        let t0 = Interval::point(piece.t0);
        let h = Interval::point(piece.t1) - t0;
        let lin = FPoly::linear(t0, h);
        let mut subs = [FPoly::zero(); 9];
        for (d, sub) in subs.iter_mut().enumerate().take(nv - 1) {
            let row: &[f64] = piece.coeffs.get(d).map(|r| r.as_slice()).unwrap_or(&[]);
            let mut acc = FPoly::zero();
            for &c in row.iter().rev() {
                acc = acc.mul(&lin)?;
                acc.add_assign(&FPoly::constant(Interval::point(c)));
            }
            acc.add_assign(&FPoly::constant(Interval::point(-self.center[d])));
            *sub = acc;
        }
        subs[nv - 1] = FPoly::linear(t0 - Interval::point(self.center[nv - 1]), h);
        Some(subs)
    }

    /// E[P] and E[P²] restricted to a piece, enclosed; `None` beyond the capacity.
    pub fn restrict(&self, piece: PieceRef<'_>) -> Option<FastRestriction> {
        let subs = self.substitutions(piece)?;
        let subs = &subs[..self.center.len()];
        Some(FastRestriction { mean: self.mean.compose(subs)?, second: self.second.compose(subs)? })
    }

    /// The degree in τ of `E[P²]` restricted to a piece of degree `k` in t (an upper
    /// bound: total degree times k).
    pub fn restricted_degree(&self, piece_degree: usize) -> usize {
        self.second.degree().max(2 * self.mean.degree()) * piece_degree.max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::certify::compose::restrict_exact;
    use crate::contour::Layout;
    use crate::poly::{parse, VarTable};
    use proptest::prelude::*;

    fn contour(text: &str, dim: usize) -> RiskContour {
        let mut names: Vec<String> = (1..=dim).map(|i| format!("x{i}")).collect();
        names.push("t".into());
        names.push("w".into());
        let vars = VarTable::new(names);
        let p = parse(text, &mut |n: &str| vars.get(n).ok_or_else(|| n.to_string())).unwrap();
        // w uniform on [0.3, 0.4]: raw moments (b^{k+1} − a^{k+1}) / ((k+1)(b − a))
        let m = |k: u32| {
            let (a, b) = (BigRational::new(3.into(), 10.into()), BigRational::new(4.into(), 10.into()));
            let p1 = |x: &BigRational| num_traits::pow(x.clone(), k as usize + 1);
            (p1(&b) - p1(&a)) / (BigRational::from_integer((k + 1).into()) * (b - a))
        };
        RiskContour::new(Layout { dim }, &p, &|_, k| Some(m(k)), &|v| vars.name(v)).unwrap()
    }

    fn encloses(i: &[Interval], e: &crate::poly::UPoly<BigRational>) -> Result<(), String> {
        for k in 0..=e.degree().max(i.len().saturating_sub(1)) {
            let v = e.coeff(k);
            let b = i.get(k).copied().unwrap_or(ZERO);
            let (lo, hi) = (BigRational::from_float(b.lo).unwrap(), BigRational::from_float(b.hi).unwrap());
            if !(lo <= v && v <= hi) {
                return Err(format!("coefficient {k}: {v} not in {b:?}"));
            }
        }
        Ok(())
    }

    proptest! {
        /// The compiled restriction encloses the exact one (computed in rationals by a
        /// different code path: no centring, general polynomial composition), for moving
        /// and static obstacles, curved pieces, far-off centres and shifted times.
        #[test]
        fn compiled_restriction_encloses_the_exact_one(
            cx in -1e3f64..1e3, cy in -1e3f64..1e3, tc in -50f64..50.0,
            a in prop::collection::vec(-2f64..2.0, 3), b in prop::collection::vec(-2f64..2.0, 3),
            t0 in -20f64..20.0, h in 1e-3f64..10.0, moving in any::<bool>(),
        ) {
            let text = if moving {
                format!("w^2 - (x1 - {cx} - 0.1*t)^2 - (x2 - {cy} + 0.05*t^2)^2")
            } else {
                format!("w^2*(1 - x1 + x2) - (x1 - {cx})^4 - (x2 - {cy})^2")
            };
            let c = contour(&text, 2);
            let center = [cx + 0.3, cy - 0.2, tc];
            let cc = CompiledContour::new(&c, &center);
            let coeffs = vec![vec![cx + a[0], a[1], a[2] * 0.1], vec![cy + b[0], b[1]]];
            let piece = PieceRef { t0, t1: t0 + h, coeffs: &coeffs };
            let delta = BigRational::new(1.into(), 20.into());
            let exact = restrict_exact(&c, piece, &delta);
            let fast = cc.restrict(piece).unwrap();
            let (g1, g2) = fast.constraints(Interval::enclose_rational(&(BigRational::from_integer(1.into()) - &delta))).unwrap();
            prop_assert!(encloses(g1.coeffs(), &exact.cantelli).is_ok(), "{:?}", encloses(g1.coeffs(), &exact.cantelli));
            prop_assert!(encloses(g2.coeffs(), &exact.mean).is_ok(), "{:?}", encloses(g2.coeffs(), &exact.mean));
        }
    }

    /// Centring keeps the enclosures tight far from the origin: at x ≈ 1000 the
    /// uncentred restriction's coefficients are orders of magnitude wider.
    #[test]
    fn centring_keeps_enclosures_tight_far_from_the_origin() {
        let c = contour("w^2 - (x1 - 1000)^2 - (x2 + 500)^2", 2);
        let coeffs = vec![vec![999.0, 0.5], vec![-501.0, 0.25]];
        let piece = PieceRef { t0: 10.0, t1: 11.0, coeffs: &coeffs };
        let delta = BigRational::new(1.into(), 20.into());
        let omd = Interval::enclose_rational(&(BigRational::from_integer(1.into()) - &delta));
        let width = |p: &FPoly| p.coeffs().iter().map(|i| i.width()).fold(0.0, f64::max);
        let centred = CompiledContour::new(&c, &[1000.0, -500.0, 10.0]).restrict(piece).unwrap();
        let origin = CompiledContour::new(&c, &[0.0, 0.0, 0.0]).restrict(piece).unwrap();
        let (g_c, _) = centred.constraints(omd).unwrap();
        let (g_o, _) = origin.constraints(omd).unwrap();
        assert!(width(&g_c) < 1e-8, "{}", width(&g_c));
        assert!(width(&g_o) > 1e3 * width(&g_c), "{} vs {}", width(&g_o), width(&g_c));
    }

    #[test]
    fn box_evaluation_encloses_point_values_and_derivatives_are_exact() {
        let c = contour("w^2 - (x1 - t)^2 - x2^2", 2);
        let cc = Compiled::new(&c.mean, 3);
        let v = cc.eval_box(&[Interval::new(0.1, 0.2), Interval::new(-0.1, 0.3), Interval::new(0.0, 0.5)]);
        for &(x, y, t) in &[(0.1, -0.1, 0.0), (0.2, 0.3, 0.5), (0.15, 0.0, 0.25)] {
            let (m, _) = c.moments_f64(&[x, y, t]);
            assert!(v.lo <= m && m <= v.hi);
        }
        let d = derivative(&c.mean, 0); // ∂/∂x1 of E[w²] − (x1 − t)² − x2² = −2(x1 − t)
        let q = |v: i64| BigRational::from_integer(v.into());
        assert_eq!(d.eval(&[q(3), q(0), q(1), q(0)]), q(-4));
    }
}
