//! Polynomials compiled into Horner trees with outward-rounded interval coefficients (`Compiled`), and their composition with a substitution.

use super::*;

/// Coefficients of `c` restricted to a piece whose coordinates have degree ≤ `sub_degree`.
pub(crate) fn restricted_len(c: &Compiled, sub_degree: usize) -> usize {
    c.degree().saturating_mul(sub_degree.max(1)).saturating_add(1)
}

/// `c` composed with a [`Substitution`] in `f64` with a running error bound, as an
/// enclosure in the smallest stack buffer that holds it.
pub(super) fn enclosed_e(c: &Compiled, sub: &Substitution) -> Option<UPoly<Interval>> {
    fn run<const N: usize>(c: &Compiled, sub: &Substitution) -> Option<UPoly<Interval>> {
        let subs = sub.epolys::<N>()?;
        let e = c.compose_e(&subs[..sub.len()])?;
        let mut out = [ZERO; N];
        let n = e.enclosure(&mut out)?;
        Some(UPoly::new(out[..n].to_vec()))
    }
    by_capacity!(restricted_len(c, sub.degree()), run, c, sub)
}

/// A node of a Horner tree: `Σ_k coeffs[k]·v^k` with each coefficient a tree over the
/// later variables.
#[derive(Clone, Debug)]
enum Node {
    Zero,
    /// The enclosure, and the nearest float with its rounding count (0 if exact).
    Const(Interval, f64, u32),
    Horner {
        var: usize,
        coeffs: Vec<Node>,
    },
}

/// A polynomial in `n` variables compiled for repeated evaluation: a Horner tree with
/// outward-rounded interval coefficients.
#[derive(Clone, Debug)]
pub struct Compiled {
    root: Node,
    nvars: usize,
    degree: usize,
    /// Every coefficient's nearest float is exact or normal ([`round_for_model`]): the
    /// `f64` path ([`Compiled::compose_e`]) is used only then.
    in_model: bool,
    /// The largest coefficient magnitude (of the enclosures' midpoints, or nearest floats).
    max_coeff: f64,
}

/// A term as its exponent vector and coefficient.
type ExpTerm<C> = (Vec<u32>, C);

/// Builds the Horner tree of `terms` from variable `var` on; `leaf` turns the terms that
/// differ only beyond the last variable into one constant node (summing their
/// coefficients).
fn build<C>(terms: &mut [ExpTerm<C>], var: usize, nvars: usize, leaf: &mut dyn FnMut(&[ExpTerm<C>]) -> Node) -> Node {
    if terms.is_empty() {
        return Node::Zero;
    }
    if var == nvars {
        return leaf(terms);
    }
    let top = terms.iter().map(|(e, _)| e[var]).max().unwrap_or(0) as usize;
    if top == 0 {
        return build(terms, var + 1, nvars, leaf);
    }
    terms.sort_by_key(|(e, _)| e[var]);
    let mut coeffs = Vec::with_capacity(top + 1);
    let mut i = 0;
    for k in 0..=top as u32 {
        let j = i + terms[i..].iter().take_while(|(e, _)| e[var] == k).count();
        coeffs.push(build(&mut terms[i..j], var + 1, nvars, leaf));
        i = j;
    }
    Node::Horner { var, coeffs }
}

/// The exponent vectors (variables `0..nvars`) and coefficients of `p`'s terms.
fn exponent_terms<C: riskplan_math::poly::Ring>(p: &Poly<C>, nvars: usize) -> Vec<(Vec<u32>, C)> {
    p.terms()
        .map(|(m, c)| {
            let mut e = vec![0u32; nvars];
            for &(v, k) in m.pairs() {
                if (v as usize) < nvars {
                    e[v as usize] = k;
                }
            }
            (e, c.clone())
        })
        .collect()
}

impl Compiled {
    /// Compiles `p` (variables `0..nvars`; any other variable must not occur) with
    /// every coefficient enclosed.
    pub fn new(p: &QPoly, nvars: usize) -> Self {
        let mut terms = exponent_terms(p, nvars);
        let degree = terms.iter().map(|(e, _)| e.iter().sum::<u32>() as usize).max().unwrap_or(0);
        let mut in_model = true;
        let root = build(&mut terms, 0, nvars, &mut |ts: &[(Vec<u32>, BigRational)]| {
            let mut acc = BigRational::zero();
            for (_, c) in ts {
                acc += c;
            }
            let (near, k) = round_for_model(&acc).unwrap_or_else(|| {
                in_model = false;
                (riskplan_math::poly::rational_to_f64(&acc), 1)
            });
            Node::Const(Interval::enclose_rational(&acc), near, k)
        });
        let max_coeff = max_const(&root);
        Compiled { root, nvars, degree, in_model, max_coeff }
    }

    /// Compiles a polynomial whose coefficients are enclosures already (the central
    /// moments of §3.8): usable with [`Compiled::compose`] only (interval arithmetic;
    /// the `f64` model path [`Compiled::compose_e`] refuses it).
    pub fn from_intervals(p: &Poly<Interval>, nvars: usize) -> Self {
        let mut terms = exponent_terms(p, nvars);
        let degree = terms.iter().map(|(e, _)| e.iter().sum::<u32>() as usize).max().unwrap_or(0);
        let root = build(&mut terms, 0, nvars, &mut |ts: &[(Vec<u32>, Interval)]| {
            let acc = ts.iter().fold(ZERO, |acc, (_, c)| acc + *c);
            Node::Const(acc, acc.mid(), 1)
        });
        let max_coeff = max_const(&root);
        Compiled { root, nvars, degree, in_model: false, max_coeff }
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
    /// (`subs[v]`), enclosed; `None` when a degree would reach the capacity `N`.
    pub fn compose<const N: usize>(&self, subs: &[FPoly<N>]) -> Option<FPoly<N>> {
        fn go<const N: usize>(n: &Node, subs: &[FPoly<N>]) -> Option<FPoly<N>> {
            match n {
                Node::Zero => Some(FPoly::zero()),
                Node::Const(c, _, _) => Some(FPoly::constant(*c)),
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

    /// [`Compiled::compose`] for a polynomial with interval coefficients
    /// ([`Compiled::from_intervals`]) in `f64` with midpoints, radii and a running error
    /// bound ([`RPoly`]): the enclosure of every restriction of a polynomial within the
    /// coefficients' intervals; `None` beyond the capacity or outside the model's range
    /// (the caller composes in interval arithmetic then).
    pub fn compose_r<const N: usize>(&self, subs: &[EPoly<N>]) -> Option<FPoly<N>> {
        if self.max_coeff.is_nan() || self.max_coeff < RPOLY_MIN_SCALE {
            return None;
        }
        fn go<const N: usize>(n: &Node, subs: &[RPoly<N>]) -> Option<RPoly<N>> {
            match n {
                Node::Zero => Some(RPoly::zero()),
                Node::Const(c, _, _) => RPoly::interval(*c),
                Node::Horner { var, coeffs } => {
                    let mut acc = go(&coeffs[coeffs.len() - 1], subs)?;
                    for c in coeffs[..coeffs.len() - 1].iter().rev() {
                        acc = acc.mul_sub(&subs[*var])?;
                        if !matches!(c, Node::Zero) {
                            acc = acc.add(&go(c, subs)?);
                        }
                    }
                    Some(acc)
                }
            }
        }
        let rs: Vec<RPoly<N>> = subs.iter().map(RPoly::from_sub).collect();
        let p = go(&self.root, &rs)?;
        let mut out = FPoly::<N>::zero();
        out.len = p.enclosure(&mut out.c)?;
        Some(out)
    }

    /// [`Compiled::compose`] in `f64` with a running error bound ([`EPoly`]); `None`
    /// beyond the capacity or outside the model's range (a coefficient, or a product
    /// on the way, that would underflow).
    pub fn compose_e<const N: usize>(&self, subs: &[EPoly<N>]) -> Option<EPoly<N>> {
        if !self.in_model {
            return None;
        }
        // in place: the polynomials are small and their arrays large, so copies, not
        // arithmetic, would dominate (a node's value goes to `out`)
        fn go<const N: usize>(n: &Node, subs: &[EPoly<N>], out: &mut EPoly<N>) -> Option<()> {
            match n {
                Node::Zero => {
                    out.len = 0;
                    out.k = 0;
                }
                Node::Const(_, f, k) => {
                    out.v[0] = *f;
                    out.a[0] = f.abs();
                    out.len = 1;
                    out.k = *k;
                }
                Node::Horner { var, coeffs } => {
                    go(&coeffs[coeffs.len() - 1], subs, out)?;
                    let mut term = EPoly::zero();
                    for c in coeffs[..coeffs.len() - 1].iter().rev() {
                        out.mul_assign(&subs[*var])?;
                        if !matches!(c, Node::Zero) {
                            go(c, subs, &mut term)?;
                            out.add_assign_signed(&term, 1.0);
                        }
                    }
                }
            }
            Some(())
        }
        let mut out = EPoly::zero();
        go(&self.root, subs, &mut out)?;
        Some(out)
    }

    /// The value at `vals` in plain floating point from the coefficients' nearest floats
    /// (an estimate, for choices; never for proofs).
    pub fn eval_f64(&self, vals: &[f64]) -> f64 {
        horner(&self.root, vals, 0.0, &|c| match c {
            Node::Const(_, f, _) => *f,
            _ => 0.0,
        })
    }

    /// An enclosure of the polynomial's range over the box `vals` (naive interval
    /// Horner evaluation).
    pub fn eval_box(&self, vals: &[Interval]) -> Interval {
        horner(&self.root, vals, ZERO, &|c| match c {
            Node::Const(i, _, _) => *i,
            _ => ZERO,
        })
    }
}

/// Horner evaluation of a tree at `vals`: `leaf` gives a constant node's value (`zero` for
/// an empty subtree).
fn horner<T>(n: &Node, vals: &[T], zero: T, leaf: &dyn Fn(&Node) -> T) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    match n {
        Node::Zero => zero,
        Node::Const(..) => leaf(n),
        Node::Horner { var, coeffs } => {
            let x = vals[*var];
            let mut acc = horner(&coeffs[coeffs.len() - 1], vals, zero, leaf);
            for c in coeffs[..coeffs.len() - 1].iter().rev() {
                acc = acc * x + horner(c, vals, zero, leaf);
            }
            acc
        }
    }
}

/// The largest magnitude among a tree's constants (nearest floats).
fn max_const(n: &Node) -> f64 {
    match n {
        Node::Zero => 0.0,
        Node::Const(_, f, _) => f.abs(),
        Node::Horner { coeffs, .. } => coeffs.iter().map(max_const).fold(0.0, f64::max),
    }
}

/// `p(c + 2^e·z)`: the polynomial in the compiled variables of `frame`, exactly.
pub fn to_frame(p: &QPoly, frame: &Frame) -> QPoly {
    let two = BigRational::from_integer(2.into());
    let maps: Vec<Option<(BigRational, BigRational)>> = frame
        .center
        .iter()
        .zip(&frame.exponents)
        .map(|(&c, &e)| {
            let c = BigRational::from_float(c).unwrap_or_default();
            let l: BigRational = num_traits::Pow::pow(&two, e);
            (!(c.is_zero() && l.is_one())).then_some((c, l))
        })
        .collect();
    riskplan_math::poly::affine_subst(p, &maps)
}

/// `∂p/∂x_v`, exactly.
pub fn derivative(p: &QPoly, v: usize) -> QPoly {
    let mut out = QPoly::zero();
    for (m, c) in p.terms() {
        let e = m.exp(v as riskplan_math::poly::Var);
        if e == 0 {
            continue;
        }
        let pairs = m.pairs().iter().map(|&(w, k)| if w as usize == v { (w, k - 1) } else { (w, k) });
        out.add_term(riskplan_math::poly::Monomial::from_pairs(pairs), c * BigRational::from_integer(e.into()));
    }
    out
}
