//! The verify path's own frame for the final check (docs/design.md §5.12).

use super::decide::Interrupted;
use super::workspace::{check_workspace, interval_hull};
use super::Status;
use crate::bounds::{Level, PieceBounds};
use crate::{bernstein, restrict_exact, PieceRef, Verdict};
use num_rational::BigRational;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_math::poly::{Interval, UPoly};
use riskplan_scene::{Obstacle, Scene};
use std::sync::OnceLock;

/// Per variable (space, then time), the frame's map `v ↦ c_v + 2^(e_v)·v`, exactly
/// ([`riskplan_math::poly::taylor_shift`]).
type FrameMaps = Vec<Option<(BigRational, BigRational)>>;

/// A scene's contour polynomials for the final check (docs/design.md §5.12), written in
/// the verify path's own frame `z_v = (x_v − c_v)·2^(−e_v)` (centre and power-of-two
/// scale from the workspace and the horizon) exactly, by the verify path's own Taylor
/// shift ([`riskplan_math::poly::taylor_shift`]), then enclosed coefficient by coefficient. In the scene's own
/// coordinates a workspace at x ≈ 5·10⁶ (UTM) makes the monomials cancel by many orders
/// of magnitude and nearly every piece would go to the exact fallback. This is
/// deliberately not the compiled path's frame code (`certify::fast`, whose exact
/// substitution is [`riskplan_math::poly::affine_subst`]): the final check shares no code with it
/// beyond the contour polynomials. A scene near the origin at moderate scale keeps its own
/// coordinates (`polys` is `None`): the substitution is not needed there.

#[derive(Debug)]
pub struct FramedContours {
    center: Vec<f64>,
    inv_scale: Vec<f64>,
    /// The substitution into the frame (`None`: the scene's own coordinates) and each
    /// obstacle's framed polynomials, made on first use (a pedestrian decided by its tail
    /// bound never needs them).
    polys: Option<(FrameMaps, Vec<FramedPair>)>,
    /// With more than [`FramedContours::NEAR_MIN_OBSTACLES`] obstacles in at most
    /// [`FramedContours::NEAR_MAX_DIM`] dimensions: each obstacle's contour polynomials
    /// rewritten exactly around a point of its own, for a box test that clears distant
    /// obstacles without a composition (`None` for an obstacle whose point is not
    /// finite). Built by the first final check that needs it, asking its `stop`.
    near: OnceLock<Option<Vec<Option<Near>>>>,
    /// What the previous revision of the scene had built of `near` and of the framed
    /// polynomials, per obstacle of this revision whose contour it shares
    /// ([`FramedContours::reusing`]): taken when `near` is built (the box test of an
    /// unchanged obstacle is the same), then dropped.
    carried: std::sync::Mutex<Option<Vec<Option<Carried>>>>,
    /// The grids of the last few risk allocations ([`NearGrid`], crowded scenes only).
    grids: std::sync::Mutex<Vec<GridEntry>>,
    /// The previous revision's grids and, per obstacle of this one, its index there when
    /// the two share its contour ([`FramedContours::reusing`]): a grid built here takes
    /// over an unchanged obstacle's cells at an unchanged Δᵢ ([`NearGrid::build`]).
    grids_carried: Option<GridsCarried>,
}

/// What [`FramedContours::reusing`] keeps of the previous revision's grids.
#[derive(Debug)]
pub(crate) struct GridsCarried {
    /// Per obstacle, its index in the previous revision (shared contour), if any.
    index: Vec<Option<usize>>,
    /// The previous revision's grids, with their risk levels.
    grids: Vec<(Vec<RiskLevel>, std::sync::Arc<NearGrid>)>,
}

/// One obstacle's box test known before [`FramedContours::near`] builds the others: taken
/// over from the previous revision ([`FramedContours::reusing`]) or built by a call that
/// was stopped (`None`: it has none).
type Carried = Option<Near>;

/// A grid (`None`: not worth building) at a list of per-obstacle risk levels.
type GridEntry = (Vec<RiskLevel>, Option<std::sync::Arc<NearGrid>>);

/// How often a thread that needs the box tests while another thread builds them looks
/// again (and asks its own `stop`): a build takes from a millisecond (an update's few
/// obstacles) to a few tenths of a second (a new scene of hundreds), and the waiting plan's
/// own deadline must still be kept.
pub const NEAR_WAIT_POLL: std::time::Duration = std::time::Duration::from_millis(1);

/// Grids kept per scene (one per list of per-obstacle risk levels), as the covers are.
pub const GRIDS_PER_SCENE: usize = 4;

type FramedPair = OnceLock<(riskplan_math::poly::Poly<Interval>, riskplan_math::poly::Poly<Interval>)>;

/// One obstacle's contour polynomials around a point of its own (`y = x − c`), with
/// interval coefficients: evaluated over a piece's bounding box they bound E\[P\] and
/// E\[P²\] there.
#[derive(Clone, Debug)]
pub struct Near {
    center: Vec<f64>,
    mean: riskplan_math::poly::Poly<Interval>,
    second: riskplan_math::poly::Poly<Interval>,
}

/// What the box tests of one obstacle at one Δ evaluate (`Near::cantelli`).
#[derive(Clone, Debug)]
pub struct NearBound {
    /// g₁ = E\[P\]² − (1−Δ)·E\[P²\], expanded.
    g1: riskplan_math::poly::Poly<Interval>,
    /// Var(P) = E\[P²\] − E\[P\]², expanded.
    var: riskplan_math::poly::Poly<Interval>,
    /// Δ and 1 − Δ, enclosed.
    delta: Interval,
    one_minus_delta: Interval,
}

impl Near {
    /// The point the box tests are written about ([`super::index::obstacle_center`]).
    pub(crate) fn center(&self) -> &[f64] {
        &self.center
    }

    /// The polynomials of the box tests at Δ (1 − Δ enclosed in `one_minus_delta`): the
    /// Cantelli polynomial g₁ = E\[P\]² − (1−Δ)·E\[P²\] around the centre, formed before any
    /// evaluation so that its leading terms cancel symbolically (evaluating E\[P\]² and
    /// E\[P²\] separately over a box cannot prove g₁ > 0 a few box-widths away), and the
    /// variance E\[P²\] − E\[P\]², formed the same way, for the equivalent form
    /// g₁ = Δ·E\[P\]² − (1−Δ)·Var(P).
    fn cantelli(&self, one_minus_delta: Interval) -> NearBound {
        let square = self.mean.mul(&self.mean);
        NearBound {
            g1: square.sub(&self.second.scale(&one_minus_delta)),
            var: self.second.sub(&square),
            delta: Interval::point(1.0) - one_minus_delta,
            one_minus_delta,
        }
    }

    /// Whether both constraints of eq. (15) are proven over the box `bbox × t` by naive
    /// interval evaluation: E\[P\] < 0, and g₁ > 0 either expanded or as
    /// Δ·E\[P\]² − (1−Δ)·Var(P) with E\[P\]² the square of E\[P\]'s enclosure (tight: it
    /// lies below 0) — the expanded g₁ loses its digits to cancellation over a box a few
    /// radii from the obstacle, where E\[P\]² is far above the variance (identical
    /// polynomials, both enclosures sound).
    fn clears(&self, bbox: &[Interval], t: Interval, b: &NearBound) -> bool {
        let mut vals: Vec<Interval> = bbox.iter().zip(&self.center).map(|(&b, &c)| b - Interval::point(c)).collect();
        vals.push(t - Interval::point(self.center[bbox.len()]));
        let mut powers = Powers::new(&vals);
        let m = powers.eval(&self.mean);
        // NaN-safe: a NaN bound is not below 0
        if m.hi.partial_cmp(&0.0) != Some(std::cmp::Ordering::Less) {
            return false;
        }
        if powers.eval(&b.g1).lo > 0.0 {
            return true;
        }
        (b.delta * (m * m) - b.one_minus_delta * powers.eval(&b.var)).lo > 0.0
    }
}

/// The powers of a box's sides for the box tests' evaluations, each formed once and
/// shared by the three polynomials of a test: `w^e` as [`power_range`] forms it (repeated
/// outward-rounded products; an even power of a side that contains 0 from 0), so a
/// polynomial's enclosure is Σ c·Π w_v^e over its terms, sound term by term. (The general
/// `Poly::eval` formed every power of every term anew: most of the final check's time on
/// crowded scenes.)
///
/// [`power_range`]: riskplan_math::contour::bounds::power_range
struct Powers<'a> {
    vals: &'a [Interval],
    /// `chain[v][k]` = w_v^(k+1) by repeated products, for the first `len[v]` exponents.
    chain: [[Interval; Powers::KEPT]; Powers::VARS],
    len: [usize; Powers::VARS],
}

impl<'a> Powers<'a> {
    /// Sides whose powers are kept (space up to 3 dimensions and time).
    const VARS: usize = 4;
    /// Exponents kept per side (higher ones are formed directly).
    const KEPT: usize = 12;

    fn new(vals: &'a [Interval]) -> Self {
        Powers { vals, chain: [[Interval::point(0.0); Self::KEPT]; Self::VARS], len: [0; Self::VARS] }
    }

    /// The enclosure of `w_v^e`.
    fn power(&mut self, v: usize, e: u32) -> Interval {
        let Some(&w) = self.vals.get(v) else { return Interval::new(f64::NEG_INFINITY, f64::INFINITY) };
        let k = e as usize;
        if e == 0 || v >= Self::VARS || k > Self::KEPT {
            return riskplan_math::contour::bounds::power_range(w, e);
        }
        while self.len[v] < k {
            let next = if self.len[v] == 0 { w } else { self.chain[v][self.len[v] - 1] * w };
            self.chain[v][self.len[v]] = next;
            self.len[v] += 1;
        }
        let acc = self.chain[v][k - 1];
        if e % 2 == 0 {
            if w.lo <= 0.0 && w.hi >= 0.0 {
                return Interval::new(0.0, acc.hi.max(0.0));
            }
            return Interval::new(acc.lo.max(0.0), acc.hi);
        }
        acc
    }

    /// The enclosure of `p` over the box.
    fn eval(&mut self, p: &riskplan_math::poly::Poly<Interval>) -> Interval {
        let mut acc = Interval::point(0.0);
        for (m, c) in p.terms() {
            let mut t = *c;
            for &(v, e) in m.pairs() {
                t = t * self.power(v as usize, e);
            }
            acc = acc + t;
        }
        acc
    }
}

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
        let center = super::index::obstacle_center(&o.contour, region);
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
    /// ([`super::SceneKernel::successor`] finds it once for everything it takes over).
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
        let inv_scale = exps.iter().map(|&e| crate::fast::pow2(-e)).collect();
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
    fn restrict(
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
        let r = crate::compose::restrict(m, s, &subs, &one_minus_delta);
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

/// The box tests of a final check: per obstacle its test (if any) and its Cantelli
/// polynomial at its Δᵢ, formed on first use.
pub(crate) type NearTests<'a> = (&'a [Option<Near>], &'a [OnceLock<NearBound>]);

/// 1 − Δ, enclosed (from the exact Δ).
fn one_minus_enclosed(d: &RiskLevel) -> Interval {
    Interval::enclose_rational(&(BigRational::from_integer(1.into()) - d.rational()))
}

/// Whether one piece passes the verify path at one risk level per obstacle: inside the
/// workspace (exact check) and, for every obstacle, both constraints proven positive
/// on the general interval restriction in [`FramedContours`] with the exact rational
/// fallback (the `exact` method of `verify`, without the compiled contours or the
/// covers of the fast path). `only`: the obstacles to examine, when the others are
/// proven clear of the piece already (the final check's [`NearGrid`]); `None`: every one.
#[allow(clippy::too_many_arguments)]
pub fn piece_passes_verify_path(
    scene: &Scene,
    framed: &FramedContours,
    near: Option<NearTests<'_>>,
    pr: PieceRef<'_>,
    deltas: &[RiskLevel],
    bounds: BoundChoice,
    compiled: Option<&super::compiled::CompiledSet>,
    only: Option<&[usize]>,
) -> bool {
    if !pr.is_finite() || check_workspace(&scene.workspace.lower, &scene.workspace.upper, pr).status != Status::Safe {
        return false;
    }
    // the piece's bounding box (outward-rounded Bernstein hull of each coordinate), for
    // the box tests of distant obstacles
    let bbox = near.and_then(|_| interval_hull(pr));
    let parts = std::cell::OnceCell::new();
    let ped_hull = std::cell::OnceCell::new();
    // 1 − Δᵢ enclosed (exact arithmetic), again only when the level differs from the last
    // obstacle's (scenes mostly share one Δ)
    let last: std::cell::Cell<Option<(usize, Interval)>> = std::cell::Cell::new(None);
    let one_minus = |i: usize, d: &RiskLevel| match last.get() {
        Some((prev, om)) if deltas.get(prev) == Some(d) => om,
        _ => {
            let om = one_minus_enclosed(d);
            last.set(Some((i, om)));
            om
        }
    };
    let obstacle_passes = |i: usize| {
        let (Some(o), Some(d)) = (scene.obstacles.get(i), deltas.get(i)) else { return false };
        if let (Some(p), true) = (&o.pedestrian, bounds.beyond_cantelli()) {
            // the tail bound (docs/design.md §3.11): a box test, then exact arithmetic
            let hull = ped_hull.get_or_init(|| interval_hull(pr));
            if hull.as_ref().is_some_and(|h| pedestrian_box_clear(p, d, h, pr.t0, pr.t1)) {
                return true;
            }
            return crate::tail::piece_clear_exact(p, d.rational(), pr).is_safe();
        }
        let omd = one_minus(i, d);
        if let (Some((Some(n), g1)), Some(b)) = (near.map(|(n, c)| (&n[i], &c[i])), &bbox) {
            let g1 = g1.get_or_init(|| n.cantelli(omd));
            if n.clears(b, Interval::new(pr.t0, pr.t1), g1) {
                return true;
            }
            // a long or curved piece: its parts' boxes (they cover the piece)
            if let Some(parts) = parts.get_or_init(|| sub_hulls(pr, FINAL_CHECK_PARTS)) {
                // every part must be cleared; the nearest to the obstacle's point first, as
                // the one most likely not to be (most obstacles that reach this test are
                // decided by the restriction below: their test ends at its first part)
                let gap = |h: &[Interval]| {
                    h.iter().zip(n.center()).map(|(s, &c)| (s.lo - c).max(c - s.hi).max(0.0).powi(2)).sum::<f64>()
                };
                let mut order: [(f64, usize); FINAL_CHECK_PARTS] = [(0.0, 0); FINAL_CHECK_PARTS];
                for (k, slot) in order.iter_mut().enumerate().take(parts.len()) {
                    *slot = (gap(&parts[k].0), k);
                }
                let order = &mut order[..parts.len().min(FINAL_CHECK_PARTS)];
                order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
                if parts.len() <= FINAL_CHECK_PARTS && order.iter().all(|&(_, k)| n.clears(&parts[k].0, parts[k].1, g1))
                {
                    return true;
                }
            }
        }
        let (cantelli, mean) = framed.restrict(i, o, pr, omd);
        let exact = std::cell::OnceCell::new();
        let exact = || exact.get_or_init(|| restrict_exact(&o.contour, pr, d.rational()));
        if !bernstein::check(&mean, || exact().mean.clone()).is_safe() {
            return false;
        }
        match bernstein::check(&cantelli, || exact().cantelli.clone()) {
            Verdict::Safe { .. } => true,
            // the other bounds, on sub-intervals (docs/design.md §5.13): the general
            // composition in absolute coordinates first, then (where that loses too much at
            // extreme scales) the compiled restriction in the scene's frame — either proof
            // is sound; only the general one is independent of the fast path
            v if bounds.beyond_cantelli() => {
                let hint = if let Verdict::Unsafe(w) = v { Some(w.tau) } else { None };
                let level = Level::new(d.rational());
                PieceBounds::for_piece(&o.contour, pr, level).cover(hint).is_ok()
                    || compiled.is_some_and(|set| {
                        let sub = super::super::fast::Substitution::new(pr, set.frame());
                        PieceBounds::for_piece_compiled(&o.contour, set.get(i), pr, level)
                            .with_substitution(sub.as_ref())
                            .cover(hint)
                            .is_ok()
                    })
            }
            _ => false,
        }
    };
    match only {
        Some(examined) => examined.iter().all(|&i| obstacle_passes(i)),
        None => (0..scene.obstacles.len()).all(obstacle_passes),
    }
}

/// Parts in time of a piece whose boxes the final check's box tests try when the whole
/// piece's box meets an obstacle's test region ([`sub_hulls`]).
pub const FINAL_CHECK_PARTS: usize = 8;

/// The piece's `k` parts in time ([`super::index::piece_parts`], which cover it) with each
/// part's hull ([`interval_hull`]) and time interval. `None` when a hull is not available.
fn sub_hulls(pr: PieceRef<'_>, k: usize) -> Option<Vec<(Vec<Interval>, Interval)>> {
    super::index::piece_parts(pr, k)?
        .into_iter()
        .map(|p| Some((interval_hull(p)?, Interval::new(p.t0, p.t1))))
        .collect()
}

/// Whether a pedestrian is cleared for a piece by a box test, in the verify path's own
/// arithmetic (docs/design.md §3.11, §5.12): the piece's hull `hull` (over `[t0, t1]`) and
/// the box of the pedestrian's nominal centre over the same times are farther apart than
/// an upper bound of `reach + κ·√s(t)` there (√s is largest at an end: it is convex).
/// From the template's exact numbers, enclosed; independent of the planners' tail code.
fn pedestrian_box_clear(p: &riskplan_scene::Pedestrian, d: &RiskLevel, hull: &[Interval], t0: f64, t1: f64) -> bool {
    let dim = p.file.position.len();
    let Some(kappa) = riskplan_math::contour::tail::tail_kappa(dim, d.rational()) else { return false };
    if hull.len() != dim {
        return false;
    }
    // the template's numbers, enclosed once (`p.disk`: the stds and the reach rounded up)
    let t_ref = p.disk.t_ref;
    let (sp, sv) = (Interval::new(0.0, p.disk.sigma_p), Interval::new(0.0, p.disk.sigma_v));
    let reach = Interval::new(0.0, p.disk.reach);
    let radius = |t: f64| {
        let tau = Interval::point(t) - t_ref;
        let s = sp * sp + sv * sv * tau * tau;
        // sqrt is correctly rounded: the next float up bounds √s.hi from above
        let sd = s.hi.sqrt().next_up();
        reach + Interval::point(kappa) * Interval::point(sd)
    };
    let r = radius(t0).hi.max(radius(t1).hi);
    if !r.is_finite() {
        return false;
    }
    let (ta, tb) = (Interval::point(t0) - t_ref, Interval::point(t1) - t_ref);
    let mut gap2 = Interval::point(0.0);
    for (i, side) in hull.iter().enumerate() {
        let (pi, vi) = (p.disk.position[i], p.disk.velocity[i]);
        let (ca, cb) = (pi + vi * ta, pi + vi * tb);
        let (lo, hi) = (ca.lo.min(cb.lo), ca.hi.max(cb.hi));
        // a lower bound of the gap between [lo, hi] and the hull's side
        let g = if side.lo > hi {
            (Interval::point(side.lo) - Interval::point(hi)).lo.max(0.0)
        } else if lo > side.hi {
            (Interval::point(lo) - Interval::point(side.hi)).lo.max(0.0)
        } else {
            0.0
        };
        gap2 = gap2 + Interval::point(g) * Interval::point(g);
    }
    gap2.lo > (Interval::point(r) * Interval::point(r)).hi
}

/// The final check's own spatial filter on crowded scenes (docs/design.md §5.12): a grid of
/// cells over the workspace and, per cell, the obstacles its box test (`Near::clears`)
/// does not clear over the whole cell and the whole horizon. A piece whose parts' hulls lie
/// in cells where an obstacle is cleared is safe from it at every point and time (each point
/// of the piece lies in one of those cells, its time in the horizon): only the obstacles of
/// the cells its parts' hulls meet are examined. Built from the final check's box tests
/// alone (nothing of the planners' covers), per list of risk levels, asking `stop`.
#[derive(Debug)]
pub struct NearGrid {
    /// Per axis, the cell edges `e_0 ≤ … ≤ e_n` (cell `k` is `[e_k, e_{k+1}]`; neighbours
    /// share the very same float, so the cells leave no gap).
    edges: Vec<Vec<f64>>,
    /// Cells per axis (a power of two).
    per_axis: usize,
    /// Per cell (row-major, axis 0 slowest), the obstacles not cleared there.
    cells: Vec<Vec<u32>>,
    /// Obstacles without a box test, or whose test clears too little to be worth its cells:
    /// examined on every piece.
    always: Vec<u32>,
    /// Obstacles in the scene.
    obstacles: usize,
    /// Each obstacle's box-test polynomials at its Δᵢ (`Near::cantelli`): formed by the
    /// build for the obstacles it tests, on first use for the others; the final checks at
    /// these risk levels use them too.
    pub bounds: Vec<OnceLock<NearBound>>,
    /// Per obstacle, what the build's box tests found (`None`: not tested — no box test,
    /// or moving), for the next revision's grid ([`GridsCarried`]).
    tested: Vec<Option<Tested>>,
}

/// What [`NearGrid::build`] found for one obstacle it tested.
#[derive(Clone, Debug)]
enum Tested {
    /// The cells its box test did not clear.
    Cells(Vec<usize>),
    /// It used up [`GRID_MAX_TESTS_PER_OBSTACLE`]: examined on every piece.
    GaveUp,
}

/// Fewest obstacles for which the final check builds its grid ([`NearGrid`]): with fewer,
/// one box test per obstacle and piece costs less than the grid (a few tens of box tests per
/// obstacle, once per scene and risk allocation).
pub const GRID_MIN_OBSTACLES: usize = 64;

/// Most cells of the grid in all (16 384: 128² in the plane, 16³ in space).
pub const GRID_MAX_CELLS: usize = 1 << 14;

/// Cells per axis per `n^(1/dim)` obstacles: about two cells across per obstacle spacing,
/// so that an obstacle's uncleared cells are a few, and a short piece meets a few cells.
pub const GRID_CELLS_PER_SPACING: f64 = 2.0;

/// Most box tests spent on one obstacle's cells: an obstacle that needs more (its region
/// of doubt covers much of the workspace, or the box tests lose their digits at the scene's
/// scale) is examined on every piece instead. A static disk of the benchmark family needs
/// about 50.
pub const GRID_MAX_TESTS_PER_OBSTACLE: usize = 256;

/// After this many obstacles tested, the grid is abandoned (the final check examines every
/// obstacle, as without it) when more than half of them used up their tests: the grid would
/// cost more than it saves (where nearly every obstacle gives up, building the grid takes
/// far longer than its lookups spare).
pub const GRID_ABANDON_AFTER: usize = 16;

/// Most parts of a piece looked up in the grid: a piece is split into about as many parts
/// as the cells it spans along its widest axis (each part's hull then meets few cells).
pub const GRID_MAX_PARTS: usize = 64;

/// Most cells a piece's parts may meet before the grid is not used for it (every obstacle
/// examined instead, as without a grid).
pub const GRID_MAX_CELLS_PER_PIECE: usize = 4096;

impl NearGrid {
    /// Builds the grid for the box tests `near` at risk levels `deltas` (`Ok(None)`: not
    /// worth it, [`GRID_ABANDON_AFTER`]; `Err` when `stop` says stop first). Moving
    /// obstacles get no cells (tested over the whole horizon they sweep the workspace):
    /// they are examined on every piece.
    pub(crate) fn build(
        scene: &Scene,
        near: &[Option<Near>],
        deltas: &[RiskLevel],
        carried: Option<&GridsCarried>,
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<NearGrid>, Interrupted> {
        let dim = scene.dim;
        let ws = &scene.workspace;
        let spacing_cells = GRID_CELLS_PER_SPACING * (scene.obstacles.len() as f64).powf(1.0 / dim as f64);
        let max_per_axis = (GRID_MAX_CELLS as f64).powf(1.0 / dim as f64).floor() as usize;
        let mut per_axis = 1usize;
        while per_axis < spacing_cells as usize && per_axis * 2 <= max_per_axis.max(1) {
            per_axis *= 2;
        }
        let edges: Vec<Vec<f64>> = (0..dim)
            .map(|d| {
                let (lo, hi) = (ws.lower[d], ws.upper[d]);
                let w = hi - lo;
                // k/n is exact (n a power of two) and the products and sums are monotone in k;
                // the ends are the workspace's own bounds
                (0..=per_axis)
                    .map(|k| match k {
                        0 => lo,
                        k if k == per_axis => hi,
                        k => (lo + w * (k as f64 / per_axis as f64)).min(hi),
                    })
                    .collect()
            })
            .collect();
        let total = per_axis.pow(dim as u32);
        let mut grid = NearGrid {
            edges,
            per_axis,
            cells: vec![Vec::new(); total],
            always: Vec::new(),
            obstacles: near.len(),
            bounds: near.iter().map(|_| OnceLock::new()).collect(),
            tested: vec![None; near.len()],
        };
        // the previous revision's grids of the same cells: an unchanged obstacle (the same
        // box test) at the same Δᵢ has the same cells there (the same tests, the same
        // horizon: FramedContours::reusing compared the region)
        let same_cells =
            |g: &NearGrid| g.per_axis == grid.per_axis && g.edges == grid.edges && g.tested.len() == g.obstacles;
        let old_grids: Vec<&(Vec<RiskLevel>, std::sync::Arc<NearGrid>)> =
            carried.map(|c| c.grids.iter().filter(|(_, g)| same_cells(g)).collect()).unwrap_or_default();
        let take_over = |i: usize| -> Option<(Tested, Option<NearBound>)> {
            let j = (*carried?.index.get(i)?)?;
            old_grids.iter().find_map(|(d, g)| {
                (d.get(j)? == deltas.get(i)?).then_some(())?;
                Some((g.tested.get(j)?.clone()?, g.bounds.get(j)?.get().cloned()))
            })
        };
        let horizon = Interval::new(scene.horizon.0, scene.horizon.1);
        let (mut tested, mut gave_up_on) = (0usize, 0usize);
        for (i, (n, d)) in near.iter().zip(deltas).enumerate() {
            if stop() {
                return Err(Interrupted);
            }
            if tested >= GRID_ABANDON_AFTER && 2 * gave_up_on > tested {
                return Ok(None);
            }
            let Some(n) = n.as_ref().filter(|_| !scene.obstacles[i].is_dynamic()) else {
                grid.always.push(i as u32);
                continue;
            };
            tested += 1;
            // an unchanged obstacle's cells from the previous revision's grid, else its own
            let found = match take_over(i) {
                Some((found, bound)) => {
                    if let Some(b) = bound {
                        let _ = grid.bounds[i].set(b);
                    }
                    found
                }
                None => {
                    let g1 = grid.bounds[i].get_or_init(|| n.cantelli(one_minus_enclosed(d)));
                    grid.cells_of(n, g1, horizon)
                }
            };
            match &found {
                Tested::Cells(cells) => cells.iter().for_each(|&c| grid.cells[c].push(i as u32)),
                Tested::GaveUp => {
                    gave_up_on += 1;
                    grid.always.push(i as u32);
                }
            }
            grid.tested[i] = Some(found);
        }
        // a grid that examines most obstacles on every piece anyway saves nothing
        Ok((2 * grid.always.len() <= grid.obstacles).then_some(grid))
    }

    /// The cells a static obstacle's box test (`g1` its Cantelli polynomial at its Δᵢ)
    /// does not clear over the whole horizon, by dyadic subdivision of the cell blocks;
    /// [`Tested::GaveUp`] past [`GRID_MAX_TESTS_PER_OBSTACLE`] tests.
    fn cells_of(&self, n: &Near, g1: &NearBound, horizon: Interval) -> Tested {
        let dim = self.edges.len();
        let mut marked = Vec::new();
        let mut tests = 0usize;
        let mut stack = vec![(vec![0usize; dim], vec![self.per_axis; dim])];
        while let Some((lo, hi)) = stack.pop() {
            tests += 1;
            if tests > GRID_MAX_TESTS_PER_OBSTACLE {
                return Tested::GaveUp;
            }
            let cell_box: Vec<Interval> =
                (0..dim).map(|a| Interval::new(self.edges[a][lo[a]], self.edges[a][hi[a]])).collect();
            if n.clears(&cell_box, horizon, g1) {
                continue;
            }
            // the widest axis of the block, halved; a single cell is marked
            let (axis, width) = (0..dim).map(|a| (a, hi[a] - lo[a])).max_by_key(|&(_, w)| w).unwrap_or((0, 1));
            if width <= 1 {
                marked.push(self.cell_index(&lo));
                continue;
            }
            let mid = lo[axis] + width / 2;
            let (mut lo2, mut hi1) = (lo.clone(), hi.clone());
            lo2[axis] = mid;
            hi1[axis] = mid;
            stack.push((lo2, hi));
            stack.push((lo, hi1));
        }
        Tested::Cells(marked)
    }

    fn cell_index(&self, k: &[usize]) -> usize {
        k.iter().fold(0, |acc, &v| acc * self.per_axis + v)
    }

    /// The cells `[k_lo, k_hi]` per axis that cover `hull` (`None` when it leaves the grid).
    fn cell_range(&self, hull: &[Interval]) -> Option<Vec<(usize, usize)>> {
        if hull.len() != self.edges.len() {
            return None;
        }
        hull.iter()
            .zip(&self.edges)
            .map(|(h, e)| {
                let n = e.len() - 1;
                if !(h.lo >= e[0] && h.hi <= e[n]) {
                    return None;
                }
                // the last cell starting at or below lo, the first ending at or above hi
                let lo = e.partition_point(|&x| x <= h.lo).saturating_sub(1).min(n - 1);
                let hi = e.partition_point(|&x| x < h.hi).saturating_sub(1).clamp(lo, n - 1);
                Some((lo, hi))
            })
            .collect()
    }

    /// Each side of a hull clamped to the grid (the workspace): sound for a piece inside
    /// the workspace, and only such a piece is ever judged by its candidates (the caller's
    /// exact workspace check rejects any other first). The outward rounding of a hull
    /// touching a wall would otherwise leave the grid by an ulp.
    fn hull_in_grid(&self, pr: PieceRef<'_>) -> Option<Vec<Interval>> {
        let hull = interval_hull(pr)?;
        if hull.len() != self.edges.len() {
            return None;
        }
        hull.iter()
            .zip(&self.edges)
            .map(|(h, e)| {
                let (a, b) = (e[0], e[e.len() - 1]);
                // a NaN side stays NaN (and leaves the grid); a side wholly outside, too
                (h.lo <= b && h.hi >= a).then(|| Interval { lo: h.lo.max(a), hi: h.hi.min(b) })
            })
            .collect()
    }

    /// The obstacles a piece inside the workspace must be examined against (sorted, without
    /// repeats), or `None` when the grid does not help (a hull that is not available, or too
    /// many cells): then every obstacle.
    pub fn candidates(&self, pr: PieceRef<'_>) -> Option<Vec<usize>> {
        let whole = self.hull_in_grid(pr)?;
        let range = self.cell_range(&whole)?;
        let span = range.iter().map(|(a, b)| b - a + 1).max().unwrap_or(1);
        let parts = if span <= 1 { vec![pr] } else { super::index::piece_parts(pr, span.min(GRID_MAX_PARTS))? };
        let mut seen = vec![false; self.obstacles];
        let mut out: Vec<usize> = self.always.iter().map(|&i| i as usize).collect();
        for &i in &out {
            seen[i] = true;
        }
        let mut cells_met = 0usize;
        for p in parts {
            let r = if span <= 1 { range.clone() } else { self.cell_range(&self.hull_in_grid(p)?)? };
            let count: usize = r.iter().map(|(a, b)| b - a + 1).product();
            cells_met += count;
            if cells_met > GRID_MAX_CELLS_PER_PIECE {
                return None;
            }
            let mut k: Vec<usize> = r.iter().map(|(a, _)| *a).collect();
            'cells: loop {
                for &o in &self.cells[self.cell_index(&k)] {
                    if !seen[o as usize] {
                        seen[o as usize] = true;
                        out.push(o as usize);
                    }
                }
                // the next cell of the block (odometer, last axis fastest)
                for a in (0..k.len()).rev() {
                    if k[a] < r[a].1 {
                        k[a] += 1;
                        continue 'cells;
                    }
                    k[a] = r[a].0;
                }
                break;
            }
        }
        out.sort_unstable();
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    /// A scene, its grid, and its disks' nominal centres.
    type Crowded = (Scene, NearGrid, Vec<(f64, f64)>);

    /// 96 uncertain disks (radius scaled by s ~ U(0.9, 1.1), centre shifted by d ~ N(0, 0.05))
    /// at constant density in a square 10·√96 wide, and the grid at Δ = 0.05.
    fn crowded() -> &'static Crowded {
        static S: OnceLock<Crowded> = OnceLock::new();
        S.get_or_init(|| {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
            let n = 96;
            let side = 10.0 * (n as f64).sqrt();
            let mut params = serde_json::Map::new();
            let mut obstacles = Vec::new();
            let mut centres = Vec::new();
            for k in 0..n {
                let (cx, cy, r): (f64, f64, f64) =
                    (rng.random_range(0.0..side), rng.random_range(0.0..side), rng.random_range(0.8..1.6));
                centres.push((cx, cy));
                params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
                params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
                obstacles.push(serde_json::json!({
                    "id": format!("disk{k}"),
                    "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - {cy})^2"),
                }));
            }
            let text = serde_json::json!({
                "format": "riskplan-scene/1", "name": "crowded", "dim": 2,
                "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
                "params": params, "obstacles": obstacles,
            })
            .to_string();
            let scene = Scene::from_json(&text).unwrap();
            let framed = FramedContours::new(&scene);
            let near = framed.near(&scene, &|| false).unwrap().expect("box tests on 96 disks");
            let deltas = vec![scene.risk.clone(); n];
            let grid = NearGrid::build(&scene, near, &deltas, None, &|| false).unwrap().expect("a grid worth building");
            (scene, grid, centres)
        })
    }

    /// Distance from a disk's centre beyond which the test's disks are safe (see below).
    const FAR: f64 = 8.0;

    /// Sampled times per piece.
    const SAMPLES: usize = 64;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Every obstacle the grid leaves out of a piece's candidates is safe at every sampled
        /// point of the piece, by exact rational evaluation of E[P] and E[P²] (no code of the
        /// grid or of the box tests): E[P] < 0 and E[P]² − (1 − Δ)·E[P²] > 0 (eq. 15). Points
        /// farther than [`FAR`] from a disk's centre are safe by its geometry (radius at most
        /// 1.6·1.1, a centre within a few 0.05 of nominal: Cantelli holds beyond about three
        /// radii) and are not evaluated.
        #[test]
        fn obstacles_left_out_by_the_grid_are_safe_on_the_piece(
            a in prop::collection::vec(0.0f64..1.0, 2),
            b in prop::collection::vec(0.0f64..1.0, 2),
            bend in prop::collection::vec(-0.2f64..0.2, 2),
            t0 in 0.0f64..0.5,
            len in 1e-3f64..0.5,
        ) {
            let side = crowded().0.workspace.upper[0];
            let p: Vec<f64> = a.iter().map(|v| v * side).collect();
            let q: Vec<f64> = b.iter().map(|v| v * side).collect();
            let c: Vec<f64> = bend.iter().map(|v| v * side).collect();
            check_left_out(&p, &q, &c, t0, len)?;
        }

        /// The same on short pieces near an obstacle, sampled densely: where the thin ring
        /// in which E[P] < 0 but Cantelli fails lies (a box test that dropped the variance
        /// term clears cells there).
        #[test]
        fn obstacles_left_out_near_a_piece_are_safe_on_it(
            k in 0usize..96,
            a in prop::collection::vec(-4.0f64..4.0, 2),
            dir in prop::collection::vec(-3.0f64..3.0, 2),
            bend in prop::collection::vec(-0.5f64..0.5, 2),
            t0 in 0.0f64..0.5,
            len in 1e-3f64..0.5,
        ) {
            let centre = crowded().2[k];
            let p = vec![centre.0 + a[0], centre.1 + a[1]];
            let q = vec![p[0] + dir[0], p[1] + dir[1]];
            check_left_out(&p, &q, &bend, t0, len)?;
        }
    }

    /// Every obstacle the grid leaves out of the quadratic from `p` to `q` bent by `c` over
    /// `[t0, t0 + len]` is safe at its sampled points inside the workspace (exact rationals).
    fn check_left_out(p: &[f64], q: &[f64], c: &[f64], t0: f64, len: f64) -> Result<(), TestCaseError> {
        {
            use num_rational::BigRational;
            let (scene, grid, centres) = crowded();
            let side = scene.workspace.upper[0];
            let t1 = t0 + len;
            // a quadratic from p to q, local τ in [0, 1], written in absolute time t:
            // x(t) = p0 + p1·τ + p2·τ², τ = (t − t0)/len
            let coeffs: Vec<Vec<f64>> = (0..2)
                .map(|d| {
                    let (p, q, c) = (p[d], q[d], c[d]);
                    let (p0, p1, p2) = (p, q - p + c, -c);
                    // in t: p0 + p1 (t − t0)/len + p2 (t − t0)²/len²
                    let (u, v) = (1.0 / len, 1.0 / (len * len));
                    vec![p0 - p1 * t0 * u + p2 * t0 * t0 * v, p1 * u - 2.0 * p2 * t0 * v, p2 * v]
                })
                .collect();
            let pr = PieceRef { t0, t1, coeffs: &coeffs };
            let Some(cands) = grid.candidates(pr) else { return Ok(()) };
            let delta = scene.risk.rational();
            let omd = BigRational::from_integer(1.into()) - delta;
            let zero = BigRational::from_integer(0.into());
            for (i, o) in scene.obstacles.iter().enumerate() {
                if cands.binary_search(&i).is_ok() {
                    continue;
                }
                for s in 0..=SAMPLES {
                    let t = (t0 + len * s as f64 / SAMPLES as f64).clamp(t0, t1);
                    let at: Vec<f64> =
                        coeffs.iter().map(|row| row.iter().rev().fold(0.0, |acc, &c| acc * t + c)).collect();
                    if (at[0] - centres[i].0).hypot(at[1] - centres[i].1) > FAR {
                        continue;
                    }
                    let tq = BigRational::from_float(t).unwrap();
                    let mut x: Vec<BigRational> = coeffs
                        .iter()
                        .map(|row| {
                            row.iter()
                                .rev()
                                .fold(zero.clone(), |acc, &c| acc * &tq + BigRational::from_float(c).unwrap())
                        })
                        .collect();
                    // a point outside the workspace is not what the grid speaks of
                    if x.iter().any(|v| *v < zero || *v > BigRational::from_float(side).unwrap()) {
                        continue;
                    }
                    x.push(tq);
                    let m = o.contour.mean.eval(&x);
                    let m2 = o.contour.second.eval(&x);
                    prop_assert!(m < zero, "obstacle {} left out, E[P] = {} at t = {}", i, m, t);
                    prop_assert!(&m * &m - &omd * &m2 > zero, "obstacle {} left out, Cantelli fails at t = {}", i, t);
                }
            }
        }
        Ok(())
    }

    /// Every cell that leaves an obstacle out is safe from it everywhere: a 16 × 16 lattice of
    /// points of each such cell near the obstacle (edges included), its E[P] and E[P²] in
    /// floating point, and wherever either constraint is not clearly met (a margin far above
    /// the rounding of these small polynomials), exactly in rationals. Fails when the box
    /// test drops its variance term (it then clears cells that the ring between E[P] = 0 and
    /// the Cantelli contour crosses).
    #[test]
    fn cleared_cells_are_safe_everywhere_in_them() {
        use num_rational::BigRational;
        let (scene, grid, centres) = crowded();
        let n = grid.per_axis;
        let one = BigRational::from_integer(1.into());
        let zero = BigRational::from_integer(0.into());
        let omd_q = &one - scene.risk.rational();
        let omd = 1.0 - scene.risk.to_f64();
        const LATTICE: usize = 16;
        const MARGIN: f64 = 1e-6;
        let mut exact_checks = 0;
        for (i, o) in scene.obstacles.iter().enumerate() {
            if grid.always.contains(&(i as u32)) {
                continue;
            }
            for cx in 0..n {
                for cy in 0..n {
                    let cell = grid.cell_index(&[cx, cy]);
                    if grid.cells[cell].contains(&(i as u32)) {
                        continue;
                    }
                    let (x0, x1, y0, y1) =
                        (grid.edges[0][cx], grid.edges[0][cx + 1], grid.edges[1][cy], grid.edges[1][cy + 1]);
                    let nearest =
                        (centres[i].0.clamp(x0, x1) - centres[i].0).hypot(centres[i].1.clamp(y0, y1) - centres[i].1);
                    if nearest > FAR {
                        continue;
                    }
                    for a in 0..=LATTICE {
                        for b in 0..=LATTICE {
                            let x = if a == LATTICE { x1 } else { x0 + (x1 - x0) * a as f64 / LATTICE as f64 };
                            let y = if b == LATTICE { y1 } else { y0 + (y1 - y0) * b as f64 / LATTICE as f64 };
                            let (m, m2) = o.contour.moments_f64(&[x, y, 0.5]);
                            let scale = m2.abs().max(1.0);
                            if m < -MARGIN * scale && m * m - omd * m2 > MARGIN * scale * scale {
                                continue;
                            }
                            exact_checks += 1;
                            let v: Vec<BigRational> =
                                [x, y, 0.5].iter().map(|&c| BigRational::from_float(c).unwrap()).collect();
                            let (mq, m2q) = (o.contour.mean.eval(&v), o.contour.second.eval(&v));
                            assert!(mq < zero, "obstacle {i} left out of cell ({cx}, {cy}): E[P] = {mq} at ({x}, {y})");
                            assert!(
                                &mq * &mq - &omd_q * &m2q > zero,
                                "obstacle {i} left out of cell ({cx}, {cy}): Cantelli fails at ({x}, {y})"
                            );
                        }
                    }
                }
            }
        }
        println!("{exact_checks} lattice points decided exactly");
    }

    /// The grid leaves out most obstacles of a short piece (else it would not pay), and keeps
    /// the obstacle a piece runs through.
    #[test]
    fn the_grid_keeps_what_a_piece_meets_and_drops_the_rest() {
        let (scene, grid, _) = crowded();
        let o = &scene.obstacles[0];
        // obstacle 0's centre: where its mean is largest on its box-test point
        let c = obstacle_point(scene, 0);
        let coeffs = vec![vec![c[0] - 0.5, 1.0], vec![c[1], 0.0]];
        let pr = PieceRef { t0: 0.0, t1: 1.0, coeffs: &coeffs };
        let cands = grid.candidates(pr).expect("a piece inside the grid");
        assert!(cands.contains(&0), "{}: {cands:?}", o.id);
        assert!(cands.len() < scene.obstacles.len() / 4, "{} candidates of {}", cands.len(), scene.obstacles.len());
    }

    fn obstacle_point(scene: &Scene, i: usize) -> Vec<f64> {
        let ws = &scene.workspace;
        let region = vec![(ws.lower[0], ws.upper[0]), (ws.lower[1], ws.upper[1]), scene.horizon];
        super::super::index::obstacle_center(&scene.obstacles[i].contour, &region)
    }
}
