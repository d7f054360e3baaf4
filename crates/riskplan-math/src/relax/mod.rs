//! Moment relaxations (Lasserre) on the SDP layer: the building blocks shared by the
//! optimisation planners (docs/design.md §8: the time-varying SOS planner of the
//! paper's Section V-B and the standard SOS planner of Section V-A.2).
//!
//! A measure `μ` on `ℝ^N` enters a [`Model`] through its moments `y_α = E_μ[z^α]`,
//! `|α| ≤ K`, with `y_0 = 1` ([`MomentVars`]). On its moments:
//!
//! * the **moment matrix** `M_k(y) = [y_(β+β')]_{β,β' ∈ v_k} ⪰ 0` ([`MomentVars::moment_matrix`]);
//! * the **localizing matrix** of a polynomial `g(z)`:
//!   `M_r(g·y) = [Σ_γ g_γ y_(β+β'+γ)]_{β,β'} ⪰ 0`, `r = ⌊(K − deg g)/2⌋`, which
//!   holds for every measure supported on `{g ≥ 0}`;
//! * for a polynomial `G(z, t)` that also depends on a time variable `t ∈ [0, 1]`, the
//!   localizing matrix is a **matrix polynomial** `L(t)` with entries linear in `y`,
//!   and `L(t) ⪰ 0 ∀t ∈ [0, 1]` is imposed exactly by the matrix Markov–Lukács
//!   form `L(t) = S0(t) + t(1−t)·S1(t)` with SOS matrix polynomials `S0`, `S1`
//!   (Dette–Studden; [`add_matrix_lukacs`]).
//!
//! Everything here is modelling: a solution is a floating-point point that proves
//! nothing. The planners read trajectories out of it and certify them with the
//! motion checker like any other trajectory.

mod extract;
#[cfg(test)]
mod tests;

pub use extract::{extract_atoms, ExtractionError, RANK_REL};

use crate::sdp::{AffineExpr, GramBlock, Model, PsdBlock, SdpError, Var};
use std::collections::HashMap;

/// Coefficients below this fraction of a polynomial's largest coefficient are
/// dropped when it is handed to the relaxation (they come from cancellations in
/// floating point; dropping them changes only the optimisation problem, never a
/// verdict, which the motion checker makes on the read-out trajectory).
pub const COEFF_DROP_REL: f64 = 1e-13;

/// Monomials in `nvars` variables of degree ≤ `max_degree`, in graded
/// lexicographic order (degree first): the first `ν(n, d)` entries are those of
/// degree ≤ `d` for every `d ≤ max_degree`, and entry 0 is the constant.
#[derive(Clone, Debug)]
pub struct Monomials {
    nvars: usize,
    list: Vec<Vec<u8>>,
    index: HashMap<Vec<u8>, usize>,
    counts: Vec<usize>,
}

impl Monomials {
    /// All monomials of degree ≤ `max_degree` (`max_degree` ≤ 32 here).
    pub fn new(nvars: usize, max_degree: u32) -> Monomials {
        let mut list: Vec<Vec<u8>> = Vec::new();
        let mut counts = Vec::new();
        for d in 0..=max_degree {
            let mut cur = vec![0u8; nvars];
            push_degree(&mut list, &mut cur, 0, d);
            counts.push(list.len());
        }
        let index = list.iter().enumerate().map(|(i, e)| (e.clone(), i)).collect();
        Monomials { nvars, list, index, counts }
    }
    /// Number of variables.
    pub fn nvars(&self) -> usize {
        self.nvars
    }
    /// Number of monomials.
    pub fn len(&self) -> usize {
        self.list.len()
    }
    /// Whether there are none (never: the constant is always there).
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }
    /// `ν(n, d)`: how many have degree ≤ `d`.
    pub fn count_up_to(&self, d: u32) -> usize {
        self.counts.get(d as usize).copied().unwrap_or(self.list.len())
    }
    /// The exponents of monomial `i`.
    pub fn exps(&self, i: usize) -> &[u8] {
        &self.list[i]
    }
    /// The index of a monomial, if its degree is within range.
    pub fn index(&self, exps: &[u8]) -> Option<usize> {
        self.index.get(exps).copied()
    }
    /// The index of the product of monomials `i` and `j`, if within range.
    pub fn product(&self, i: usize, j: usize) -> Option<usize> {
        let e: Vec<u8> = self.list[i].iter().zip(&self.list[j]).map(|(a, b)| a + b).collect();
        self.index(&e)
    }
    /// The index of `z_k^p` (`p ≥ 1`), if within range.
    pub fn power(&self, k: usize, p: u8) -> Option<usize> {
        let mut e = vec![0u8; self.nvars];
        e[k] = p;
        self.index(&e)
    }
}

/// Monomials of degree exactly `d` in variables `k..`, lexicographically (higher
/// powers of earlier variables first).
fn push_degree(out: &mut Vec<Vec<u8>>, cur: &mut [u8], k: usize, d: u32) {
    if k + 1 == cur.len() {
        cur[k] = d as u8;
        out.push(cur.to_vec());
        cur[k] = 0;
        return;
    }
    if cur.is_empty() {
        if d == 0 {
            out.push(Vec::new());
        }
        return;
    }
    for e in (0..=d).rev() {
        cur[k] = e as u8;
        push_degree(out, cur, k + 1, d - e);
    }
    cur[k] = 0;
}

/// A polynomial in `z` (the measure's variables) whose coefficients are univariate
/// polynomials in a time variable `t`: `G(z, t) = Σ_γ Σ_l c_(γ,l) z^γ t^l`, stored as
/// `(γ, [c_(γ,0), c_(γ,1), …])`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ZtPoly {
    /// Terms by `z`-exponent.
    pub terms: Vec<(Vec<u8>, Vec<f64>)>,
}

impl ZtPoly {
    /// From a [`crate::poly::Poly`] over variables `0..nz` (`z`) and `nz` (`t`);
    /// other variables must not occur. Coefficients below [`COEFF_DROP_REL`] times the
    /// largest are dropped; the result is scaled so that its largest coefficient is
    /// 1 (a positive scale: the constraint `G ≥ 0` is unchanged). Returns `None` for
    /// the zero polynomial or a non-finite coefficient.
    pub fn from_poly(p: &crate::poly::Poly<f64>, nz: usize) -> Option<ZtPoly> {
        let max = p.terms().map(|(_, c)| c.abs()).fold(0.0, f64::max);
        if !(max.is_finite() && max > 0.0) {
            return None;
        }
        let mut map: HashMap<Vec<u8>, Vec<f64>> = HashMap::new();
        for (m, &c) in p.terms() {
            if c.abs() < COEFF_DROP_REL * max {
                continue;
            }
            let mut e = vec![0u8; nz];
            let mut l = 0usize;
            for &(v, k) in m.pairs() {
                let v = v as usize;
                if v < nz {
                    e[v] = u8::try_from(k).ok()?;
                } else if v == nz {
                    l = k as usize;
                } else {
                    return None;
                }
            }
            let cs = map.entry(e).or_default();
            if cs.len() <= l {
                cs.resize(l + 1, 0.0);
            }
            cs[l] += c / max;
        }
        let mut terms: Vec<(Vec<u8>, Vec<f64>)> = map.into_iter().collect();
        terms.sort_by(|a, b| a.0.cmp(&b.0));
        Some(ZtPoly { terms })
    }
    /// Total degree in `z`.
    pub fn z_degree(&self) -> u32 {
        self.terms.iter().map(|(e, _)| e.iter().map(|&k| k as u32).sum::<u32>()).max().unwrap_or(0)
    }
    /// Degree in `t`.
    pub fn t_degree(&self) -> usize {
        self.terms.iter().map(|(_, c)| c.len().saturating_sub(1)).max().unwrap_or(0)
    }
}

/// A linear expression under construction: terms merged by variable.
#[derive(Clone, Debug, Default)]
struct Acc {
    constant: f64,
    terms: HashMap<usize, f64>,
}

impl Acc {
    fn add(&mut self, e: &AffineExpr, c: f64) {
        self.constant += c * e.constant;
        for &(v, k) in &e.terms {
            *self.terms.entry(v.index()).or_insert(0.0) += c * k;
        }
    }
    fn finish(self) -> AffineExpr {
        let mut terms: Vec<(Var, f64)> =
            self.terms.into_iter().filter(|&(_, c)| c != 0.0).map(|(v, c)| (Var::from_index(v), c)).collect();
        terms.sort_by_key(|t| t.0);
        AffineExpr { constant: self.constant, terms }
    }
}

/// The moments `y_α`, `|α| ≤ K`, of one measure as model variables (`y_0 = 1` is a
/// constant, so every moment vector is that of a probability measure).
#[derive(Clone, Debug)]
pub struct MomentVars {
    mono: Monomials,
    vars: Vec<Option<Var>>,
    degree: u32,
}

impl MomentVars {
    /// New moment variables of degree ≤ `degree` in `nvars` variables.
    pub fn new(model: &mut Model, nvars: usize, degree: u32) -> MomentVars {
        let mono = Monomials::new(nvars, degree);
        let vars = (0..mono.len()).map(|i| (i > 0).then(|| model.add_var())).collect();
        MomentVars { mono, vars, degree }
    }
    /// The monomials.
    pub fn monomials(&self) -> &Monomials {
        &self.mono
    }
    /// The relaxation degree `K`.
    pub fn degree(&self) -> u32 {
        self.degree
    }
    /// `y_i` as an expression (the constant 1 for `i = 0`).
    pub fn expr(&self, i: usize) -> AffineExpr {
        match self.vars[i] {
            Some(v) => AffineExpr::var(v),
            None => AffineExpr::constant(1.0),
        }
    }
    /// The variable of `y_i` (`None` for `y_0`).
    pub fn var(&self, i: usize) -> Option<Var> {
        self.vars[i]
    }
    /// The value of `y_i` in a primal solution.
    pub fn value(&self, x: &[f64], i: usize) -> f64 {
        self.vars[i].map_or(1.0, |v| x.get(v.index()).copied().unwrap_or(f64::NAN))
    }
    /// `E[z_k]` in a primal solution.
    pub fn mean(&self, x: &[f64], k: usize) -> f64 {
        self.mono.power(k, 1).map_or(f64::NAN, |i| self.value(x, i))
    }

    /// `M_k(y) ⪰ 0`, `k = ⌊K/2⌋`.
    pub fn moment_matrix(&self, model: &mut Model) -> Result<PsdBlock, SdpError> {
        let side = self.mono.count_up_to(self.degree / 2);
        let mut entries = Vec::with_capacity(side * (side + 1) / 2);
        for j in 0..side {
            for i in 0..=j {
                let k = self.mono.product(i, j).ok_or_else(|| SdpError::BadConeSize("moment index".into()))?;
                entries.push(self.expr(k));
            }
        }
        model.add_psd_affine(side, &entries)
    }

    /// The entries of the localizing matrix polynomial of `g` (§ module docs):
    /// `result[svec(a, b)][l]` is the coefficient of `t^l` in `L_ab(t)`, for the
    /// order `r = ⌊(K − deg_z g)/2⌋`. `None` when `deg_z g > K` (the relaxation
    /// cannot hold the constraint: the caller must raise `K`, never drop it).
    pub fn localizing(&self, g: &ZtPoly) -> Option<(usize, Vec<Vec<AffineExpr>>)> {
        self.localizing_capped(g, u32::MAX)
    }

    /// [`MomentVars::localizing`] of order `min(r, cap)`. A lower order is a weaker
    /// relaxation (order 0 keeps only `E_μ[g(z, t)] ≥ 0 ∀t`) that is still exact at a
    /// Dirac measure, where it reads `g(z*, t) ≥ 0 ∀t`: enough for a heuristic that
    /// drives the measures to points and certifies what it reads out.
    pub fn localizing_capped(&self, g: &ZtPoly, cap: u32) -> Option<(usize, Vec<Vec<AffineExpr>>)> {
        let d = g.z_degree();
        if d > self.degree {
            return None;
        }
        let r = ((self.degree - d) / 2).min(cap);
        let side = self.mono.count_up_to(r);
        let nl = g.t_degree() + 1;
        let gi: Vec<(usize, &Vec<f64>)> =
            g.terms.iter().map(|(e, c)| self.mono.index(e).map(|i| (i, c))).collect::<Option<_>>()?;
        let mut out = Vec::with_capacity(side * (side + 1) / 2);
        for b in 0..side {
            for a in 0..=b {
                let ab = self.mono.product(a, b)?;
                let mut per_l: Vec<Acc> = vec![Acc::default(); nl];
                for &(gidx, cs) in &gi {
                    let k = self.mono.product(ab, gidx)?;
                    let e = self.expr(k);
                    for (l, &c) in cs.iter().enumerate() {
                        if c != 0.0 {
                            per_l[l].add(&e, c);
                        }
                    }
                }
                out.push(per_l.into_iter().map(|acc| acc.finish()).collect());
            }
        }
        Some((side, out))
    }
}

/// Sizes of one matrix Markov–Lukács constraint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LukacsSizes {
    /// Matrix side `m`.
    pub side: usize,
    /// Degree `D` in `t`.
    pub degree: usize,
    /// Side of `Q0` (`m(e+1)`), 0 when `D = 0` (a plain affine PSD block).
    pub q0: usize,
    /// Side of `Q1` (`m·e`).
    pub q1: usize,
}

/// Imposes `L(t) ⪰ 0 for all t ∈ [0, 1]` for a symmetric matrix polynomial of side
/// `side` given by its entries `entries[svec(a, b)][l]` (coefficient of `t^l`,
/// affine in the model's variables): `L = S0 + t(1−t)·S1`, `S0 = (I⊗v_e)ᵀQ0(I⊗v_e)`,
/// `S1 = (I⊗v_(e−1))ᵀQ1(I⊗v_(e−1))`, `Q0, Q1 ⪰ 0`, `e = ⌈D/2⌉`, matched
/// coefficient by coefficient (`m(m+1)/2·(2e+1)` equality rows). Exact for every
/// `D` (an odd degree is a degree-`2e` polynomial with a zero top coefficient).
/// With `D = 0` it is the affine PSD block `L ⪰ 0`.
pub fn add_matrix_lukacs(model: &mut Model, side: usize, entries: &[Vec<AffineExpr>]) -> Result<LukacsSizes, SdpError> {
    let degree = entries.iter().map(|e| e.len().saturating_sub(1)).max().unwrap_or(0);
    if degree == 0 {
        let flat: Vec<AffineExpr> = entries.iter().map(|e| e.first().cloned().unwrap_or_default()).collect();
        model.add_psd_affine(side, &flat)?;
        return Ok(LukacsSizes { side, degree, q0: 0, q1: 0 });
    }
    let e = degree.div_ceil(2);
    let q0 = model.add_gram(side * (e + 1))?;
    let q1 = model.add_gram(side * e)?;
    // [S]_(ab, l) = Σ_(p+q=l) Q_((a,p),(b,q)); raw entry coefficient 1 for a < b,
    // and for a = b: 1 on p = q, 2 on p ≠ q (both orders hit one raw entry)
    let s_terms = |g: &GramBlock, w: usize, a: usize, b: usize, l: usize, sign: f64, out: &mut Vec<(Var, f64)>| {
        for p in 0..w {
            if l < p || l - p >= w {
                continue;
            }
            let q = l - p;
            if a == b && q < p {
                continue;
            }
            let c = if a == b && p != q { 2.0 } else { 1.0 };
            out.push((g.var(a * w + p, b * w + q), sign * c));
        }
    };
    let mut k = 0;
    for b in 0..side {
        for a in 0..=b {
            let le = &entries[k];
            k += 1;
            for l in 0..=2 * e {
                // L_l − [S0]_l − [S1]_(l−1) + [S1]_(l−2) = 0
                let mut terms: Vec<(Var, f64)> = le.get(l).map(|x| x.terms.clone()).unwrap_or_default();
                let constant = le.get(l).map_or(0.0, |x| x.constant);
                s_terms(&q0, e + 1, a, b, l, -1.0, &mut terms);
                if l >= 1 {
                    s_terms(&q1, e, a, b, l - 1, -1.0, &mut terms);
                }
                if l >= 2 {
                    s_terms(&q1, e, a, b, l - 2, 1.0, &mut terms);
                }
                model.add_eq(&terms, -constant)?;
            }
        }
    }
    Ok(LukacsSizes { side, degree, q0: side * (e + 1), q1: side * e })
}
