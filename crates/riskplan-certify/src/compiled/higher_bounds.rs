//! The bounds beyond Cantelli compiled in the certifier's centred frame (docs/design.md
//! §5.13): the central moments cⱼ(x, t) of §3.8 and the support form's coefficients
//! a_β(x, t) of §3.7, as Horner trees over the frame's variables, so that restricting them
//! to a piece is a stack computation like the Cantelli restriction's ([`super::Compiled`])
//! instead of a general polynomial composition (a heap allocation per product).
//!
//! Soundness: P and E\[P\] are moved to the frame exactly (rationals, [`super::to_frame`]);
//! the central moments are enclosed from those exact polynomials by interval arithmetic
//! ([`riskplan_math::contour::bounds::build_higher_of`]), and every later operation is outward
//! rounded, so each restricted coefficient encloses the exact one.

use super::{by_capacity, restricted_len, to_frame, Compiled, FPoly, Frame, Substitution, CAPACITY};
use riskplan_math::contour::bounds::build_higher_of;
use riskplan_math::contour::{RiskContour, SupportForm};
use riskplan_math::poly::{Interval, Poly, UPoly, Var};

/// A support-form term: ω^β as (parameter, exponent) pairs, and its coefficient a_β in some form.
pub type SupportPart<T> = (Vec<(Var, u32)>, T);

/// One obstacle's higher-moment and support polynomials, compiled in a frame.
#[derive(Clone, Debug)]
pub struct CompiledBounds {
    /// c₀ … c_top (c₀ = 1, c₁ = 0), top the highest order the work budget allowed.
    central: Vec<Compiled>,
    /// The support form's terms: ω^β as (parameter, exponent) pairs and a_β compiled;
    /// `None` without bounded support.
    support: Option<Vec<SupportPart<Compiled>>>,
    /// E\[P\] and E\[P²\] as a table for point evaluation.
    moments: PointTable,
    /// c₀ … c_max as a table for point evaluation.
    point: PointTable,
}

/// Several polynomials in the frame's variables as one table for evaluation at points in
/// floating point (choices and giving up, never proofs): the union of their monomials,
/// evaluated once from the variables' powers, and per polynomial a dense row of
/// coefficient midpoints over that union. The central moments share most monomials (cⱼ
/// has those of P^j), so a point costs about one pass over the highest order's terms
/// instead of a tree walk per order.
#[derive(Clone, Debug, Default)]
struct PointTable {
    nvars: usize,
    /// Powers kept per variable (highest exponent + 1).
    stride: usize,
    /// The monomials' exponents, `nvars` per monomial.
    exps: Vec<u32>,
    /// Per polynomial, its terms as (monomial index, coefficient midpoint).
    rows: Vec<Vec<(u32, f64)>>,
}

/// A polynomial's terms as exponent vectors over variables `0..nvars` and `f64` coefficients.
fn sparse_row<C>(p: &Poly<C>, nvars: usize, to_f: impl Fn(&C) -> f64) -> Vec<(Vec<u32>, f64)>
where
    C: riskplan_math::poly::Ring,
{
    p.terms()
        .map(|(m, c)| {
            let mut e = vec![0u32; nvars];
            for &(v, k) in m.pairs() {
                if let Some(slot) = e.get_mut(v as usize) {
                    *slot = k;
                }
            }
            (e, to_f(c))
        })
        .collect()
}

impl PointTable {
    fn new(sparse: Vec<Vec<(Vec<u32>, f64)>>, nvars: usize) -> Self {
        let mut index: std::collections::BTreeMap<Vec<u32>, u32> = std::collections::BTreeMap::new();
        let rows = sparse
            .into_iter()
            .map(|row| {
                let mut terms: Vec<(u32, f64)> = Vec::with_capacity(row.len());
                for (e, c) in row {
                    let n = index.len() as u32;
                    let i = *index.entry(e).or_insert(n);
                    match terms.iter_mut().find(|t| t.0 == i) {
                        Some(t) => t.1 += c,
                        None => terms.push((i, c)),
                    }
                }
                terms
            })
            .collect();
        let mut exps = vec![0u32; index.len() * nvars];
        for (e, i) in index {
            let i = i as usize;
            exps[i * nvars..(i + 1) * nvars].copy_from_slice(&e);
        }
        let stride = exps.iter().copied().max().unwrap_or(0) as usize + 1;
        PointTable { nvars, stride, exps, rows }
    }

    /// Every row's value at `z` (missing coordinates are 0).
    fn eval(&self, z: &[f64]) -> Vec<f64> {
        // stack buffers for the usual sizes (a few variables, degree ≤ 16, ≤ 256 monomials)
        let npow = self.nvars * self.stride;
        let nmon = self.exps.len() / self.nvars.max(1);
        let (mut pstack, mut vstack) = ([0.0f64; 64], [0.0f64; 256]);
        let (mut pheap, mut vheap) = (Vec::new(), Vec::new());
        let powers: &mut [f64] = if npow <= pstack.len() {
            &mut pstack[..npow]
        } else {
            pheap.resize(npow, 0.0);
            &mut pheap
        };
        for v in 0..self.nvars {
            let x = z.get(v).copied().unwrap_or(0.0);
            let p = &mut powers[v * self.stride..(v + 1) * self.stride];
            p[0] = 1.0;
            for k in 1..self.stride {
                p[k] = p[k - 1] * x;
            }
        }
        let values: &mut [f64] = if nmon <= vstack.len() {
            &mut vstack[..nmon]
        } else {
            vheap.resize(nmon, 0.0);
            &mut vheap
        };
        for (val, e) in values.iter_mut().zip(self.exps.chunks_exact(self.nvars.max(1))) {
            *val = e.iter().enumerate().fold(1.0, |acc, (v, &k)| acc * powers[v * self.stride + k as usize]);
        }
        self.rows.iter().map(|row| row.iter().map(|&(i, c)| c * values[i as usize]).sum()).collect()
    }
}

impl CompiledBounds {
    /// Compiles the bounds of `contour` in `frame` (`dim + 1` variables).
    pub fn new(contour: &RiskContour, frame: &Frame) -> Self {
        let nv = contour.layout().xt_len();
        let poly = to_frame(contour.poly(), frame);
        let mean = to_frame(&contour.mean, frame);
        let hm = build_higher_of(contour, &poly, &mean);
        let top = hm.max_order() as usize;
        let central = hm.interval().iter().take(top + 1).map(|c| Compiled::from_intervals(c, nv)).collect();
        let moments = PointTable::new(
            vec![
                sparse_row(&mean, nv, riskplan_math::poly::rational_to_f64),
                sparse_row(&to_frame(&contour.second, frame), nv, riskplan_math::poly::rational_to_f64),
            ],
            nv,
        );
        let point = PointTable::new(
            hm.interval().iter().take(top + 1).map(|c| sparse_row(c, nv, |i: &Interval| i.mid())).collect(),
            nv,
        );
        let layout = contour.layout();
        let support = contour.support().and_then(|sf| {
            let form = SupportForm::new(&poly, |v| layout.is_param(v), &sf.support)?;
            Some(form.terms.iter().map(|(beta, a, _)| (beta.clone(), Compiled::new(a, nv))).collect())
        });
        CompiledBounds { central, support, moments, point }
    }

    /// The highest even central-moment order compiled.
    pub fn max_order(&self) -> u32 {
        let top = self.central.len().saturating_sub(1) as u32;
        top - top % 2
    }

    /// cⱼ alone restricted to a piece; `None` beyond the compiled orders or the capacity.
    pub fn central_one_on(&self, j: usize, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
        restricted(self.central.get(j)?, subs)
    }

    /// cⱼ restricted to a piece given by its [`Substitution`], in `f64` with midpoints,
    /// radii and a running error bound ([`Compiled::compose_r`]); `None` beyond the
    /// compiled orders, the capacity or the error model's range (the caller uses
    /// [`CompiledBounds::central_one_on`] then).
    pub fn central_one_on_f64(&self, j: usize, sub: &Substitution) -> Option<UPoly<Interval>> {
        let c = self.central.get(j)?;
        fn run<const N: usize>(c: &Compiled, sub: &Substitution) -> Option<UPoly<Interval>> {
            let subs = sub.epolys::<N>()?;
            c.compose_r(&subs[..sub.len()]).map(|f| UPoly::new(f.coeffs().to_vec()))
        }
        by_capacity!(restricted_len(c, sub.degree()), run, c, sub)
    }

    /// E\[P\] and E\[P²\] at a point given by its compiled coordinates `z`, in floating
    /// point (choices and giving up only).
    pub fn moments_at(&self, z: &[f64]) -> (f64, f64) {
        let v = self.moments.eval(z);
        (v.first().copied().unwrap_or(f64::NAN), v.get(1).copied().unwrap_or(f64::NAN))
    }

    /// The central moments c₀ … c_max at a point given by its compiled coordinates `z`, in
    /// floating point from the coefficients' midpoints (choices and giving up only).
    pub fn central_at(&self, z: &[f64]) -> Vec<f64> {
        let mut c = self.point.eval(z);
        c.truncate(self.max_order() as usize + 1);
        c
    }

    /// The support terms restricted to a piece; `None` without bounded support or beyond
    /// the capacity.
    pub fn support_on(&self, subs: &[FPoly<CAPACITY>]) -> Option<Vec<SupportPart<UPoly<Interval>>>> {
        self.support.as_ref()?.iter().map(|(beta, a)| Some((beta.clone(), restricted(a, subs)?))).collect()
    }
}

/// `c` composed with the piece's coordinates, as a heap polynomial. The composition runs
/// in the smallest stack polynomial that holds its degree (a straight piece's c₄ needs 9
/// coefficients, not [`CAPACITY`]): every product of the Horner walk zeroes and copies
/// the whole buffer, which dominated the cost of the low orders.
pub fn restricted(c: &Compiled, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
    let sub_degree = subs.iter().map(FPoly::degree).max().unwrap_or(0);
    by_capacity!(restricted_len(c, sub_degree), restricted_in, c, subs)
}

fn restricted_in<const N: usize>(c: &Compiled, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
    let small: Option<Vec<FPoly<N>>> = subs.iter().map(FPoly::resized).collect();
    c.compose(&small?).map(|f| UPoly::new(f.coeffs().to_vec()))
}
