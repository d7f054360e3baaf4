//! Sparse multivariate polynomials in indexed variables (layer L0).
//!
//! A [`Poly`] maps [`Monomial`]s to coefficients of a [`Ring`]. Variables are small
//! integers ([`Var`]); names live in a [`VarTable`] owned by whoever parses the text
//! (a scene numbers them `x1..xn, t, ω1..ωp`, docs/design.md §1.2).
//!
//! Operations: `+ - *`, powers, substitution of a variable by a polynomial
//! (composition), evaluation, degree per variable, the expectation operator E[·]
//! over independent parameters (§2.3), and printing that [`parse`] reads back.

mod affine;
pub mod dyadic;
mod expect;
mod interval;
#[cfg(test)]
mod oracle_tests;
mod parse;
mod ring;
mod taylor;
mod univariate;

pub use affine::{affine_subst, square_minus_scaled};
pub use expect::mean_and_second_moment;
pub use interval::Interval;
pub use parse::{
    parse, parse_with_budget, product_cost, PolyError, VarResolver, MAX_EXPONENT, MAX_NESTING, MAX_PARSE_DEGREE,
    MAX_PARSE_TERMS, MAX_PARSE_WORK,
};
pub use ring::{
    cmp_float_rational, f64_shortest_decimal, f64_to_rational, float_within_rounding, parse_decimal, parse_num_text,
    rational_to_f64, Ring, MAX_DECIMAL_DIGITS, MAX_DECIMAL_EXPONENT,
};
pub use taylor::taylor_shift;
pub use univariate::UPoly;

use num_rational::BigRational;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

/// A variable: an index into a [`VarTable`].
pub type Var = u16;

/// A monomial `Π v^e`: sorted by variable, every exponent `> 0`. The empty monomial is 1.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Monomial(Vec<(Var, u32)>);

impl Monomial {
    /// The monomial 1.
    pub fn one() -> Self {
        Monomial(Vec::new())
    }

    /// `v^e` (1 when `e == 0`).
    pub fn var_pow(v: Var, e: u32) -> Self {
        if e == 0 {
            Self::one()
        } else {
            Monomial(vec![(v, e)])
        }
    }

    /// Builds from `(var, exp)` pairs in any order; repeated variables add up.
    pub fn from_pairs(pairs: impl IntoIterator<Item = (Var, u32)>) -> Self {
        let mut m: BTreeMap<Var, u32> = BTreeMap::new();
        for (v, e) in pairs {
            *m.entry(v).or_insert(0) += e;
        }
        Monomial(m.into_iter().filter(|&(_, e)| e > 0).collect())
    }

    /// The `(var, exponent)` pairs, sorted by variable.
    pub fn pairs(&self) -> &[(Var, u32)] {
        &self.0
    }

    /// Total degree.
    pub fn degree(&self) -> u32 {
        self.0.iter().map(|&(_, e)| e).sum()
    }

    /// Exponent of `v`.
    pub fn exp(&self, v: Var) -> u32 {
        self.0.iter().find(|&&(w, _)| w == v).map_or(0, |&(_, e)| e)
    }

    /// Product of two monomials.
    pub fn mul(&self, o: &Monomial) -> Monomial {
        let (a, b) = (&self.0, &o.0);
        let mut out = Vec::with_capacity(a.len() + b.len());
        let (mut i, mut j) = (0, 0);
        while i < a.len() && j < b.len() {
            match a[i].0.cmp(&b[j].0) {
                std::cmp::Ordering::Less => {
                    out.push(a[i]);
                    i += 1;
                }
                std::cmp::Ordering::Greater => {
                    out.push(b[j]);
                    j += 1;
                }
                std::cmp::Ordering::Equal => {
                    out.push((a[i].0, a[i].1 + b[j].1));
                    i += 1;
                    j += 1;
                }
            }
        }
        out.extend_from_slice(&a[i..]);
        out.extend_from_slice(&b[j..]);
        Monomial(out)
    }

    /// Lexicographic order on dense exponent vectors (`x1 > x2 > ...`): the first
    /// variable whose exponents differ decides, the larger exponent being greater.
    pub fn lex_cmp(&self, o: &Monomial) -> std::cmp::Ordering {
        let (a, b) = (&self.0, &o.0);
        let mut i = 0;
        while i < a.len() && i < b.len() {
            let (va, ea) = a[i];
            let (vb, eb) = b[i];
            if va != vb {
                // the monomial holding the smaller variable has a positive exponent
                // where the other has 0
                return if va < vb { std::cmp::Ordering::Greater } else { std::cmp::Ordering::Less };
            }
            if ea != eb {
                return ea.cmp(&eb);
            }
            i += 1;
        }
        a.len().cmp(&b.len())
    }

    /// Splits into (the part whose variables satisfy `pred`, the rest).
    pub fn split(&self, pred: impl Fn(Var) -> bool) -> (Monomial, Monomial) {
        let (a, b): (Vec<_>, Vec<_>) = self.0.iter().partition(|&&(v, _)| pred(v));
        (Monomial(a), Monomial(b))
    }
}

/// A sparse polynomial with coefficients in `C`. No stored coefficient is zero.
#[derive(Clone, Debug, PartialEq)]
pub struct Poly<C> {
    terms: BTreeMap<Monomial, C>,
}

impl<C: Ring> Default for Poly<C> {
    fn default() -> Self {
        Self::zero()
    }
}

impl<C: Ring> Poly<C> {
    /// The zero polynomial.
    pub fn zero() -> Self {
        Poly { terms: BTreeMap::new() }
    }

    /// A constant.
    pub fn constant(c: C) -> Self {
        Self::monomial(Monomial::one(), c)
    }

    /// The polynomial `v`.
    pub fn var(v: Var) -> Self {
        Self::monomial(Monomial::var_pow(v, 1), C::one())
    }

    /// `c * m`.
    pub fn monomial(m: Monomial, c: C) -> Self {
        let mut p = Self::zero();
        p.add_term(m, c);
        p
    }

    /// Adds `c * m` in place.
    pub fn add_term(&mut self, m: Monomial, c: C) {
        if c.is_zero() {
            return;
        }
        match self.terms.entry(m) {
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert(c);
            }
            std::collections::btree_map::Entry::Occupied(mut e) => {
                let s = e.get().radd(&c);
                if s.is_zero() {
                    e.remove();
                } else {
                    *e.get_mut() = s;
                }
            }
        }
    }

    /// The terms, in monomial order.
    pub fn terms(&self) -> impl Iterator<Item = (&Monomial, &C)> {
        self.terms.iter()
    }

    /// Number of nonzero terms.
    #[allow(clippy::len_without_is_empty)] // `is_zero` is the polynomial's emptiness test
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Whether this is the zero polynomial.
    pub fn is_zero(&self) -> bool {
        self.terms.is_empty()
    }

    /// The coefficient of `m` (zero if absent).
    pub fn coeff(&self, m: &Monomial) -> C {
        self.terms.get(m).cloned().unwrap_or_else(C::zero)
    }

    /// The constant term.
    pub fn constant_term(&self) -> C {
        self.coeff(&Monomial::one())
    }

    /// `self + o`.
    pub fn add(&self, o: &Self) -> Self {
        let mut r = self.clone();
        for (m, c) in &o.terms {
            r.add_term(m.clone(), c.clone());
        }
        r
    }

    /// `self - o`.
    pub fn sub(&self, o: &Self) -> Self {
        let mut r = self.clone();
        for (m, c) in &o.terms {
            r.add_term(m.clone(), c.rneg());
        }
        r
    }

    /// `-self`.
    pub fn neg(&self) -> Self {
        self.map_coeffs(|c| c.rneg())
    }

    /// `c * self`.
    pub fn scale(&self, c: &C) -> Self {
        let mut r = Self::zero();
        for (m, a) in &self.terms {
            r.add_term(m.clone(), a.rmul(c));
        }
        r
    }

    /// `self * o`.
    pub fn mul(&self, o: &Self) -> Self {
        let mut r = Self::zero();
        for (m1, c1) in &self.terms {
            for (m2, c2) in &o.terms {
                r.add_term(m1.mul(m2), c1.rmul(c2));
            }
        }
        r
    }

    /// `self^k`.
    pub fn pow(&self, mut k: u32) -> Self {
        let mut base = self.clone();
        let mut acc = Self::constant(C::one());
        while k > 0 {
            if k & 1 == 1 {
                acc = acc.mul(&base);
            }
            k >>= 1;
            if k > 0 {
                base = base.mul(&base);
            }
        }
        acc
    }

    /// Applies `f` to every coefficient (zero results are dropped).
    pub fn map_coeffs<D: Ring>(&self, f: impl Fn(&C) -> D) -> Poly<D> {
        let mut r = Poly::zero();
        for (m, c) in &self.terms {
            r.add_term(m.clone(), f(c));
        }
        r
    }

    /// Total degree (0 for the zero polynomial).
    pub fn degree(&self) -> u32 {
        self.terms.keys().map(Monomial::degree).max().unwrap_or(0)
    }

    /// Degree in one variable.
    pub fn degree_in(&self, v: Var) -> u32 {
        self.terms.keys().map(|m| m.exp(v)).max().unwrap_or(0)
    }

    /// Largest total degree counting only the variables that satisfy `pred`.
    pub fn degree_in_vars(&self, pred: impl Fn(Var) -> bool) -> u32 {
        self.terms.keys().map(|m| m.pairs().iter().filter(|&&(v, _)| pred(v)).map(|&(_, e)| e).sum()).max().unwrap_or(0)
    }

    /// Raises `tops[v]` to the largest exponent of each variable `v` in `self` (over several
    /// polynomials, one call each).
    pub fn max_exponents_into(&self, tops: &mut BTreeMap<Var, u32>) {
        for m in self.terms.keys() {
            for &(v, e) in m.pairs() {
                let t = tops.entry(v).or_insert(0);
                *t = (*t).max(e);
            }
        }
    }

    /// The variables that occur.
    pub fn vars(&self) -> BTreeSet<Var> {
        self.terms.keys().flat_map(|m| m.pairs().iter().map(|&(v, _)| v)).collect()
    }

    /// Whether `v` occurs.
    pub fn contains_var(&self, v: Var) -> bool {
        self.terms.keys().any(|m| m.exp(v) > 0)
    }

    /// Value at a point; `vals[v]` is the value of variable `v`.
    ///
    /// # Panics
    /// If a variable that occurs has no entry in `vals` (a caller bug, not input).
    pub fn eval(&self, vals: &[C]) -> C {
        let mut acc = C::zero();
        for (m, c) in &self.terms {
            let mut t = c.clone();
            for &(v, e) in m.pairs() {
                t = t.rmul(&vals[v as usize].rpow(e));
            }
            acc = acc.radd(&t);
        }
        acc
    }

    /// Substitutes the variables for which `sub` returns a polynomial (composition);
    /// the other variables stay.
    pub fn subst(&self, sub: &dyn Fn(Var) -> Option<Poly<C>>) -> Self {
        let mut cache: BTreeMap<(Var, u32), Poly<C>> = BTreeMap::new();
        let mut r = Self::zero();
        for (m, c) in &self.terms {
            let mut term = Self::constant(c.clone());
            let mut kept = Vec::new();
            for &(v, e) in m.pairs() {
                match sub(v) {
                    Some(p) => {
                        let pe = cache.entry((v, e)).or_insert_with(|| p.pow(e));
                        term = term.mul(pe);
                    }
                    None => kept.push((v, e)),
                }
            }
            let km = Monomial(kept);
            for (m2, c2) in term.terms {
                r.add_term(m2.mul(&km), c2);
            }
        }
        r
    }

    /// Substitutes one variable by a value.
    pub fn partial_eval(&self, v: Var, value: &C) -> Self {
        let mut r = Self::zero();
        for (m, c) in &self.terms {
            let e = m.exp(v);
            let rest = Monomial(m.pairs().iter().copied().filter(|&(w, _)| w != v).collect());
            r.add_term(rest, c.rmul(&value.rpow(e)));
        }
        r
    }

    /// Composes with univariate polynomials: every variable `v` that occurs is replaced by
    /// `subs[v]` (a polynomial in one common variable τ). Used to restrict a constraint
    /// g(x, t) to a trajectory piece (docs/design.md §5.1).
    ///
    /// # Panics
    /// If a variable that occurs has no entry in `subs` (a caller bug).
    pub fn compose_univariate(&self, subs: &[UPoly<C>]) -> UPoly<C> {
        self.compose_with_powers(&mut substitution_powers(subs))
    }

    /// [`Self::compose_univariate`] with the powers of the substitutions formed so far
    /// (`powers[v][e]` = `subs[v]^e`, at least the 0th and 1st: [`substitution_powers`]),
    /// extended as needed — shared by compositions with the same substitutions.
    pub fn compose_with_powers(&self, powers: &mut [Vec<UPoly<C>>]) -> UPoly<C> {
        // each term's product and the sum in reused buffers, with the operations of
        // `UPoly::mul` and `UPoly::add` in their order (the same enclosures), without a
        // polynomial allocated per factor
        let mut acc: Vec<C> = Vec::new();
        let (mut term, mut next): (Vec<C>, Vec<C>) = (Vec::new(), Vec::new());
        for (m, c) in &self.terms {
            term.clear();
            if !c.is_zero() {
                term.push(c.clone());
            }
            for &(v, e) in m.pairs() {
                let pw = &mut powers[v as usize];
                while pw.len() <= e as usize {
                    let p = pw[pw.len() - 1].mul(&pw[1]);
                    pw.push(p);
                }
                let f = pw[e as usize].coeffs();
                if term.is_empty() || f.is_empty() {
                    term.clear();
                    break;
                }
                next.clear();
                next.resize(term.len() + f.len() - 1, C::zero());
                for (i, a) in term.iter().enumerate() {
                    if a.is_zero() {
                        continue;
                    }
                    for (j, b) in f.iter().enumerate() {
                        next[i + j] = next[i + j].radd(&a.rmul(b));
                    }
                }
                while next.last().is_some_and(|c| c.is_zero()) {
                    next.pop();
                }
                std::mem::swap(&mut term, &mut next);
            }
            if acc.len() < term.len() {
                acc.resize(term.len(), C::zero());
            }
            // (`UPoly::add` adds zero to the coefficients beyond the shorter operand)
            for (k, a) in acc.iter_mut().enumerate() {
                let t = term.get(k).cloned().unwrap_or_else(C::zero);
                *a = a.radd(&t);
            }
            while acc.last().is_some_and(|c| c.is_zero()) {
                acc.pop();
            }
        }
        UPoly::new(acc)
    }

    /// If only `v` occurs (or none), the dense univariate polynomial in `v`.
    pub fn to_univariate(&self, v: Var) -> Option<UPoly<C>> {
        let mut coeffs = vec![C::zero(); self.degree_in(v) as usize + 1];
        for (m, c) in &self.terms {
            match m.pairs() {
                [] => coeffs[0] = coeffs[0].radd(c),
                [(w, e)] if *w == v => coeffs[*e as usize] = coeffs[*e as usize].radd(c),
                _ => return None,
            }
        }
        Some(UPoly::new(coeffs))
    }

    /// The expectation operator over independent parameters (docs/design.md §2.3):
    /// every monomial's parameter part `Π ωj^βj` becomes `Π moment(ωj, βj)`.
    ///
    /// `moment` returns `None` when a moment is unavailable; the first such
    /// `(param, order)` is returned as the error.
    pub fn expect(
        &self,
        is_param: impl Fn(Var) -> bool,
        mut moment: impl FnMut(Var, u32) -> Option<C>,
    ) -> Result<Self, (Var, u32)> {
        let mut r = Self::zero();
        for (m, c) in &self.terms {
            let (params, rest) = m.split(&is_param);
            let mut k = c.clone();
            for &(v, e) in params.pairs() {
                k = k.rmul(&moment(v, e).ok_or((v, e))?);
            }
            r.add_term(rest, k);
        }
        Ok(r)
    }
}

/// [`Poly::compose_univariate`] of each of `polys` with the same `subs`, the powers of the
/// substitutions formed once for all (the whole-path partition composes every parameter
/// monomial's coefficient with one piece part, docs/design.md §5.14).
pub fn compose_univariate_all<'a, C: Ring + 'a>(
    polys: impl IntoIterator<Item = &'a Poly<C>>,
    subs: &[UPoly<C>],
) -> Vec<UPoly<C>> {
    let mut powers = substitution_powers(subs);
    polys.into_iter().map(|p| p.compose_with_powers(&mut powers)).collect()
}

/// The 0th and 1st powers of each substitution, which [`Poly::compose_with_powers`] extends.
pub fn substitution_powers<C: Ring>(subs: &[UPoly<C>]) -> Vec<Vec<UPoly<C>>> {
    subs.iter().map(|s| vec![UPoly::constant(C::one()), s.clone()]).collect()
}

/// Formatting of coefficients in polynomial text that [`parse`] reads back.
pub trait CoeffText: Ring {
    /// Whether the coefficient is negative (printed as ` - |c|`).
    fn is_neg(&self) -> bool;
    /// Text of `|c|`; `None` when `|c| == 1` (omitted before a monomial).
    fn abs_text(&self) -> (String, bool);
}

impl CoeffText for BigRational {
    fn is_neg(&self) -> bool {
        num_traits::Signed::is_negative(self)
    }
    fn abs_text(&self) -> (String, bool) {
        let a = num_traits::Signed::abs(self);
        (a.to_string(), num_traits::One::is_one(&a))
    }
}

impl CoeffText for f64 {
    fn is_neg(&self) -> bool {
        *self < 0.0
    }
    fn abs_text(&self) -> (String, bool) {
        let a = self.abs();
        (format!("{a}"), a == 1.0)
    }
}

impl<C: CoeffText> Poly<C> {
    /// Text in the scene grammar, e.g. `37/300 - x1^2 - x2^2`; terms by increasing degree.
    /// [`parse`] of this text gives the same polynomial back (for exact coefficients).
    pub fn to_text(&self, names: &dyn Fn(Var) -> String) -> String {
        if self.terms.is_empty() {
            return "0".to_string();
        }
        let mut ordered: Vec<(&Monomial, &C)> = self.terms.iter().collect();
        ordered.sort_by(|a, b| a.0.degree().cmp(&b.0.degree()).then_with(|| b.0.lex_cmp(a.0)));
        let mut s = String::new();
        for (i, (m, c)) in ordered.into_iter().enumerate() {
            let neg = c.is_neg();
            match (i, neg) {
                (0, true) => s.push('-'),
                (0, false) => {}
                (_, true) => s.push_str(" - "),
                (_, false) => s.push_str(" + "),
            }
            let (txt, is_one) = c.abs_text();
            // an exponent above the parser's per-'^' limit is written as repeated
            // factors (w^64 as w^32*w^32), so that printed text always parses back
            let mut mono: Vec<String> = Vec::new();
            for &(v, e) in m.pairs() {
                let mut left = e;
                while left > 0 {
                    let k = left.min(parse::MAX_EXPONENT);
                    mono.push(if k == 1 { names(v) } else { format!("{}^{k}", names(v)) });
                    left -= k;
                }
            }
            if mono.is_empty() {
                s.push_str(&txt);
            } else {
                if !is_one {
                    let _ = write!(s, "{txt}*");
                }
                s.push_str(&mono.join("*"));
            }
        }
        s
    }
}

/// Names of variables, in index order. Parsing registers or looks names up here.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VarTable {
    names: Vec<String>,
}

impl VarTable {
    /// A table with these names as variables `0, 1, ...`.
    pub fn new(names: impl IntoIterator<Item = String>) -> Self {
        VarTable { names: names.into_iter().collect() }
    }

    /// Index of `name`, if present.
    pub fn get(&self, name: &str) -> Option<Var> {
        self.names.iter().position(|n| n == name).map(|i| i as Var)
    }

    /// Index of `name`, adding it if absent.
    pub fn get_or_insert(&mut self, name: &str) -> Var {
        match self.get(name) {
            Some(v) => v,
            None => {
                self.names.push(name.to_string());
                (self.names.len() - 1) as Var
            }
        }
    }

    /// Name of `v` (`?v` if unknown).
    pub fn name(&self, v: Var) -> String {
        self.names.get(v as usize).cloned().unwrap_or_else(|| format!("?{v}"))
    }

    /// Number of variables.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the table is empty.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }
}

/// Exact-rational polynomial, the form scenes and contours are kept in.
pub type QPoly = Poly<BigRational>;

impl QPoly {
    /// The value at `vals`, exactly: [`Poly::eval`]'s, summed in integers over one common
    /// denominator and reduced once. With `xᵥ = nᵥ/dᵥ`, `eᵥ` the largest exponent of `v` and
    /// `L` the least common multiple of the coefficients' denominators,
    /// `p(x) = Σ (c·L)·Π nᵥ^e·dᵥ^(eᵥ−e) / (L·Π dᵥ^(eᵥ))`. ([`Poly::eval`] reduces every
    /// product and sum by a gcd: at a point given in floats, whose denominators are powers
    /// of two, that was most of the exact point bounds' time — `risk`, the bounds oracle
    /// test.) Panics, as [`Poly::eval`] does, when a variable of `self` has no value.
    pub fn eval_exact(&self, vals: &[BigRational]) -> BigRational {
        use num_bigint::BigInt;
        use num_integer::Integer;
        use num_traits::One;
        let mut top: BTreeMap<Var, u32> = BTreeMap::new();
        self.max_exponents_into(&mut top);
        // per variable: nᵥ^k and dᵥ^k for k = 0..=eᵥ
        let table = |x: &BigInt, n: u32| {
            let mut out = vec![BigInt::one()];
            for k in 1..=n as usize {
                let next = &out[k - 1] * x;
                out.push(next);
            }
            out
        };
        let powers: BTreeMap<Var, (Vec<BigInt>, Vec<BigInt>)> = top
            .iter()
            .map(|(&v, &e)| {
                let x = &vals[v as usize];
                (v, (table(x.numer(), e), table(x.denom(), e)))
            })
            .collect();
        let l = self.terms.values().fold(BigInt::one(), |acc, c| acc.lcm(c.denom()));
        let mut sum = BigInt::from(0);
        for (m, c) in &self.terms {
            let mut t = c.numer() * (&l / c.denom());
            for (v, (num, den)) in &powers {
                let e = m.exp(*v) as usize;
                let ev = top[v] as usize;
                if e > 0 {
                    t *= &num[e];
                }
                if ev > e {
                    t *= &den[ev - e];
                }
            }
            sum += t;
        }
        let denom = powers.iter().fold(l, |acc, (v, (_, den))| acc * &den[top[v] as usize]);
        BigRational::new(sum, denom)
    }
}

/// `p(x + c)`: the polynomial in centred variables, exactly (`c[v]` for variables
/// `0..c.len()`).
pub fn shift(p: &QPoly, c: &[f64]) -> QPoly {
    let maps: Vec<Option<(BigRational, BigRational)>> = c
        .iter()
        .map(|&v| {
            let c = BigRational::from_float(v).unwrap_or_default();
            (!num_traits::Zero::is_zero(&c)).then(|| (c, BigRational::from_integer(1.into())))
        })
        .collect();
    affine_subst(p, &maps)
}

#[cfg(test)]
mod tests;
