//! Each bound's proof over a sub-interval of the piece (zero risk from the support, the shifted moment bounds) and the bounds' values at one instant, for the cover's choices.

use super::*;

impl<'a> PieceBounds<'a> {
    /// Whether P < 0 for every τ in [a, a + w] and every parameter in the support box,
    /// proven by interval branch and bound over the parameter box (§3.7).
    pub(super) fn support_proves(&self, a: f64, w: f64) -> bool {
        let (Some(terms), Some(sf)) = (self.support_terms(), self.contour.support()) else { return false };
        // each term's ω^β as (box side, exponent) pairs, once per piece
        let index = self.support_index.get_or_init(|| {
            terms
                .iter()
                .map(|(beta, _)| {
                    beta.iter()
                        .map(|&(v, e)| (sf.support.iter().position(|s| s.0 == v).unwrap_or(usize::MAX), e))
                        .collect()
                })
                .collect()
        });
        let ranges: Option<Vec<Interval>> = terms.iter().map(|(_, p)| hull_on(p, a, w)).collect();
        let Some(ranges) = ranges else { return false };
        let root = &sf.support_box;
        let mid_tau = Interval::point(a + 0.5 * w);
        let at_mid: Vec<Interval> = terms.iter().map(|(_, p)| p.eval(&mid_tau)).collect();
        // Σ_β coefficient_β · range of ω^β, each parameter's range given by `side(i)`
        let sum = |coeffs: &[Interval], side: &dyn Fn(usize) -> Interval| {
            index.iter().zip(coeffs).fold(Interval::point(0.0), |acc, (beta, r)| {
                let m = beta.iter().fold(Interval::point(1.0), |m, &(i, e)| {
                    m * if i == usize::MAX { Interval::ENTIRE } else { power_range(side(i), e) }
                });
                acc + *r * m
            })
        };
        // quick refutation at the box's corners (the maximum over a box is often at a corner;
        // the search below finds such points only after many splits): P ≥ 0 there at the
        // sub-interval's middle, or P's range over the sub-interval at the corner not below
        // 0 — every box containing the corner has a range at least as wide, so no split
        // can prove the box that holds it
        if root.len() <= SUPPORT_CORNER_PARAMS {
            for mask in 0..1usize << root.len() {
                let corner = |i: usize| Interval::point(if mask >> i & 1 == 1 { root[i].hi } else { root[i].lo });
                if sum(&at_mid, &corner).lo >= 0.0 || sum(&ranges, &corner).hi >= 0.0 {
                    return false;
                }
            }
        }
        let mut stack = vec![root.clone()];
        let mut boxes = 0;
        while let Some(bx) = stack.pop() {
            boxes += 1;
            if boxes > SUPPORT_MAX_BOXES {
                return false;
            }
            if sum(&ranges, &|i| bx[i]).hi < 0.0 {
                continue;
            }
            // P ≥ 0 at the box's centre and the sub-interval's middle: no proof possible
            if sum(&at_mid, &|i| Interval::point(bx[i].mid())).lo >= 0.0 {
                return false;
            }
            // split the widest parameter range
            let Some((i, _)) = bx.iter().enumerate().max_by(|x, y| x.1.width().total_cmp(&y.1.width())) else {
                return false;
            };
            let m = bx[i].mid();
            if !(bx[i].lo < m && m < bx[i].hi) {
                return false;
            }
            let mut left = bx.clone();
            left[i] = Interval::new(bx[i].lo, m);
            let mut right = bx;
            right[i] = Interval::new(m, right[i].hi);
            stack.push(left);
            stack.push(right);
        }
        true
    }

    /// H/s^2k = Σⱼ αⱼ·(μ/s)^(2k−j)·cⱼ/sʲ with α₀ = Δ(1−b)^2k − b^2k, α₁ = 0 (c₁ = 0) and
    /// αⱼ = −C(2k,j)·b^(2k−j), by Horner's rule in μ/s (2k products by the low-degree μ/s
    /// instead of the powers of μ times each cⱼ); `None` when a cⱼ is unavailable.
    pub(super) fn moment_constraint(&self, s: &Scaled, order: u32, b: f64) -> Option<UPoly<Interval>> {
        let bi = Interval::point(b);
        let omb = Interval::point(1.0) - bi;
        let mu = s.mu_s.coeffs();
        let cap = (order as usize + 1) * mu.len().max(1) + 1;
        // two buffers, no allocation per step
        let (mut h, mut next) = (Vec::with_capacity(cap), Vec::with_capacity(cap));
        h.push(self.delta * pow(omb, order) - pow(bi, order));
        let zero = Interval::point(0.0);
        for j in 1..=order {
            // next = h·(μ/s)
            next.clear();
            next.resize(h.len() + mu.len().max(1) - 1, zero);
            for (i, x) in h.iter().enumerate() {
                for (k, y) in mu.iter().enumerate() {
                    next[i + k] = next[i + k] + *x * *y;
                }
            }
            std::mem::swap(&mut h, &mut next);
            if j >= 2 {
                let coef = -(Interval::point(binomial_f64(order, j)) * pow(bi, order - j));
                let c = self.central_scaled(s, j as usize)?.coeffs();
                if c.len() > h.len() {
                    h.resize(c.len(), zero);
                }
                for (x, y) in h.iter_mut().zip(c) {
                    *x = *x + coef * *y;
                }
            }
        }
        Some(UPoly::new(h))
    }

    /// The moment bound to try at local time `tau` (order, shift, float value at `tau`),
    /// from the point's central moments in floating point: the lowest order whose best
    /// shifted bound is at most [`LOW_ORDER_SHARE`]·Δ there, else the smallest bound.
    pub(super) fn moment_choice_at(&self, tau: f64) -> Option<(u32, f64, f64)> {
        let pt = self.point_at(tau)?;
        *pt.choice.get_or_init(|| {
            let (mu, c) = (pt.mu, pt.central(self));
            let top = (c.len() as u32).saturating_sub(1);
            let mut best: Option<(u32, f64, f64)> = None;
            for o in MOMENT_ORDERS.into_iter().filter(|&o| o <= top) {
                let Some((b, v)) = shift_search(mu, c, o, f64::NEG_INFINITY, SHIFT_SEARCH_COARSE) else { continue };
                if v <= LOW_ORDER_SHARE * self.delta_f {
                    return Some((o, b, v));
                }
                if best.is_none_or(|x| v < x.2) {
                    best = Some((o, b, v));
                }
            }
            best
        })
    }

    /// Whether no bound can prove any sub-interval containing local time `tau`, judged at the
    /// point in floating point (cheap; only ever used to give up): every bound there is
    /// above `factor`·Δ.
    pub(super) fn hopeless_at(&self, tau: f64, factor: f64) -> Option<CoverFailure> {
        let pt = self.point_at(tau)?;
        if pt.mu >= 0.0 {
            return Some(CoverFailure::MeanNotNegative { tau });
        }
        let limit = self.delta_f * factor;
        let mut best = cantelli_bound_f64(pt.mu, pt.second);
        if best <= limit {
            return None;
        }
        // the moment bound a proof here would use (memoised for that proof): the smallest
        // over the orders unless a low order is already below ½Δ
        if let Some(c) = self.moment_choice_at(tau) {
            best = best.min(c.2);
            if best <= limit {
                return None;
            }
        }
        // the central-moment Markov bounds (shift 0), which the shift grid may miss
        let central = pt.central(self);
        for o in MOMENT_ORDERS {
            best = best.min(moment_bound_f64(pt.mu, central, o, 0.0));
            if best <= limit {
                return None;
            }
        }
        // zero risk from the support at the point itself (a zero-width sub-interval)
        if self.support_proves(tau, 0.0) {
            return None;
        }
        Some(CoverFailure::AboveDelta { tau, best })
    }

    /// μ, E\[P²\] and the central moments at local time `tau` of the piece (or at the
    /// point) in floating point: from the compiled frame's point table when there is one
    /// (one pass for all of them), else from the contour's `f64` copies.
    fn point_values(&self, tau: f64) -> Option<PointValues> {
        let dim = self.contour.layout().dim;
        let mut xt = vec![0.0; dim + 1];
        match self.piece {
            Some(p) => {
                let t = p.t0 + (p.t1 - p.t0) * tau;
                for (d, row) in p.coeffs.iter().enumerate().take(dim) {
                    xt[d] = row.iter().rev().fold(0.0, |acc, &c| acc * t + c);
                }
                xt[dim] = t;
            }
            None => {
                for (d, s) in self.subs.iter().enumerate().take(dim + 1) {
                    xt[d] = s.coeff(0).mid();
                }
            }
        }
        if xt.iter().any(|v| !v.is_finite()) {
            return None;
        }
        if let Some(f) = &self.fast {
            let z = f.compiled.frame().point_coords_f64(&xt);
            let (mu, second) = f.compiled.bounds(self.contour).moments_at(&z);
            if mu.is_finite() && second.is_finite() {
                return Some(PointValues {
                    tau,
                    mu,
                    second,
                    central: OnceCell::new(),
                    xt,
                    z: Some(z),
                    choice: OnceCell::new(),
                });
            }
        }
        let (mu, second) = self.contour.moments_f64(&xt);
        Some(PointValues { tau, mu, second, central: OnceCell::new(), xt, z: None, choice: OnceCell::new() })
    }

    /// [`Self::point_values`] with a one-entry memo: a failed sub-interval's choice and
    /// its give-up test look at the same middle.
    fn point_at(&self, tau: f64) -> Option<std::rc::Rc<PointValues>> {
        if let Some(p) = self.last_point.borrow().as_ref().filter(|p| p.tau == tau) {
            return Some(p.clone());
        }
        let p = std::rc::Rc::new(self.point_values(tau)?);
        *self.last_point.borrow_mut() = Some(p.clone());
        Some(p)
    }
}
