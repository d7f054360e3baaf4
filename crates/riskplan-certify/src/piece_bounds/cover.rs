//! The cover of the piece's local time [0, 1] by sub-intervals, each proven by one bound (docs/design.md §5.13).

use super::*;

impl<'a> PieceBounds<'a> {
    /// Covers [0, 1] by sub-intervals each proven by one bound (§5.13), or says where it
    /// could not. `hint`: a local time where Cantelli failed (checked first for hopelessness).
    pub fn cover(&self, hint: Option<f64>) -> Result<Vec<BoundPart>, CoverFailure> {
        let is_piece = self.piece.is_some();
        // cheap rejection first (the float checks cost about a microsecond, a sub-interval
        // proof tens): the hint; then the whole piece, which one bound proves more often
        // than not; then evenly spaced points before splitting (a piece that fails
        // somewhere usually fails at one of them)
        if let Some(f) = hint.and_then(|t| self.hopeless_at(t, HOPELESS_FACTOR)) {
            return Err(f);
        }
        // a hint is where Cantelli's constraints failed: they cannot prove the whole piece
        if let Some(kind) = self.node_at(0.0, 1.0, hint.is_none(), hint.unwrap_or(0.5)) {
            return Ok(vec![BoundPart { tau0: 0.0, tau1: 1.0, bound: kind }]);
        }
        if !is_piece {
            return Err(self.failure_at(0.5));
        }
        for k in 0..=HOPELESS_PROBES {
            if let Some(f) = self.hopeless_at(k as f64 / HOPELESS_PROBES as f64, HOPELESS_FACTOR) {
                return Err(f);
            }
        }
        let mut parts: Vec<BoundPart> = Vec::new();
        let mut stack = vec![(0.5f64, 0.5f64, 1u32), (0.0, 0.5, 1)];
        let mut nodes = 1usize;
        while let Some((a, w, depth)) = stack.pop() {
            nodes += 1;
            let mid = a + 0.5 * w;
            if nodes > COVER_MAX_NODES {
                return Err(CoverFailure::Budget { tau: mid });
            }
            if let Some(kind) = self.node(a, w, true) {
                match parts.last_mut() {
                    Some(last) if last.bound == kind && last.tau1 == a => last.tau1 = a + w,
                    _ => parts.push(BoundPart { tau0: a, tau1: a + w, bound: kind }),
                }
                continue;
            }
            if depth >= COVER_MAX_DEPTH {
                return Err(self.failure_at(mid));
            }
            if let Some(f) = self.hopeless_at(mid, HOPELESS_FACTOR) {
                return Err(f);
            }
            let half = 0.5 * w;
            stack.push((a + half, half, depth + 1));
            stack.push((a, half, depth + 1));
        }
        Ok(parts)
    }

    fn failure_at(&self, tau: f64) -> CoverFailure {
        if self.piece.is_some() {
            if let Some(f) = self.hopeless_at(tau, HOPELESS_FACTOR) {
                return f;
            }
        } else {
            let mu = self.mu().eval(&Interval::point(0.0));
            if mu.lo >= 0.0 {
                return CoverFailure::MeanNotNegative { tau };
            }
        }
        CoverFailure::Budget { tau }
    }

    /// The bound proving [a, a + w], if one does.
    /// `cantelli`: whether to try Cantelli's constraints (not on a whole piece where the
    /// caller saw them fail).
    fn node(&self, a: f64, w: f64, cantelli: bool) -> Option<BoundKind> {
        self.node_at(a, w, cantelli, a + 0.5 * w)
    }

    /// [`Self::node`] with the moment bound chosen at local time `at` in [a, a + w] (the
    /// whole piece: at the hint, where Cantelli's constraints fail and the give-up test
    /// has just computed the choice's ingredients).
    fn node_at(&self, a: f64, w: f64, cantelli: bool, at: f64) -> Option<BoundKind> {
        let mu_h = hull_on(self.mu(), a, w)?;
        if cantelli && mu_h.hi < 0.0 && hull_on(self.g1(), a, w).is_some_and(|g| g.lo > 0.0) {
            return Some(BoundKind::Cantelli);
        }
        let moment = || -> Option<BoundKind> {
            let s = self.scaled()?;
            let (order, b, value) = self.moment_choice_at(at)?;
            if !(value < self.delta_f && b < 1.0) {
                return None;
            }
            let h = self.moment_constraint(s, order, b)?;
            hull_on(&h, a, w).is_some_and(|g| g.lo > 0.0).then_some(BoundKind::Moment(order))
        };
        // a moment bound well below Δ at the choice point is tried before the support
        // proof (a branch and bound over the parameter box, the dearer of the two)
        let negative = mu_h.hi < 0.0;
        let promising = negative && self.moment_choice_at(at).is_some_and(|c| c.2 <= LOW_ORDER_SHARE * self.delta_f);
        if promising {
            if let Some(kind) = moment() {
                return Some(kind);
            }
        }
        if self.support_proves(a, w) {
            return Some(BoundKind::Support);
        }
        if negative && !promising {
            return moment();
        }
        None
    }
}
