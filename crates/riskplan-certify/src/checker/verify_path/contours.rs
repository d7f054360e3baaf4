//! The framed contours of a scene (`FramedContours`): each obstacle's contour polynomials in the verify path's frame, its box tests and their grid, built on first use.

use super::*;

impl FramedContours {
    /// Largest scale exponent: `2^±1000` is a normal float.
    const MAX_EXPONENT: i32 = 1000;
    /// A centre within this many half-widths of the origin is not shifted: the
    /// monomials then cancel by at most about this factor to the power of the degree,
    /// which the interval enclosures absorb (Bernstein decides such scenes today).
    const CENTRE_KEPT: f64 = 16.0;
    /// A scale exponent of at most this magnitude is not applied (2^±16).
    const SCALE_KEPT: i32 = 16;
    /// Above this many obstacles distant ones are cleared by a box test first: below
    /// it composing with every obstacle costs less than preparing the test (a few
    /// tenths of a millisecond per obstacle, once per scene).
    const NEAR_MIN_OBSTACLES: usize = 16;
    /// The box tests' points are found on a grid of 16^dim points per obstacle
    /// (`index::obstacle_center`): beyond 3 dimensions that costs more than it saves.
    const NEAR_MAX_DIM: usize = 3;

    /// The box tests of every obstacle (`None` when the scene has too few obstacles or
    /// too many dimensions), built on first use; `Err` when `stop` says stop first (the
    /// tests built so far are kept for the next call, with those taken over from the
    /// previous revision).
    pub fn near(&self, scene: &Scene, stop: &dyn Fn() -> bool) -> Result<Option<&[Option<Near>]>, Interrupted> {
        if let Some(n) = self.near.get() {
            return Ok(n.as_deref());
        }
        if !Self::has_near(scene) {
            return Ok(self.near.get_or_init(|| None).as_deref());
        }
        // one build at a time (the final check and the whole-path bound beside it both
        // ask, and plans on other workers): another thread waits for it instead of
        // building the same again — polling, so that its own `stop` still ends the wait
        let mut carried = loop {
            match self.carried.try_lock() {
                Ok(g) => break g,
                Err(std::sync::TryLockError::Poisoned(e)) => break e.into_inner(),
                Err(std::sync::TryLockError::WouldBlock) => {
                    if let Some(n) = self.near.get() {
                        return Ok(n.as_deref());
                    }
                    if stop() {
                        return Err(Interrupted);
                    }
                    std::thread::sleep(NEAR_WAIT_POLL);
                }
            }
        };
        if let Some(n) = self.near.get() {
            return Ok(n.as_deref());
        }
        let region = Self::near_region(scene);
        // what the previous revision (or a stopped build) left, taken: `Some(test)` per
        // obstacle whose test is known (`Some(None)`: known to have none)
        let n = scene.obstacles.len();
        let mut known: Vec<Option<Carried>> = carried.take().filter(|c| c.len() == n).unwrap_or_else(|| vec![None; n]);
        for (o, slot) in scene.obstacles.iter().zip(known.iter_mut()) {
            if slot.is_some() {
                continue;
            }
            if stop() {
                // the tests built so far stay for the next call
                *carried = Some(known);
                return Err(Interrupted);
            }
            *slot = Some(Self::near_of(o, &region));
        }
        let near: Vec<Option<Near>> = known.into_iter().map(Option::flatten).collect();
        Ok(self.near.get_or_init(|| Some(near)).as_deref())
    }

    /// How many obstacles' box tests were taken over from the previous revision and wait
    /// for [`Self::near`] (`None`: none are waiting).
    #[cfg(test)]
    pub(crate) fn carried_count(&self) -> Option<usize> {
        let c = self.carried.lock().ok()?;
        Some(c.as_ref()?.iter().filter(|e| e.is_some()).count())
    }

    /// Whether a scene's obstacles get box tests at all ([`Self::near`]).
    pub(crate) fn has_near(scene: &Scene) -> bool {
        scene.obstacles.len() > Self::NEAR_MIN_OBSTACLES && scene.dim <= Self::NEAR_MAX_DIM
    }

    /// The workspace × the horizon, where the box tests' points are looked for.
    fn near_region(scene: &Scene) -> Vec<(f64, f64)> {
        let ws = &scene.workspace;
        let mut region: Vec<(f64, f64)> = ws.lower.iter().copied().zip(ws.upper.iter().copied()).collect();
        region.push(scene.horizon);
        region
    }

    /// One obstacle's box test in `region` ([`Self::near_region`]): `None` for a
    /// pedestrian (decided by its tail bound or, with `cantelli`, by the composition) and
    /// for a point that is not a finite float.
    fn near_of(o: &Obstacle, region: &[(f64, f64)]) -> Option<Near> {
        if o.pedestrian.is_some() {
            return None;
        }
        let center = crate::checker::cover_index::obstacle_center(&o.contour, region);
        // the same exact values substituted and subtracted
        let one = BigRational::from_integer(1.into());
        let maps = center
            .iter()
            .map(|&c| Some((BigRational::from_float(c)?, one.clone())))
            .map(|m| m.map(Some))
            .collect::<Option<Vec<_>>>()?;
        let around = |p: &riskplan_math::poly::QPoly| {
            riskplan_math::poly::taylor_shift(p, &maps).map_coeffs(Interval::enclose_rational)
        };
        Some(Near { mean: around(&o.contour.mean), second: around(&o.contour.second), center })
    }

    /// The contours of `scene`, a later revision of `old_scene` whose framed contours
    /// were `old`, taking over what `old` built for the obstacles whose contour the two
    /// revisions share (the same cached contour: the same polynomial and laws): their box
    /// tests and framed polynomials are the same when the frame and the region are
    /// (else a one-obstacle update of a crowded scene would make the next plan's final
    /// check rebuild every obstacle's box test). Nothing is built
    /// here: the box tests of the other obstacles are made by the first final check, as
    /// for a new scene.
    /// `index[i]`: obstacle `i`'s index in `old_scene` when the two share its contour
    /// ([`crate::checker::SceneKernel::successor`] finds it once for everything it takes over).
    pub fn reusing(scene: &Scene, old: &FramedContours, old_scene: &Scene, index: &[Option<usize>]) -> Self {
        let mut new = FramedContours::new(scene);
        let same_frame = new.center == old.center && new.inv_scale == old.inv_scale;
        if !same_frame
            || Self::near_region(scene) != Self::near_region(old_scene)
            || index.len() != scene.obstacles.len()
        {
            return new;
        }
        // (pedestrians have no box test and no framed polynomials taken over)
        let previous = |i: usize| {
            index[i].filter(|&j| old_scene.obstacles[j].pedestrian.is_none() && scene.obstacles[i].pedestrian.is_none())
        };
        // the framed polynomials (exact substitutions into the frame)
        if let (Some((_, new_p)), Some((_, old_p))) = (&new.polys, &old.polys) {
            for (i, slot) in new_p.iter().enumerate() {
                if let Some(pair) = previous(i).and_then(|j| old_p.get(j)?.get()) {
                    let _ = slot.set(pair.clone());
                }
            }
        }
        // the box tests the old revision had built — or, when it built none, those it had
        // itself taken over (a revision no plan used passes them on)
        let old_tests: Option<Vec<Option<Carried>>> = match old.near.get() {
            Some(Some(built)) => Some(built.iter().cloned().map(Some).collect()),
            Some(None) => None,
            // (never waiting: a plan may be building them right now — then nothing passes)
            None => old.carried.try_lock().ok().and_then(|c| c.clone()),
        };
        if let Some(tests) = old_tests.filter(|t| t.len() == old_scene.obstacles.len()) {
            let kept = (0..scene.obstacles.len()).map(|i| previous(i).and_then(|j| tests[j].clone())).collect();
            if let Ok(mut c) = new.carried.lock() {
                *c = Some(kept);
            }
        }
        // the grids: the old revision's own, or those it had taken over (their obstacles
        // mapped through it)
        let grids: Vec<_> = old
            .grids
            .lock()
            .map(|v| v.iter().filter_map(|(d, g)| Some((d.clone(), g.clone()?))).collect())
            .unwrap_or_default();
        let index: Vec<Option<usize>> = (0..scene.obstacles.len()).map(previous).collect();
        new.grids_carried = if !grids.is_empty() {
            Some(GridsCarried { index, grids })
        } else {
            old.grids_carried.as_ref().map(|c| GridsCarried {
                index: index.iter().map(|j| c.index.get((*j)?).copied().flatten()).collect(),
                grids: c.grids.clone(),
            })
        };
        new
    }

    /// The grid of the box tests at `deltas` ([`NearGrid`]) on a scene of at least
    /// `GRID_MIN_OBSTACLES` (64) obstacles with box tests (`None` otherwise), built on first
    /// use; `Err` when `stop` says stop first (nothing is kept then).
    pub fn grid(
        &self,
        scene: &Scene,
        deltas: &[RiskLevel],
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<std::sync::Arc<NearGrid>>, Interrupted> {
        let Some(near) = self.near(scene, stop)? else { return Ok(None) };
        if scene.obstacles.len() < GRID_MIN_OBSTACLES || deltas.len() != near.len() {
            return Ok(None);
        }
        if let Some(g) = self.grids.lock().ok().and_then(|v| v.iter().find(|(d, _)| d == deltas).map(|e| e.1.clone())) {
            return Ok(g);
        }
        let g = NearGrid::build(scene, near, deltas, self.grids_carried.as_ref(), stop)?.map(std::sync::Arc::new);
        if let Ok(mut v) = self.grids.lock() {
            if v.len() >= GRIDS_PER_SCENE {
                v.remove(0);
            }
            v.push((deltas.to_vec(), g.clone()));
        }
        Ok(g)
    }

    /// Whether the box tests are built, and on a scene of at least `GRID_MIN_OBSTACLES`
    /// obstacles their grid at `deltas`: what [`Self::grid`] would otherwise build.
    pub(crate) fn built(&self, scene: &Scene, deltas: &[RiskLevel]) -> bool {
        // (a scene without box tests has no grid either)
        self.near.get().is_some_and(|n| {
            n.is_none()
                || scene.obstacles.len() < GRID_MIN_OBSTACLES
                || self.grids.lock().is_ok_and(|v| v.iter().any(|(d, _)| d == deltas))
        })
    }

    /// The scene's contours in the verify path's frame (exact substitution, then enclosed).
    pub fn new(scene: &Scene) -> Self {
        let ws = &scene.workspace;
        let mut center = scene.center();
        let mut half: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(l, u)| 0.5 * u - 0.5 * l).collect();
        half.push(0.5 * scene.horizon.1 - 0.5 * scene.horizon.0);
        let exps: Vec<i32> = half
            .iter()
            .map(|&w| {
                let e = if w > 0.0 && w.is_finite() {
                    (w.log2().floor() as i32).clamp(-Self::MAX_EXPONENT, Self::MAX_EXPONENT)
                } else {
                    0
                };
                if e.abs() <= Self::SCALE_KEPT {
                    0
                } else {
                    e
                }
            })
            .collect();
        for (c, w) in center.iter_mut().zip(&half) {
            if c.abs() <= Self::CENTRE_KEPT * w {
                *c = 0.0;
            }
        }
        if center.iter().all(|&c| c == 0.0) && exps.iter().all(|&e| e == 0) {
            let n = center.len();
            return FramedContours {
                center,
                inv_scale: vec![1.0; n],
                polys: None,
                near: OnceLock::new(),
                carried: Default::default(),
                grids: Default::default(),
                grids_carried: None,
            };
        }
        let two = BigRational::from_integer(2.into());
        // v ↦ c_v + 2^(e_v)·v
        let subs: FrameMaps = center
            .iter()
            .zip(&exps)
            .map(|(&c, &e)| Some((BigRational::from_float(c).unwrap_or_default(), num_traits::Pow::pow(&two, e))))
            .collect();
        let polys = scene.obstacles.iter().map(|_| OnceLock::new()).collect();
        let inv_scale = exps.iter().map(|&e| crate::compiled::pow2(-e)).collect();
        FramedContours {
            center,
            inv_scale,
            polys: Some((subs, polys)),
            near: OnceLock::new(),
            carried: Default::default(),
            grids: Default::default(),
            grids_carried: None,
        }
    }

    /// The constraints of obstacle `o` (the scene's `i`-th) restricted to a piece, in
    /// interval arithmetic: `(g1, g2)` = (Cantelli, mean) of eq. (15) in τ ∈ [0, 1].
    pub(super) fn restrict(
        &self,
        i: usize,
        o: &Obstacle,
        pr: PieceRef<'_>,
        one_minus_delta: Interval,
    ) -> (UPoly<Interval>, UPoly<Interval>) {
        let t0 = Interval::point(pr.t0);
        let h = Interval::point(pr.t1) - t0;
        let n = self.center.len();
        let mut subs: Vec<UPoly<Interval>> = (0..n - 1)
            .map(|d| {
                let row = pr.coeffs.get(d).map(|r| r.as_slice()).unwrap_or(&[]);
                let x = UPoly::new(row.iter().map(|&c| Interval::point(c)).collect()).compose_affine(&t0, &h);
                x.sub(&UPoly::constant(Interval::point(self.center[d]))).scale(&Interval::point(self.inv_scale[d]))
            })
            .collect();
        subs.push(
            UPoly::linear(t0 - Interval::point(self.center[n - 1]), h).scale(&Interval::point(self.inv_scale[n - 1])),
        );
        let (m, s) = match self.framed_pair(i, o) {
            Some(pair) => (&pair.0, &pair.1),
            None => o.contour.interval_polys(),
        };
        let r = crate::restrict::restrict(m, s, &subs, &one_minus_delta);
        (r.cantelli, r.mean)
    }

    /// E\[P\] and E\[P²\] of obstacle `o` (the scene's `i`-th) in the frame, substituted
    /// exactly on first use (or taken over from the previous revision,
    /// [`FramedContours::reusing`]) and enclosed; `None` in the scene's own coordinates.
    fn framed_pair(
        &self,
        i: usize,
        o: &Obstacle,
    ) -> Option<&(riskplan_math::poly::Poly<Interval>, riskplan_math::poly::Poly<Interval>)> {
        let (maps, p) = self.polys.as_ref()?;
        let frame = |p: &riskplan_math::poly::QPoly| {
            riskplan_math::poly::taylor_shift(p, maps).map_coeffs(Interval::enclose_rational)
        };
        Some(p[i].get_or_init(|| (frame(&o.contour.mean), frame(&o.contour.second))))
    }

    /// Makes obstacle `o`'s (the scene's `i`-th) E\[P\] and E\[P²\] in the frame now, if they
    /// are not yet (a warm-up, `app::warm_up`: the verify path makes them on first use).
    pub(crate) fn ensure_pair(&self, i: usize, o: &Obstacle) {
        let _ = self.framed_pair(i, o);
    }

    /// Whether obstacle `i`'s framed polynomials are made (always, in the scene's own
    /// coordinates: there are none to make; for tests).
    pub fn has_pair(&self, i: usize) -> bool {
        self.polys.as_ref().is_none_or(|(_, p)| p.get(i).is_some_and(|q| q.get().is_some()))
    }

    /// For tests: how many obstacles' framed polynomials are made (or taken over) so far,
    /// and then every obstacle's, made where missing (`Debug` forms: exact for floats);
    /// `None` in the scene's own coordinates.
    #[cfg(test)]
    pub(crate) fn framed_pairs_for_test(&self, scene: &Scene) -> Option<(usize, Vec<String>)> {
        let made = self.polys.as_ref()?.1.iter().filter(|p| p.get().is_some()).count();
        let all = scene.obstacles.iter().enumerate().map(|(i, o)| format!("{:?}", self.framed_pair(i, o))).collect();
        Some((made, all))
    }
}
