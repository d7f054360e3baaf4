//! The restricted polynomials each bound needs over a piece (the mean, Cantelli's constraint, the scaled central moments, the support form's terms), each formed on first use.

use super::*;

impl<'a> PieceBounds<'a> {
    pub(super) fn mu(&self) -> &UPoly<Interval> {
        self.mu.get_or_init(|| {
            self.fast
                .as_ref()
                .and_then(|f| {
                    f.esub.and_then(|sub| f.compiled.mean_on_f64(sub)).or_else(|| f.compiled.mean_on(f.subs()))
                })
                .unwrap_or_else(|| self.contour.interval_polys().0.compose_univariate(&self.subs))
        })
    }

    pub(super) fn g1(&self) -> &UPoly<Interval> {
        self.g1.get_or_init(|| {
            let e1 = self.mu();
            let e2 = self
                .fast
                .as_ref()
                .and_then(|f| {
                    f.esub.and_then(|sub| f.compiled.second_on_f64(sub)).or_else(|| f.compiled.second_on(f.subs()))
                })
                .unwrap_or_else(|| self.contour.interval_polys().1.compose_univariate(&self.subs));
            let omd = Interval::point(1.0) - self.delta;
            e1.mul(e1).sub(&e2.scale(&omd))
        })
    }

    /// The highest central-moment order available (compiled in the frame, else general).
    fn top_order(&self) -> u32 {
        match &self.fast {
            Some(f) => f.compiled.bounds(self.contour).max_order(),
            None => self.contour.higher().max_order(),
        }
    }

    pub(super) fn scaled(&self) -> Option<&Scaled> {
        self.central
            .get_or_init(|| {
                let top = self.top_order();
                if top < MOMENT_ORDERS[0] {
                    return None;
                }
                let mu = self.mu();
                let h = bernstein_hull(mu.coeffs())?;
                let big = h.lo.abs().max(h.hi.abs());
                if !(big > 0.0 && big.is_finite()) {
                    return None;
                }
                let e = big.log2().floor() as i32;
                let mu_s = mu.scale(&scale_factor(e, 1)?);
                let central = (0..=top).map(|_| OnceCell::new()).collect();
                Some(Scaled { e, mu_s, central })
            })
            .as_ref()
    }

    /// cⱼ/sʲ restricted to the piece: compiled in the frame, else generally composed;
    /// `None` when sʲ is not a normal power of two (the proof is not attempted then).
    pub(super) fn central_scaled<'s>(&self, s: &'s Scaled, j: usize) -> Option<&'s UPoly<Interval>> {
        s.central
            .get(j)?
            .get_or_init(|| {
                let f = scale_factor(s.e, j as i32)?;
                // in f64 with midpoints and radii where the model allows, else in intervals
                // (compiled), else generally composed
                let fast = self.fast.as_ref().and_then(|fa| {
                    let cb = fa.compiled.bounds(self.contour);
                    fa.esub.and_then(|sub| cb.central_one_on_f64(j, sub)).or_else(|| cb.central_one_on(j, fa.subs()))
                });
                let c = match fast {
                    Some(c) => c,
                    None => self.contour.higher().interval().get(j)?.compose_univariate(&self.subs),
                };
                Some(c.scale(&f))
            })
            .as_ref()
    }

    pub(super) fn support_terms(&self) -> Option<&SupportTerms> {
        self.support
            .get_or_init(|| {
                let sf = self.contour.support()?;
                if let Some(terms) =
                    self.fast.as_ref().and_then(|f| f.compiled.bounds(self.contour).support_on(f.subs()))
                {
                    return Some(terms);
                }
                Some(sf.terms.iter().map(|(beta, _, ai)| (beta.clone(), ai.compose_univariate(&self.subs))).collect())
            })
            .as_ref()
    }
}
