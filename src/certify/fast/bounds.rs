//! The bounds beyond Cantelli compiled in the certifier's centred frame (docs/design.md
//! §5.13): the central moments cⱼ(x, t) of §3.8 and the support form's coefficients
//! a_β(x, t) of §3.7, as Horner trees over the frame's variables, so that restricting them
//! to a piece is a stack computation like the Cantelli restriction's ([`super::Compiled`])
//! instead of a general polynomial composition (a heap allocation per product).
//!
//! Soundness: P and E\[P\] are moved to the frame exactly (rationals, [`super::to_frame`]);
//! the central moments are enclosed from those exact polynomials by interval arithmetic
//! ([`crate::contour::bounds::build_higher_of`]), and every later operation is outward
//! rounded, so each restricted coefficient encloses the exact one.

use super::{to_frame, Compiled, FPoly, Frame, CAPACITY};
use crate::contour::bounds::build_higher_of;
use crate::contour::{RiskContour, SupportForm};
use crate::poly::{Interval, UPoly, Var};

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
        let layout = contour.layout();
        let support = contour.support().and_then(|sf| {
            let form = SupportForm::new(&poly, |v| layout.is_param(v), &sf.support)?;
            Some(form.terms.iter().map(|(beta, a, _)| (beta.clone(), Compiled::new(a, nv))).collect())
        });
        CompiledBounds { central, support }
    }

    /// The highest even central-moment order compiled.
    pub fn max_order(&self) -> u32 {
        let top = self.central.len().saturating_sub(1) as u32;
        top - top % 2
    }

    /// cⱼ restricted to a piece (`subs`: its frame coordinates), for j = 0 … max order;
    /// `None` when a degree exceeds the capacity (the caller composes generally then).
    pub fn central_on(&self, subs: &[FPoly<CAPACITY>]) -> Option<Vec<UPoly<Interval>>> {
        self.central.iter().take(self.max_order() as usize + 1).map(|c| restricted(c, subs)).collect()
    }

    /// The central moments at a point given by its compiled coordinates `z`, in plain
    /// floating point from the coefficients' midpoints (for choices and for giving up,
    /// never for proofs).
    pub fn central_at(&self, z: &[f64]) -> Vec<f64> {
        self.central.iter().take(self.max_order() as usize + 1).map(|c| c.eval_f64(z)).collect()
    }

    /// The support terms restricted to a piece; `None` without bounded support or beyond
    /// the capacity.
    pub fn support_on(&self, subs: &[FPoly<CAPACITY>]) -> Option<Vec<SupportPart<UPoly<Interval>>>> {
        self.support.as_ref()?.iter().map(|(beta, a)| Some((beta.clone(), restricted(a, subs)?))).collect()
    }
}

/// `c` composed with the piece's coordinates, as a heap polynomial.
pub fn restricted(c: &Compiled, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
    c.compose(subs).map(|f| UPoly::new(f.coeffs().to_vec()))
}
