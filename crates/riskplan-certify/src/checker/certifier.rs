//! The scene certifier: the continuous-time certifier as a planner's motion checker
//! (docs/design.md §5.9, §5.10).

use super::cover_index::{piece_bbox, piece_sub_boxes, SceneIndex, LAZY_MAX_OBSTACLES};
use super::decide::{combine, point_obstacle_safe_at, point_status, Method, PointStatus, Status};
use super::kernel::{CompiledSet, SceneKernel};
use super::verify_path::piece_passes_verify_path;
use super::workspace::{check_workspace, inside_by_box};
use crate::compiled::Substitution;
use crate::piece_bounds::{BoundPart, CoverFailure, Level, PieceBounds};
use crate::{gaussian_tail, positivity::bernstein, positivity::sos, restrict_exact, PieceRef, Verdict};
use num_rational::BigRational;
use riskplan_math::contour::tail::tail_kappa;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_math::poly::Interval;
use riskplan_scene::motion::{Motion, MotionChecker, Termination};
use riskplan_scene::{Piece, Scene};
use std::sync::{Arc, OnceLock};

/// The continuous-time certifier as a planner's motion checker: a piece is accepted
/// only when every constraint of every obstacle is proven positive on the piece and
/// the piece stays in the workspace. Stops at the first failure; the lower-degree
/// mean constraint is tried first.
///
/// Fast path (docs/design.md §5.10): the workspace is proven from the piece's
/// Bernstein bounding box (exact check otherwise); obstacles whose proven cover the
/// box misses are skipped ([`SceneIndex`]); the rest are decided on the compiled
/// restriction, with the exact rational fallback for undecided cases.
///
/// Each obstacle may have its own risk level Δᵢ (the joint risk mode: Σ Δᵢ = Δ bounds
/// the probability of colliding with any obstacle, by Boole's inequality).
#[derive(Debug)]
pub struct SceneCertifier {
    kernel: SceneKernel,
    scene: Arc<Scene>,
    deltas: Vec<RiskLevel>,
    one_minus: Vec<(f64, bool)>,
    method: Method,
    settings: sos::SosSettings,
    compiled: Arc<CompiledSet>,
    index: OnceLock<Arc<SceneIndex>>,
    /// Whether the fast path (covers, compiled restriction) is used; without it every
    /// obstacle is decided on every piece by the verify path (the final check's).
    fast: bool,
    /// Which bounds may prove a piece (docs/design.md §5.13).
    bounds: BoundChoice,
    /// Each obstacle's Δᵢ as the cover search uses it, converted once.
    levels: Vec<Level>,
    /// Each pedestrian's tail threshold κ at its Δᵢ (docs/design.md §3.11).
    kappas: Vec<Option<f64>>,
    /// Whether the checker builds covers (all at once on large scenes, each obstacle's
    /// on demand on small ones: [`LAZY_MAX_OBSTACLES`]).
    build_covers: bool,
    /// Checking work done ([`MotionChecker::work`]): one per piece, one per obstacle decided.
    work: std::sync::atomic::AtomicU64,
    /// Whether [`MotionChecker::path_risk`] answers (`risk_mode: trajectory`), and the
    /// partition's effort for it.
    path_risk: Option<crate::whole_path::CellEffort>,
}

/// Boxes of the parameter partition per obstacle and piece when planners ask for a piece's
/// whole-path bound: a tenth of a report's (`CellEffort::REPORT`); a grazing piece costs
/// about a millisecond.
pub const PLAN_PATH_RISK_BOXES: usize = 400;

impl SceneCertifier {
    /// A certifier for a scene (or its [`SceneKernel`], to share what it caches) at risk
    /// `delta` for every obstacle.
    pub fn new(scene: impl Into<SceneKernel>, delta: RiskLevel, method: Method) -> Self {
        let kernel = scene.into();
        let deltas = vec![delta; kernel.scene().obstacles.len()];
        Self::with_deltas(kernel, deltas, method)
    }

    /// A certifier with one risk level per obstacle (`deltas[i]` for obstacle `i`).
    pub fn with_deltas(scene: impl Into<SceneKernel>, deltas: Vec<RiskLevel>, method: Method) -> Self {
        let kernel = scene.into();
        let scene = kernel.scene().clone();
        assert_eq!(deltas.len(), scene.obstacles.len(), "one risk level per obstacle");
        // each distinct level converted once (exact arithmetic: on 512 obstacles at one Δ,
        // converting every copy cost half a millisecond per plan)
        let mut last: Option<(&RiskLevel, (f64, bool), Level)> = None;
        let (one_minus, levels): (Vec<(f64, bool)>, Vec<Level>) = deltas
            .iter()
            .map(|d| {
                if let Some((prev, om, level)) = &last {
                    if *prev == d {
                        return (*om, *level);
                    }
                }
                let q = BigRational::from_integer(1.into()) - d.rational();
                let f = riskplan_math::poly::rational_to_f64(&q);
                let om = (f, BigRational::from_float(f).is_some_and(|e| e == q));
                let level = Level::new(d.rational());
                last = Some((d, om, level));
                (om, level)
            })
            .unzip();
        let compiled = kernel.compiled();
        let kappas = scene
            .obstacles
            .iter()
            .zip(&deltas)
            .map(|(o, d)| o.pedestrian.as_ref().and_then(|p| tail_kappa(p.disk.dim(), d.rational())))
            .collect();
        SceneCertifier {
            kernel,
            scene,
            deltas,
            one_minus,
            method,
            settings: sos::SosSettings::default(),
            compiled,
            index: OnceLock::new(),
            fast: true,
            bounds: BoundChoice::default(),
            levels,
            kappas,
            build_covers: true,
            work: Default::default(),
            path_risk: None,
        }
    }

    /// The same certifier answering [`MotionChecker::path_risk`] (`risk_mode: trajectory`),
    /// the partition working until its undecided probability is within 5 % of its bound
    /// or below `negligible` (planners pass a small fraction of Δ).
    pub fn with_path_risk(mut self, negligible: f64) -> Self {
        use crate::whole_path::CellEffort;
        self.path_risk = Some(CellEffort { max_boxes: PLAN_PATH_RISK_BOXES, rel_tol: 0.05, abs_tol: negligible });
        self
    }

    /// The same certifier with another choice of bounds (`auto` by default).
    pub fn with_bounds(mut self, bounds: BoundChoice) -> Self {
        self.bounds = bounds;
        self
    }

    /// The same certifier with other SOS settings (the `sos` and `both` methods).
    pub fn with_settings(mut self, settings: sos::SosSettings) -> Self {
        self.settings = settings;
        self
    }

    /// The bounds it may use.
    pub fn bounds(&self) -> BoundChoice {
        self.bounds
    }

    /// The same certifier without the fast path: every obstacle on every piece by the
    /// verify path (general interval composition, exact fallback) — what a plan is
    /// re-planned with after the final check disagreed with the fast path
    /// (docs/design.md §5.12).
    pub fn without_fast_path(mut self) -> Self {
        self.fast = false;
        self
    }

    /// A certifier that does not build covers for its own use: it uses the scene's
    /// cached index when there is one and otherwise checks every obstacle on every
    /// piece (sound either way). For planners that check a handful of pieces, for
    /// which building the covers (milliseconds per moving obstacle) would cost more
    /// than it saves.
    pub fn without_index_build(mut self) -> Self {
        let index = self
            .kernel
            .peek_index(&self.deltas)
            .unwrap_or_else(|| Arc::new(SceneIndex::lazy(&self.scene, &self.deltas, &[])));
        let _ = self.index.set(index);
        self.build_covers = false;
        self
    }

    /// The per-obstacle risk levels.
    pub fn deltas(&self) -> &[RiskLevel] {
        &self.deltas
    }

    /// The index, built (without interruption) if [`MotionChecker::prepare`] did not:
    /// on a scene of fewer than `LAZY_MAX_OBSTACLES` obstacles with the covers built on
    /// demand (docs/design.md §5.10).
    pub fn index(&self) -> &Arc<SceneIndex> {
        self.index_until(&|| false)
    }

    fn index_until(&self, stop: &(dyn Fn() -> bool + Sync)) -> &Arc<SceneIndex> {
        self.index.get_or_init(|| {
            if self.scene.obstacles.len() < LAZY_MAX_OBSTACLES {
                self.kernel.lazy_index(&self.deltas)
            } else {
                // a plan's first check on a crowded scene waits for every cover: built on
                // the rayon pool's threads, one per core (the service's warm-up builds them
                // on one thread beforehand, `app::warm_up`)
                let cores = rayon::current_num_threads();
                self.kernel.index_on(&self.deltas, stop, cores)
            }
        })
    }

    /// Whether obstacle `i` is proven safe on a piece (`subs`: the piece's centred
    /// coordinates, shared by all obstacles): [`SceneCertifier::decide_obstacle`]
    /// stopping at the first constraint that fails.
    pub fn obstacle_safe(&self, i: usize, pr: PieceRef<'_>, subs: Option<&Substitution>) -> bool {
        let o = &self.scene.obstacles[i];
        if let (Some(p), true) = (&o.pedestrian, self.bounds.beyond_cantelli()) {
            // a pedestrian: its Gaussian tail bound (docs/design.md §3.11)
            return self.kappas[i].is_some_and(|k| gaussian_tail::piece_clear(&p.disk, k, pr).is_safe());
        }
        self.decide_obstacle(i, pr, subs, false, &mut |_, _| {}).is_safe()
    }

    /// Decides obstacle `i` (not a pedestrian under `auto` bounds: its tail bound decides
    /// those) on a piece, as the motion checker does (docs/design.md §5.10, §5.13):
    /// Cantelli's two constraints of eq. (15) — the mean first — on the compiled
    /// restriction (`subs`: the piece's coordinates in the compiled frame) by the
    /// certifier's method, the Exact method with the exact rational fallback where the
    /// floats leave a constraint undecided; and when only g₁ fails and the bounds are
    /// `auto`, a cover of the piece by the other bounds on sub-intervals. Each
    /// constraint's verdicts go to `visit`; with `every` both constraints are decided
    /// even when the first fails (the verify report shows both).
    pub fn decide_obstacle(
        &self,
        i: usize,
        pr: PieceRef<'_>,
        subs: Option<&Substitution>,
        every: bool,
        visit: &mut Visit<'_>,
    ) -> ObstacleFinding {
        let mut found = CantelliFindings::default();
        if self.cantelli_compiled(i, pr, subs, every, visit, &mut found).is_none() {
            self.cantelli_general(i, pr, subs, every, visit, &mut found);
        }
        if found.mean_failed {
            return ObstacleFinding::NotProven(None);
        }
        let Some(hint) = found.g1_failed else { return ObstacleFinding::Proven };
        if !self.bounds.beyond_cantelli() {
            return ObstacleFinding::NotProven(None);
        }
        self.cover_beyond_cantelli(i, pr, subs, hint, found.restricted)
    }

    /// Cantelli's constraints of obstacle `i` on the compiled fast path (the exact
    /// method with the piece's substitution): decided in floats, and where undecided in
    /// exact rationals (the piece restricted once for both); `None` when the fast path
    /// does not apply (the general path decides then).
    fn cantelli_compiled(
        &self,
        i: usize,
        pr: PieceRef<'_>,
        subs: Option<&Substitution>,
        every: bool,
        visit: &mut Visit<'_>,
        found: &mut CantelliFindings,
    ) -> Option<()> {
        if self.method != Method::Exact {
            return None;
        }
        let (o, delta) = (&self.scene.obstacles[i], self.deltas[i].rational());
        // the fast path's enclosures of −E[P] and g₁ when g₁ fails there, for the other
        // bounds' search (the same polynomials it would restrict again)
        let keep = self.bounds.beyond_cantelli() && self.fast;
        self.compiled.get(i).with_constraints(subs?, self.one_minus[i], |g2, g1| {
            // undecided in floats: the exact rational check, restricted once for both
            let exact = std::cell::OnceCell::new();
            for (name, g) in [("mean", g2), ("cantelli", g1)] {
                let v = match bernstein::check_interval_coeffs(g, bernstein::DEFAULT_MAX_DEPTH) {
                    Verdict::Undecided(_) => {
                        let r = exact.get_or_init(|| restrict_exact(&o.contour, pr, delta));
                        let p = if name == "mean" { &r.mean } else { &r.cantelli };
                        bernstein::check_exact(p, bernstein::DEFAULT_MAX_DEPTH)
                    }
                    decided => decided,
                };
                found.note(name, &v);
                visit(name, &[("exact", v)]);
                if name == "cantelli" && keep && found.g1_failed.is_some() {
                    found.restricted = Some((g2.to_vec(), g1.to_vec()));
                }
                if found.mean_failed && !every {
                    break;
                }
            }
        })
    }

    /// Cantelli's constraints of obstacle `i` by the general decision of `self.method`
    /// ([`super::decide::decide_obstacle`]).
    fn cantelli_general(
        &self,
        i: usize,
        pr: PieceRef<'_>,
        subs: Option<&Substitution>,
        every: bool,
        visit: &mut Visit<'_>,
        found: &mut CantelliFindings,
    ) {
        let fast = subs.map(|s| (s, self.one_minus[i]));
        let (o, delta) = (&self.scene.obstacles[i], self.deltas[i].rational());
        let compiled = Some(self.compiled.get(i));
        super::decide::decide_obstacle(o, compiled, fast, pr, delta, self.method, &self.settings, |name, vs| {
            let st = combine(&vs);
            if st != Status::Safe {
                let hint = vs.iter().find_map(|(_, v)| if let Verdict::Unsafe(w) = v { Some(w.tau) } else { None });
                if name == "mean" && st == Status::Unsafe {
                    found.mean_failed = true;
                } else {
                    // g₁ fails, or the mean is undecided: other bounds may still cover
                    // the piece (their search proves E[P] < 0 where it uses them)
                    found.g1_failed.get_or_insert(hint);
                }
            }
            visit(name, &vs);
            every || st == Status::Safe
        });
    }

    /// Where Cantelli's g₁ failed (at local time `hint`, if known), the cover of the
    /// piece by the other bounds (docs/design.md §5.13), reusing the fast path's
    /// `restricted` enclosures.
    fn cover_beyond_cantelli(
        &self,
        i: usize,
        pr: PieceRef<'_>,
        subs: Option<&Substitution>,
        hint: Option<f64>,
        restricted: Option<Restricted>,
    ) -> ObstacleFinding {
        let o = &self.scene.obstacles[i];
        let pb = if self.fast {
            PieceBounds::for_piece_compiled(&o.contour, self.compiled.get(i), pr, self.levels[i])
                .with_substitution(subs)
                .with_cantelli_restrictions(restricted)
        } else {
            PieceBounds::for_piece(&o.contour, pr, self.levels[i])
        };
        match pb.cover(hint) {
            Ok(parts) => ObstacleFinding::Covered(parts),
            Err(f) => ObstacleFinding::NotProven(Some(f)),
        }
    }
}

/// Fewest candidates of a piece's whole box for which the piece is split into parts
/// ([`SceneCertifier::candidates`]): a direct check of an obstacle costs a few
/// microseconds, a part's box and lookup a fraction of one, so splitting pays only when
/// several obstacles may be dropped.
pub const SPLIT_MIN_CANDIDATES: usize = 3;

/// Most parts per candidate of the whole box when a piece is split.
pub const SPLIT_PARTS_PER_CANDIDATE: usize = 2;

impl SceneCertifier {
    /// The obstacles a piece inside the workspace must be checked against (`bbox`: its
    /// proven bounding box). A long or curved piece's box meets covers its path stays
    /// clear of: such a piece is split in time into parts
    /// ([`SceneIndex::sub_pieces_for`]), each with its own proven box, and the candidates
    /// are those of the parts (the parts cover the piece: sound).
    fn candidates(&self, index: &SceneIndex, pr: PieceRef<'_>, bbox: Option<&[(f64, f64)]>, out: &mut Vec<usize>) {
        let split = |k: usize, out: &mut Vec<usize>| {
            let Some(parts) = (k > 1).then(|| piece_sub_boxes(pr, k)).flatten() else { return false };
            let mut set = index.candidate_set();
            for (b, (a, z)) in &parts {
                index.mark_candidates(Some(b), *a, *z, &mut set);
            }
            set.emit(out);
            true
        };
        let k = bbox.map_or(1, |b| index.sub_pieces_for(b));
        // a long piece among many obstacles is split before its whole box is looked up
        // (that lookup visits every grid cell of the box: on 512 disks a diagonal
        // shortcut's cost more than deciding the obstacles found), by the grid's estimate
        if let Some(est) = bbox.and_then(|b| index.expected_candidates(b)).filter(|_| k > 1) {
            if est >= SPLIT_MIN_CANDIDATES as f64 {
                let cap = (SPLIT_PARTS_PER_CANDIDATE as f64 * est).min(usize::MAX as f64) as usize;
                if split(k.min(cap), out) {
                    return;
                }
            }
        }
        index.candidates(bbox, pr.t0, pr.t1, out);
        if out.len() < SPLIT_MIN_CANDIDATES {
            return;
        }
        // parts cost a box and a lookup each: no more than the candidates they may save
        split(k.min(SPLIT_PARTS_PER_CANDIDATE * out.len()), out);
    }
}

/// Receives each constraint's name and its verdicts (one per method).
pub(crate) type Visit<'a> = dyn FnMut(&'static str, &[(&'static str, Verdict)]) + 'a;

/// Enclosures of −E\[P\] and of Cantelli's g₁ on a piece (monomial coefficients in τ).
type Restricted = (Vec<Interval>, Vec<Interval>);

/// What Cantelli's constraints of one obstacle left on one piece.
#[derive(Default)]
struct CantelliFindings {
    /// The mean failed: no other bound can help where E\[P\] ≥ 0.
    mean_failed: bool,
    /// g₁ failed (`Some`), at a local time where it fails if known.
    g1_failed: Option<Option<f64>>,
    /// The fast path's enclosures of −E\[P\] and g₁ where g₁ failed.
    restricted: Option<Restricted>,
}

impl CantelliFindings {
    /// Notes the verdict on the constraint `name` (`mean` or `cantelli`).
    fn note(&mut self, name: &str, v: &Verdict) {
        match (name, v) {
            (_, Verdict::Safe { .. }) => {}
            ("mean", _) => self.mean_failed = true,
            (_, Verdict::Unsafe(w)) => self.g1_failed = Some(Some(w.tau)),
            (_, Verdict::Undecided(_)) => self.g1_failed = Some(None),
        }
    }
}

/// What deciding one obstacle on one piece found ([`SceneCertifier::decide_obstacle`]).
#[derive(Clone, Debug, PartialEq)]
pub enum ObstacleFinding {
    /// Cantelli's constraints hold on the whole piece.
    Proven,
    /// Cantelli's g₁ fails somewhere, and other bounds prove the piece part by part
    /// (docs/design.md §5.13).
    Covered(Vec<BoundPart>),
    /// Not proven: why the other bounds could not cover it, or `None` when they were not
    /// tried (E\[P\] ≥ 0 somewhere, or Cantelli's bound only).
    NotProven(Option<CoverFailure>),
}

impl ObstacleFinding {
    /// Proven, by Cantelli or a cover.
    pub(crate) fn is_safe(&self) -> bool {
        !matches!(self, ObstacleFinding::NotProven(_))
    }
}

/// Points per typical cover side ([`SceneIndex::typical_extent`]) at which
/// [`SceneCertifier::nominally_blocked`] samples a piece: a cover spans an obstacle and
/// its Cantelli ring, so a piece through an obstacle's nominal region has a sample
/// inside it unless it only clips the region's edge (then the guess is `false`, and the
/// check decides as always).
pub const GUESS_SAMPLES_PER_EXTENT: f64 = 4.0;

/// Most sample points of one guess.
pub const GUESS_MAX_SAMPLES: usize = 256;

impl SceneCertifier {
    /// Whether a point sampled along the piece has E\[P\] ≥ 0 in floating point for an
    /// obstacle the index files there: where E\[P\] ≥ 0 the mean constraint of eq. (15)
    /// fails and no bound proves the piece (the check rejects it, up to rounding at the
    /// contour; docs/design.md §6.8). A guess for
    /// post-processing ([`MotionChecker::likely_rejected`]): on 512 disks most random
    /// shortcuts cross an obstacle, and the check spent most of post-processing rejecting
    /// them (finding the candidates of a long piece, then deciding them). Only on scenes
    /// with an index grid and the fast path; pedestrians are not guessed.
    pub fn nominally_blocked(&self, piece: &Piece) -> bool {
        if !self.fast || piece.t0.partial_cmp(&piece.t1).is_none_or(|o| o == std::cmp::Ordering::Greater) {
            return false;
        }
        let index = self.index();
        let Some(extent) = index.typical_extent() else { return false };
        let (a, b) = (piece.at(piece.t0), piece.at(piece.t1));
        let len = riskplan_scene::motion::dist(&a, &b);
        let steps = (len / extent * GUESS_SAMPLES_PER_EXTENT).ceil();
        if !steps.is_finite() {
            return false;
        }
        let steps = (steps as usize).clamp(1, GUESS_MAX_SAMPLES);
        let dim = a.len();
        let mut xt = vec![0.0; dim + 1];
        let mut point = vec![(0.0, 0.0); dim];
        // coarse to fine (k in bit-reversed order over the next power of two): a refused
        // shortcut meets an obstacle somewhere inside, seldom at its ends (they lie on
        // certified pieces), and is found after a few samples instead of half of them
        let bits = (steps + 1).next_power_of_two().trailing_zeros();
        let order = (0..1usize << bits).map(|j| if bits == 0 { 0 } else { j.reverse_bits() >> (usize::BITS - bits) });
        for k in order.filter(|&k| k <= steps) {
            let t = piece.t0 + (piece.t1 - piece.t0) * (k as f64 / steps as f64);
            for ((x, p), c) in xt.iter_mut().zip(point.iter_mut()).zip(&piece.coeffs) {
                *x = c.iter().rev().fold(0.0, |acc, &k| acc * t + k);
                *p = (*x, *x);
            }
            xt[dim] = t;
            let Some((cell, always)) = index.point_candidates(&xt[..dim]) else { return false };
            // (an obstacle whose covers leave the point out has E[P] < 0 there)
            let inside = |&i: &u32| {
                let o = &self.scene.obstacles[i as usize];
                o.pedestrian.is_none() && !index.point_cleared(i as usize, &point, t) && o.contour.mean_f64(&xt) >= 0.0
            };
            if cell.iter().any(inside) || always.iter().any(inside) {
                return true;
            }
        }
        false
    }
}

impl SceneCertifier {
    /// [`MotionChecker::check`], with the number of obstacles decided (the work).
    fn check_counting(&self, piece: &Piece) -> (Motion, u64) {
        let pr = PieceRef { t0: piece.t0, t1: piece.t1, coeffs: &piece.coeffs };
        // a piece runs forward in time (t0 ≤ t1); anything else is no piece
        if !pr.is_finite() || pr.t0 > pr.t1 {
            return (Motion::Rejected, 0);
        }
        if !self.fast {
            let m = if piece_passes_verify_path(
                &self.scene,
                &self.kernel.framed(),
                None,
                pr,
                &self.deltas,
                self.bounds,
                Some(&self.compiled),
                None,
            ) {
                Motion::Accepted
            } else {
                Motion::Rejected
            };
            return (m, self.scene.obstacles.len() as u64);
        }
        let ws = &self.scene.workspace;
        let bbox = piece_bbox(pr);
        if !inside_by_box(&ws.lower, &ws.upper, pr, bbox.as_deref())
            && check_workspace(&ws.lower, &ws.upper, pr).status != Status::Safe
        {
            return (Motion::Rejected, 0);
        }
        let mut cands = Vec::new();
        let index = self.index();
        self.candidates(index, pr, bbox.as_deref(), &mut cands);
        if self.build_covers {
            let due: Vec<usize> =
                cands.iter().copied().filter(|&i| !index.has_covers(i) && index.note_direct_check(i)).collect();
            if !due.is_empty() {
                // obstacles checked often enough to pay for their covers: built now, and
                // the candidates found again with them
                for &i in &due {
                    index.ensure(&self.scene, i, &|| false);
                }
                self.candidates(index, pr, bbox.as_deref(), &mut cands);
            }
        }
        // the compiled substitution, for the candidates that use it (not the pedestrians
        // decided by their tail bound)
        let tail_only = self.bounds.beyond_cantelli();
        let needs_subs = cands.iter().any(|&i| !(tail_only && self.scene.obstacles[i].pedestrian.is_some()));
        let subs = if needs_subs { Substitution::new(pr, self.compiled.frame()) } else { None };
        let mut decided = 0;
        for i in cands {
            decided += 1;
            if !self.obstacle_safe(i, pr, subs.as_ref()) {
                return (Motion::Rejected, decided);
            }
        }
        (Motion::Accepted, decided)
    }
}

impl MotionChecker for SceneCertifier {
    fn name(&self) -> &str {
        self.method.as_str()
    }

    fn sound(&self) -> bool {
        true
    }

    fn prepare(&self, term: &Termination) {
        if !self.fast {
            return;
        }
        let index = self.index_until(&|| term.expired());
        // every cover before the first check, on small scenes too (where a check would
        // otherwise build an obstacle's covers once it is checked often enough): the
        // candidates of a check, and with them the checking work that budgets
        // post-processing (docs/design.md §6.8), are then the same whether the scene is new
        // here (a CLI plan) or its covers were built by earlier plans or the service's
        // warm-up — same seed, same plan, through every front end
        if self.build_covers {
            index.ensure_all(&self.scene, &|| term.expired());
        }
    }

    fn work(&self) -> Option<u64> {
        Some(self.work.load(std::sync::atomic::Ordering::Relaxed))
    }

    fn check(&self, piece: &Piece) -> Motion {
        let (motion, decided) = self.check_counting(piece);
        self.work.fetch_add(1 + decided, std::sync::atomic::Ordering::Relaxed);
        motion
    }

    fn path_risk(&self, piece: &Piece, stop: &dyn Fn() -> bool) -> Option<f64> {
        use crate::whole_path::{cells_path_risk_in, piece_path_risk, PieceBoxes};
        let effort = self.path_risk?;
        let r = PieceRef { t0: piece.t0, t1: piece.t1, coeffs: &piece.coeffs };
        let mut total = 0.0f64;
        // each obstacle in its own frame (docs/design.md §5.14)
        let frames = self.kernel.path_frames(stop).ok()?;
        let boxes = PieceBoxes::new(std::slice::from_ref(&r), self.scene.dim);
        for (i, (o, frame)) in self.scene.obstacles.iter().zip(frames.iter()).enumerate() {
            let c = o.contour.get();
            let reach = self.kernel.path_reach(i, frame);
            let b = match cells_path_risk_in(c, std::slice::from_ref(&r), &boxes, frame, reach.as_deref(), effort, stop)
            {
                Some(b) => b.bound,
                None if stop() => return None,
                // no rigorous distribution function: the moment envelopes
                None => piece_path_risk(c, r, stop)?.bound_f64(),
            };
            total = crate::whole_path::add_up(total, b);
            if total >= 1.0 {
                return Some(1.0);
            }
        }
        Some(total)
    }

    fn likely_rejected(&self, piece: &Piece) -> bool {
        self.nominally_blocked(piece)
    }

    fn blocking_obstacle(&self, x: &[f64], t: f64) -> Option<String> {
        match point_status(&self.scene, x, t, &self.deltas, self.bounds) {
            PointStatus::InContour(i) => Some(self.scene.obstacles[i].id.clone()),
            _ => None,
        }
    }

    fn check_point(&self, x: &[f64], t: f64) -> Motion {
        if !self.scene.workspace.contains(x) {
            return Motion::Rejected;
        }
        // obstacles whose proven cover misses the point are safe there; the others are
        // decided exactly
        let bbox: Vec<(f64, f64)> = x.iter().map(|&v| (v, v)).collect();
        let mut cands = Vec::new();
        if self.fast {
            self.index().candidates(Some(&bbox), t, t, &mut cands);
        } else {
            cands.extend(0..self.scene.obstacles.len());
        }
        let Some(mut xt) = x.iter().map(|&v| BigRational::from_float(v)).collect::<Option<Vec<_>>>() else {
            return Motion::Rejected;
        };
        let Some(tq) = BigRational::from_float(t) else { return Motion::Rejected };
        xt.push(tq);
        let mut xf = x.to_vec();
        xf.push(t);
        for i in cands {
            let compiled =
                (self.fast && self.scene.obstacles[i].pedestrian.is_none()).then(|| (self.compiled.get(i), &xf[..]));
            if !point_obstacle_safe_at(
                &self.scene.obstacles[i],
                &xt,
                &self.deltas[i],
                Some(self.levels[i]),
                compiled,
                self.bounds,
            ) {
                return Motion::Rejected;
            }
        }
        Motion::Accepted
    }
}
