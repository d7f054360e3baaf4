//! What the checkers of one scene share, built on first use and kept by whoever keeps
//! the scene alive (a server's registry entry, a prepared plan): the compiled contours
//! (independent of Δ), the verify path's framed contours, and the covers of the last
//! few risk allocations (docs/design.md §5.10, §5.12).
//!
//! The kernel owns its scene (`Arc<Scene>`), so what it caches can never belong to
//! another scene: a changed scene is a new scene and gets a new kernel.

pub use super::compiled_set::CompiledSet;
use super::cover_index::SceneIndex;
use super::decide::Interrupted;
use super::verify_path::FramedContours;
use crate::compiled::Frame;
use crate::whole_path::{Reach, ReachGrid};
use riskplan_math::contour::RiskLevel;
use riskplan_scene::Scene;
use std::sync::{Arc, Mutex, OnceLock};

/// Indexes kept per scene (one per distinct list of per-obstacle risk levels).
pub const INDEXES_PER_SCENE: usize = 4;

/// How much wider, relative to its sides, the region of the obstacles' [`Reach`] boxes
/// is than the workspace × the horizon ([`SceneKernel::path_reach`]).
pub const REACH_REGION_MARGIN: f64 = 1.0 / 1024.0;

/// A scene with what its checkers cache (cheap to clone: the caches are shared).
#[derive(Clone)]
pub struct SceneKernel {
    inner: Arc<Inner>,
}

struct Inner {
    scene: Arc<Scene>,
    compiled: OnceLock<Arc<CompiledSet>>,
    framed: OnceLock<Arc<FramedContours>>,
    /// Per obstacle, the frame of its whole-path partition ([`SceneKernel::path_frames`]).
    path_frames: OnceLock<Arc<Vec<Frame>>>,
    /// Per obstacle, its path frame in the previous revision when the two revisions share
    /// its contour, the scene's frame and the region (the same inputs: the same frame),
    /// for [`SceneKernel::path_frames`]; empty when nothing was carried.
    frames_carried: Vec<Option<Frame>>,
    /// Per obstacle, where in the workspace × horizon it may be met ([`SceneKernel::path_reach`]).
    path_reach: Vec<OnceLock<Option<Arc<Reach>>>>,
    /// The reaches in a grid ([`SceneKernel::path_reach_grid`]).
    path_reach_grid: OnceLock<Option<Arc<ReachGrid>>>,
    indexes: Mutex<Vec<(Vec<RiskLevel>, Arc<SceneIndex>)>>,
    /// The indexes of the scene's previous revision, whose covers of unchanged obstacles
    /// the indexes built here take over.
    previous: Vec<Arc<SceneIndex>>,
    /// Obstacles whose contour the previous revision shared ([`SceneKernel::unchanged`]).
    unchanged: usize,
}

impl std::fmt::Debug for SceneKernel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneKernel")
            .field("scene", &self.inner.scene.name)
            .field("compiled", &self.inner.compiled.get().map(|c| c.built()))
            .finish()
    }
}

impl From<Arc<Scene>> for SceneKernel {
    fn from(scene: Arc<Scene>) -> Self {
        SceneKernel::new(scene)
    }
}

impl From<&Arc<Scene>> for SceneKernel {
    /// A kernel of its own for `scene` (nothing shared with other kernels).
    fn from(scene: &Arc<Scene>) -> Self {
        SceneKernel::new(scene.clone())
    }
}

impl From<&Scene> for SceneKernel {
    /// A kernel of its own for a copy of `scene` (nothing shared with other kernels).
    fn from(scene: &Scene) -> Self {
        SceneKernel::new(Arc::new(scene.clone()))
    }
}

impl From<&SceneKernel> for SceneKernel {
    fn from(k: &SceneKernel) -> Self {
        k.clone()
    }
}

impl SceneKernel {
    /// A kernel for `scene`, with nothing built yet.
    pub fn new(scene: Arc<Scene>) -> Self {
        let path_reach = (0..scene.obstacles.len()).map(|_| OnceLock::new()).collect();
        SceneKernel {
            inner: Arc::new(Inner {
                scene,
                compiled: OnceLock::new(),
                framed: OnceLock::new(),
                path_frames: OnceLock::new(),
                frames_carried: Vec::new(),
                path_reach,
                path_reach_grid: OnceLock::new(),
                indexes: Mutex::new(Vec::new()),
                previous: Vec::new(),
                unchanged: 0,
            }),
        }
    }

    /// A kernel for `scene`, the next revision of this kernel's scene: what this kernel
    /// built for obstacles that are unchanged (same contour; compiled contours, covers at
    /// the same risk level) is taken over, so that an update of some obstacles costs only
    /// theirs (docs/design.md §5.10, §3.11). Sound for any `scene`: only what depends on
    /// nothing but an unchanged contour, the workspace and the horizon is reused, and those
    /// are compared.
    pub fn successor(&self, scene: Arc<Scene>) -> SceneKernel {
        let compiled = OnceLock::new();
        if let Some(old) = self.inner.compiled.get() {
            let _ = compiled.set(Arc::new(CompiledSet::reusing(scene.clone(), old)));
        }
        let mut previous: Vec<Arc<SceneIndex>> =
            self.inner.indexes.lock().map(|v| v.iter().map(|e| e.1.clone()).collect()).unwrap_or_default();
        if previous.is_empty() {
            previous = self.inner.previous.clone();
        }
        let path_reach: Vec<OnceLock<Option<Arc<Reach>>>> =
            (0..scene.obstacles.len()).map(|_| OnceLock::new()).collect();
        // each obstacle's index in the old revision, when the two share its contour (the
        // same cached contour: the same polynomial, laws and body)
        let old_scene = &self.inner.scene;
        let by_key: std::collections::HashMap<usize, usize> =
            old_scene.obstacles.iter().enumerate().map(|(j, o)| (o.contour.key(), j)).collect();
        let index: Vec<Option<usize>> = scene.obstacles.iter().map(|o| by_key.get(&o.contour.key()).copied()).collect();
        // (counted only when what is built for them can be taken over: the same Δ, region
        // and frame, and a previous index complete at that Δ — else the new revision is as
        // cold as a new scene, whatever its contours)
        let old_deltas = vec![old_scene.risk.clone(); old_scene.obstacles.len()];
        let takes_over = scene.risk == old_scene.risk
            && scene.workspace == old_scene.workspace
            && scene.horizon == old_scene.horizon
            && super::scene_frame(&scene) == super::scene_frame(old_scene)
            && self.peek_index(&old_deltas).is_some_and(|i| i.complete());
        let unchanged = if takes_over { index.iter().filter(|j| j.is_some()).count() } else { 0 };
        // the verify path's contours: what the old revision built for unchanged obstacles
        let framed = OnceLock::new();
        if let Some(old) = self.inner.framed.get() {
            let _ = framed.set(Arc::new(FramedContours::reusing(&scene, old, old_scene, &index)));
        }
        // the whole-path partition's frames and reaches of unchanged obstacles: the same
        // when the scene's frame and region are (a path frame depends on nothing else but
        // the obstacle's contour; a reach on its frame and the region)
        // (and the same use of box tests: a path frame is moved to its obstacle only with one)
        let same_region = super::scene_frame(&scene) == super::scene_frame(old_scene)
            && scene.workspace == old_scene.workspace
            && scene.horizon == old_scene.horizon
            && FramedContours::has_near(&scene) == FramedContours::has_near(old_scene);
        // (the old revision's frames, or those it had taken over itself: a revision no plan
        // used passes them on)
        let old_frames: Option<Vec<Option<Frame>>> = match self.inner.path_frames.get() {
            Some(f) => Some(f.iter().cloned().map(Some).collect()),
            None => (!self.inner.frames_carried.is_empty()).then(|| self.inner.frames_carried.clone()),
        };
        let mut frames_carried = Vec::new();
        if let (true, Some(old_frames)) = (same_region, old_frames.filter(|f| f.len() == old_scene.obstacles.len())) {
            frames_carried = index
                .iter()
                .enumerate()
                .map(|(i, &j)| {
                    let j = j?;
                    let frame = old_frames[j].clone()?;
                    if let Some(Some(r)) = self.inner.path_reach.get(j).and_then(|s| s.get()) {
                        let _ = path_reach[i].set(Some(r.clone()));
                    }
                    Some(frame)
                })
                .collect();
        }
        SceneKernel {
            inner: Arc::new(Inner {
                scene,
                compiled,
                framed,
                path_frames: OnceLock::new(),
                frames_carried,
                path_reach,
                path_reach_grid: OnceLock::new(),
                indexes: Mutex::new(Vec::new()),
                previous,
                unchanged,
            }),
        }
    }

    /// How many of the scene's obstacles have the contour they had in the revision this
    /// kernel succeeds ([`SceneKernel::successor`]), when what was built for them there can
    /// be taken over: the same Δ, workspace, horizon and frame, and the previous revision's
    /// index complete at its Δ; 0 otherwise, and for a kernel made with
    /// [`SceneKernel::new`]. The service warms a kernel in the background only when most of
    /// its scene is new in this sense (docs/design.md §3.11, "Warm-ups").
    pub fn unchanged(&self) -> usize {
        self.inner.unchanged
    }

    /// Whether everything a warm-up (`app::warm_up`) builds at `deltas` is built:
    /// the index complete, the final check's box tests (and their grid), the whole-path
    /// frames, reaches and their grid.
    pub fn is_warm(&self, deltas: &[RiskLevel]) -> bool {
        let scene = &self.inner.scene;
        self.peek_index(deltas).is_some_and(|i| i.complete())
            && self.inner.framed.get().is_some_and(|f| f.built(scene, deltas))
            && self.inner.path_frames.get().is_some()
            && self.inner.path_reach.iter().all(|r| r.get().is_some())
            && self.inner.path_reach_grid.get().is_some()
    }

    /// Builds now what plans build for obstacle `i` on first use, where their edges go
    /// (for warm-ups, `app::warm_up`; docs/design.md §3.11): its compiled contour (§5.10),
    /// with `beyond_cantelli` its compiled bounds beyond Cantelli (§5.13), and its contours
    /// in the verify path's frame (§5.12). A pedestrian with `beyond_cantelli` is decided by
    /// its tail bound (§3.11) and needs none of them. Nothing is built twice.
    pub fn build_obstacle(&self, i: usize, beyond_cantelli: bool) {
        let Some(o) = self.inner.scene.obstacles.get(i) else { return };
        if o.pedestrian.is_some() && beyond_cantelli {
            return;
        }
        let compiled = self.compiled();
        let c = compiled.get(i);
        if beyond_cantelli {
            c.bounds(&o.contour);
        }
        self.framed().ensure_pair(i, o);
    }

    /// How many obstacles have what [`Self::build_obstacle`] builds (with
    /// `beyond_cantelli`), built or not needed (what the tests of the warm-up count).
    pub fn obstacles_built(&self, beyond_cantelli: bool) -> usize {
        let scene = &self.inner.scene;
        let compiled = self.inner.compiled.get();
        let framed = self.inner.framed.get();
        (0..scene.obstacles.len())
            .filter(|&i| {
                (scene.obstacles[i].pedestrian.is_some() && beyond_cantelli)
                    || (compiled.is_some_and(|c| c.is_built(i, beyond_cantelli))
                        && framed.is_some_and(|f| f.has_pair(i)))
            })
            .count()
    }

    /// The scene.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.inner.scene
    }

    /// The scene's compiled contours (each built on first use, shared by every checker
    /// of the scene).
    pub fn compiled(&self) -> Arc<CompiledSet> {
        let scene = &self.inner.scene;
        self.inner.compiled.get_or_init(|| Arc::new(CompiledSet::new(scene.clone()))).clone()
    }

    /// The scene's contours in the verify path's own frame (built once, shared by every
    /// final check of the scene; docs/design.md §5.12).
    pub fn framed(&self) -> Arc<FramedContours> {
        self.inner.framed.get_or_init(|| Arc::new(FramedContours::new(&self.inner.scene))).clone()
    }

    /// Per obstacle, the frame its whole-path partition is written in (docs/design.md
    /// §5.14): the scene's frame ([`super::scene_frame`]) moved to the obstacle when the
    /// box tests found a centre for it (scenes of more than a few obstacles, static ones)
    /// — the centre refined (`super::cover_index::refine_center`), the scales kept. Far from
    /// its frame's centre P's expanded terms cancel, and their interval ranges over the
    /// parameters' boxes, which cannot cancel, dwarf P (on 512 disks the screen kept six
    /// obstacles in ten, and the partition beside the path never converged). Built once
    /// per scene (`Err` when `stop` said stop first; nothing is kept then).
    pub fn path_frames(&self, stop: &dyn Fn() -> bool) -> Result<Arc<Vec<Frame>>, Interrupted> {
        if let Some(f) = self.inner.path_frames.get() {
            return Ok(f.clone());
        }
        let scene = &self.inner.scene;
        let base = super::scene_frame(scene);
        let framed = self.framed();
        let near = framed.near(scene, stop)?;
        let ws = &scene.workspace;
        let mut region: Vec<(f64, f64)> = ws.lower.iter().copied().zip(ws.upper.iter().copied()).collect();
        region.push(scene.horizon);
        let mut frames = Vec::with_capacity(scene.obstacles.len());
        for (i, o) in scene.obstacles.iter().enumerate() {
            if let Some(Some(kept)) = self.inner.frames_carried.get(i) {
                frames.push(kept.clone());
                continue;
            }
            if stop() {
                return Err(Interrupted);
            }
            let c = o.contour.get();
            let centre = near.and_then(|n| n.get(i)?.as_ref()).filter(|_| !c.is_dynamic());
            let frame = match centre {
                Some(n) => {
                    let mut center = super::cover_index::refine_center(c, n.center(), &region);
                    center[scene.dim] = base.center[scene.dim];
                    if center.iter().all(|v| v.is_finite()) {
                        Frame { center, exponents: base.exponents.clone() }
                    } else {
                        base.clone()
                    }
                }
                None => base.clone(),
            };
            frames.push(frame);
        }
        Ok(self.inner.path_frames.get_or_init(|| Arc::new(frames)).clone())
    }

    /// Where obstacle `i` may be met in the workspace × the horizon, for some ω of its
    /// parameters' ranges ([`Reach`], docs/design.md §5.14): the whole-path screen's first
    /// test. Built on first use from P folded in `frame` (the obstacle's path frame; the
    /// box it gives is a statement about P in the scene's coordinates, true whatever frame
    /// found it) and kept; `None` for an obstacle without rigorous laws.
    pub fn path_reach(&self, i: usize, frame: &Frame) -> Option<Arc<Reach>> {
        let slot = self.inner.path_reach.get(i)?;
        slot.get_or_init(|| {
            let scene = &self.inner.scene;
            let folded = scene.obstacles.get(i)?.contour.get().folded_poly(&frame.center, &frame.exponents)?;
            Reach::new(&folded, frame, &self.reach_region()).map(Arc::new)
        })
        .clone()
    }

    /// The region of the obstacles' reaches: the workspace × the horizon, widened a
    /// little ([`REACH_REGION_MARGIN`]): the enclosures of pieces that end on the boundary
    /// (and of their times) overshoot it by roundings, and a box must lie inside.
    fn reach_region(&self) -> Vec<(f64, f64)> {
        let scene = &self.inner.scene;
        let ws = &scene.workspace;
        let mut region: Vec<(f64, f64)> = ws.lower.iter().copied().zip(ws.upper.iter().copied()).collect();
        region.push(scene.horizon);
        for side in &mut region {
            let m = REACH_REGION_MARGIN * (side.1 - side.0);
            *side = (side.0 - m, side.1 + m);
        }
        region
    }

    /// Every obstacle's reach in its path frame ([`SceneKernel::path_reach`] of
    /// [`SceneKernel::path_frames`]) and their grid ([`ReachGrid`]: the obstacles a
    /// trajectory may come near, found from its boxes). Built once per scene (`Err` when
    /// `stop` said stop first).
    #[allow(clippy::type_complexity)]
    pub fn path_reaches(
        &self,
        stop: &dyn Fn() -> bool,
    ) -> Result<(Arc<Vec<Frame>>, Vec<Option<Arc<Reach>>>, Option<Arc<ReachGrid>>), Interrupted> {
        let frames = self.path_frames(stop)?;
        let mut reaches = Vec::with_capacity(frames.len());
        for (i, frame) in frames.iter().enumerate() {
            if self.inner.path_reach.get(i).is_some_and(|s| s.get().is_none()) && stop() {
                return Err(Interrupted);
            }
            reaches.push(self.path_reach(i, frame));
        }
        let grid = self
            .inner
            .path_reach_grid
            .get_or_init(|| ReachGrid::new(&self.reach_region(), &reaches).map(Arc::new))
            .clone();
        Ok((frames, reaches, grid))
    }

    /// The index at `deltas` if this kernel holds it (never builds).
    pub fn peek_index(&self, deltas: &[RiskLevel]) -> Option<Arc<SceneIndex>> {
        let v = self.inner.indexes.lock().ok()?;
        v.iter().find(|(d, _)| d == deltas).map(|e| e.1.clone())
    }

    /// The index at `deltas` with every obstacle's covers built (asking `stop` between
    /// obstacles; what a stop leaves unbuilt is built by a later call). Kept among the
    /// last `INDEXES_PER_SCENE`.
    pub fn index(&self, deltas: &[RiskLevel], stop: &dyn Fn() -> bool) -> Arc<SceneIndex> {
        let index = self.lazy_index(deltas);
        index.ensure_all(&self.inner.scene, stop);
        index
    }

    /// [`Self::index`], its covers built on up to `threads` threads
    /// ([`SceneIndex::ensure_all_on`]).
    pub fn index_on(&self, deltas: &[RiskLevel], stop: &(dyn Fn() -> bool + Sync), threads: usize) -> Arc<SceneIndex> {
        let index = self.lazy_index(deltas);
        index.ensure_all_on(&self.inner.scene, stop, threads);
        index
    }

    /// The index at `deltas`, made if absent with no covers built but those taken over
    /// from the previous revision (its obstacles' covers are built on demand:
    /// [`SceneIndex::ensure`]). Kept among the last `INDEXES_PER_SCENE`.
    pub fn lazy_index(&self, deltas: &[RiskLevel]) -> Arc<SceneIndex> {
        if let Some(i) = self.peek_index(deltas) {
            return i;
        }
        let made = Arc::new(SceneIndex::lazy(&self.inner.scene, deltas, &self.inner.previous));
        if let Ok(mut v) = self.inner.indexes.lock() {
            if let Some(e) = v.iter().find(|(d, _)| d == deltas) {
                // made meanwhile by another thread: share it
                return e.1.clone();
            }
            if v.len() >= INDEXES_PER_SCENE {
                v.remove(0);
            }
            v.push((deltas.to_vec(), made.clone()));
        }
        made
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use riskplan_scene::{ContourCache, SceneFile};

    /// `n` static disks of uncertain radius and offset (the growth family of the benches,
    /// placed by a fixed sequence) in a square of side 10·√n, with disk `moved` shifted by
    /// `shift` along x₂.
    fn disks(n: usize, moved: usize, shift: f64) -> SceneFile {
        disks_at(n, moved, shift, 0.0)
    }

    /// [`disks`] with the square's corner at (`origin`, `origin`).
    fn disks_at(n: usize, moved: usize, shift: f64, origin: f64) -> SceneFile {
        let side = 10.0 * (n as f64).sqrt();
        let mut params = serde_json::Map::new();
        let mut obstacles = Vec::new();
        for k in 0..n {
            let u = |a: u64| ((k as u64 * a + 7) % 1000) as f64 / 1000.0;
            let (cx, cy, r) =
                (origin + 5.0 + u(377) * (side - 10.0), origin + 5.0 + u(613) * (side - 10.0), 0.8 + 0.8 * u(271));
            let cy = if k == moved { cy + shift } else { cy };
            params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
            params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
            obstacles.push(serde_json::json!({"id": format!("disk{k}"),
                "poly": format!("({r:.2}*s{k})^2 - (x1 - {cx:.2} - d{k})^2 - (x2 - {cy:.2})^2")}));
        }
        serde_json::from_value(serde_json::json!({"format": "riskplan-scene/1", "name": "disks", "dim": 2,
            "workspace": {"lower": [origin, origin], "upper": [origin + side, origin + side]}, "horizon": [0, 1], "risk": 0.05,
            "params": params, "obstacles": obstacles}))
        .unwrap()
    }

    /// Everything the final check and the whole-path bound build for a scene, as text (the
    /// floats' `Debug` forms are exact).
    fn built(k: &SceneKernel, deltas: &[RiskLevel]) -> Vec<String> {
        let scene = k.scene().clone();
        let framed = k.framed();
        let near = framed.near(&scene, &|| false).unwrap();
        let grid = framed.grid(&scene, deltas, &|| false).unwrap();
        assert!(grid.is_some(), "no grid on {} obstacles", scene.obstacles.len());
        let (frames, reaches, reach_grid) = k.path_reaches(&|| false).unwrap();
        vec![
            format!("{near:?}"),
            format!("{grid:?}"),
            format!("{frames:?}"),
            format!("{reaches:?}"),
            format!("{reach_grid:?}"),
        ]
    }

    /// Asserts that `successor` holds everything of [`built`] that `fresh` (a kernel made
    /// afresh for the same revision) holds; the successor's, as text.
    fn same_as_fresh(successor: &SceneKernel, fresh: &SceneKernel, deltas: &[RiskLevel]) -> Vec<String> {
        let (a, b) = (built(successor, deltas), built(fresh, deltas));
        for (what, (x, y)) in ["box tests", "grid", "path frames", "reaches", "reach grid"].iter().zip(a.iter().zip(&b))
        {
            assert!(x == y, "{what}: the successor's differs from a fresh build");
        }
        a
    }

    /// The first revision of the tests' scene (80 disks, disk 10 in place), its cache, its
    /// risk levels and its kernel with everything of [`built`] built.
    fn first_revision(n: usize) -> (ContourCache, Arc<Scene>, Vec<RiskLevel>, SceneKernel, Vec<String>) {
        first_revision_at(n, 0.0)
    }

    /// [`first_revision`] of [`disks_at`] `origin`.
    fn first_revision_at(
        n: usize,
        origin: f64,
    ) -> (ContourCache, Arc<Scene>, Vec<RiskLevel>, SceneKernel, Vec<String>) {
        let cache = ContourCache::default();
        let s1 = Arc::new(Scene::from_file_cached(disks_at(n, 10, 0.0, origin), &cache).unwrap());
        let deltas = vec![RiskLevel::from_f64(0.05).unwrap(); n];
        let k1 = SceneKernel::new(s1.clone());
        let old = built(&k1, &deltas);
        (cache, s1, deltas, k1, old)
    }

    /// `SceneKernel::unchanged` (what the service's warm-ups go by): the obstacles whose
    /// contour the previous revision shared, counted only when what was built for them can
    /// be taken over — the previous index complete at the scene's own Δ, and the same Δ.
    #[test]
    fn unchanged_counts_what_a_successor_can_take_over() {
        let n = 40;
        let cache = ContourCache::default();
        let s1 = Arc::new(Scene::from_file_cached(disks(n, 10, 0.0), &cache).unwrap());
        let own = vec![s1.risk.clone(); n];
        let k1 = SceneKernel::new(s1.clone());
        let moved = || Arc::new(Scene::from_file_reusing(disks(n, 10, 3.0), &cache, Some(&s1)).unwrap());
        // nothing built at the scene's Δ yet: as cold as a new scene
        assert_eq!(k1.successor(moved()).unchanged(), 0);
        let _ = k1.index(&own, &|| false);
        assert_eq!(k1.unchanged(), 0, "a fresh kernel");
        assert_eq!(k1.successor(moved()).unchanged(), n - 1, "all but the moved disk");
        // the same disks at another Δ: their covers are not the old ones
        let mut other = serde_json::to_value(disks(n, 10, 3.0)).unwrap();
        other["risk"] = serde_json::json!(0.01);
        let s3 = Arc::new(Scene::from_file_reusing(serde_json::from_value(other).unwrap(), &cache, Some(&s1)).unwrap());
        assert_eq!(k1.successor(s3).unchanged(), 0);
    }

    /// After an update of one obstacle of 80, the next revision's kernel takes over what
    /// the old one built for the others (box tests, their grid, path frames and reaches)
    /// and holds exactly what a kernel built afresh for the new
    /// revision holds — and has rebuilt the moved obstacle's own.
    #[test]
    fn a_successor_holds_what_a_fresh_kernel_builds() {
        let n = 80;
        let (cache, s1, deltas, k1, old) = first_revision(n);
        let s2 = Arc::new(Scene::from_file_reusing(disks(n, 10, 3.0), &cache, Some(&s1)).unwrap());
        // the new revision's contours (the moved one's built with its own parameters'
        // moments alone) are those of the same scene built afresh
        let afresh = Scene::from_file(disks(n, 10, 3.0)).unwrap();
        for (a, b) in s2.obstacles.iter().zip(&afresh.obstacles) {
            let (a, b) = (a.contour.get(), b.contour.get());
            assert_eq!((&a.mean, &a.second), (&b.mean, &b.second));
        }
        let k2 = k1.successor(s2.clone());
        // taken over before anything is asked of the new kernel: all but the moved one
        let carried = k2.inner.framed.get().and_then(|f| f.carried_count()).unwrap_or(0);
        assert_eq!(carried, n - 1);
        assert_eq!(k2.inner.frames_carried.iter().filter(|f| f.is_some()).count(), n - 1);
        let fresh = SceneKernel::new(s2);
        let a = same_as_fresh(&k2, &fresh, &deltas);
        // the moved obstacle's box test is its own, not the old one's
        assert_ne!(old[0], a[0]);
    }

    /// The same through reordered and removed obstacles, another Δ for one unchanged
    /// obstacle, a revision no plan used (it passes on what it took over), and a build of
    /// the box tests stopped half-way (what it built is kept).
    #[test]
    fn a_chain_of_successors_holds_what_a_fresh_kernel_builds() {
        let n = 80;
        let (cache, s1, _, k1, _) = first_revision(n);
        // revision 2: obstacle 10 moved, the list rotated, one obstacle removed; no plan
        let mut f2 = disks(n, 10, 3.0);
        f2.obstacles.rotate_left(7);
        f2.obstacles.remove(5);
        let s2 = Arc::new(Scene::from_file_reusing(f2.clone(), &cache, Some(&s1)).unwrap());
        let k2 = k1.successor(s2.clone());
        // revision 3: obstacle 20 moved too
        let mut f3 = disks(n, 10, 3.0);
        let moved = disks(n, 20, 2.0);
        f3.obstacles[20] = moved.obstacles[20].clone();
        f3.obstacles.rotate_left(7);
        f3.obstacles.remove(5);
        let s3 = Arc::new(Scene::from_file_reusing(f3, &cache, Some(&s2)).unwrap());
        let k3 = k2.successor(s3.clone());
        let m = n - 1;
        assert_eq!(k3.inner.framed.get().and_then(|f| f.carried_count()), Some(m - 2));
        assert_eq!(k3.inner.frames_carried.iter().filter(|f| f.is_some()).count(), m - 2);
        // one unchanged obstacle at another Δ
        let mut d3 = vec![RiskLevel::from_f64(0.05).unwrap(); m];
        d3[40] = RiskLevel::from_f64(0.01).unwrap();
        // a build of the box tests stopped after a few obstacles: kept, then finished
        let asked = std::sync::atomic::AtomicUsize::new(0);
        let few = || asked.fetch_add(1, std::sync::atomic::Ordering::Relaxed) >= 1;
        assert!(k3.framed().near(&s3, &few).is_err());
        let fresh = SceneKernel::new(s3);
        same_as_fresh(&k3, &fresh, &d3);
    }

    /// Far from the origin the verify path works in a frame of its own, with each
    /// obstacle's polynomials substituted exactly into it (docs/design.md §5.12): after an
    /// update of one obstacle, the successor takes over the others' substitutions, and
    /// they — with the box tests, the grid, the frames and the reaches — are those a fresh
    /// kernel makes; the moved obstacle's is made anew.
    #[test]
    fn a_successor_far_from_the_origin_holds_what_a_fresh_kernel_builds() {
        let (n, origin) = (80, 4.0e6);
        let (cache, s1, deltas, k1, _) = first_revision_at(n, origin);
        let (_, old_pairs) = k1.framed().framed_pairs_for_test(&s1).expect("a frame of its own far from the origin");
        let s2 = Arc::new(Scene::from_file_reusing(disks_at(n, 10, 3.0, origin), &cache, Some(&s1)).unwrap());
        let k2 = k1.successor(s2.clone());
        let fresh = SceneKernel::new(s2.clone());
        let (carried, pairs) = k2.framed().framed_pairs_for_test(&s2).unwrap();
        assert_eq!(carried, n - 1, "taken over: all but the moved obstacle's");
        let (made, fresh_pairs) = fresh.framed().framed_pairs_for_test(&s2).unwrap();
        assert_eq!(made, 0);
        for (i, (a, b)) in pairs.iter().zip(&fresh_pairs).enumerate() {
            assert!(a == b, "obstacle {i}: the successor's framed polynomials differ from a fresh build");
        }
        assert_ne!(old_pairs[10], pairs[10], "the moved obstacle's are its own");
        same_as_fresh(&k2, &fresh, &deltas);
    }
}
