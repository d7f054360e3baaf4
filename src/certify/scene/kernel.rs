//! What the checkers of one scene share, built on first use and kept by whoever keeps
//! the scene alive (a server's registry entry, a prepared plan): the compiled contours
//! (independent of Δ), the verify path's framed contours, and the covers of the last
//! few risk allocations (docs/design.md §5.10, §5.12).
//!
//! The kernel owns its scene (`Arc<Scene>`), so what it caches can never belong to
//! another scene: a changed scene is a new scene and gets a new kernel.

use super::framed::FramedContours;
use super::index::SceneIndex;
pub use super::compiled::CompiledSet;
use super::decide::Interrupted;
use crate::certify::fast::Frame;
use crate::certify::path_risk::{Reach, ReachGrid};
use crate::contour::RiskLevel;
use crate::scene::Scene;
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
    /// Per obstacle, where in the workspace × horizon it may be met ([`SceneKernel::path_reach`]).
    path_reach: Vec<OnceLock<Option<Arc<Reach>>>>,
    /// The reaches in a grid ([`SceneKernel::path_reach_grid`]).
    path_reach_grid: OnceLock<Option<Arc<ReachGrid>>>,
    indexes: Mutex<Vec<(Vec<RiskLevel>, Arc<SceneIndex>)>>,
    /// The indexes of the scene's previous revision, whose covers of unchanged obstacles
    /// the indexes built here take over.
    previous: Vec<Arc<SceneIndex>>,
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
                path_reach,
                path_reach_grid: OnceLock::new(),
                indexes: Mutex::new(Vec::new()),
                previous: Vec::new(),
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
        let path_reach = (0..scene.obstacles.len()).map(|_| OnceLock::new()).collect();
        SceneKernel {
            inner: Arc::new(Inner {
                scene,
                compiled,
                framed: OnceLock::new(),
                path_frames: OnceLock::new(),
                path_reach,
                path_reach_grid: OnceLock::new(),
                indexes: Mutex::new(Vec::new()),
                previous,
            }),
        }
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
    /// — the centre refined ([`super::index::refine_center`]), the scales kept. Far from
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
            if stop() {
                return Err(Interrupted);
            }
            let c = o.contour.get();
            let centre = near.and_then(|n| n.get(i)?.as_ref()).filter(|_| !c.is_dynamic());
            let frame = match centre {
                Some(n) => {
                    let mut center = super::index::refine_center(c, n.center(), &region);
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
        let grid = self.inner.path_reach_grid.get_or_init(|| ReachGrid::new(&self.reach_region(), &reaches).map(Arc::new)).clone();
        Ok((frames, reaches, grid))
    }

    /// The index at `deltas` if this kernel holds it (never builds).
    pub fn peek_index(&self, deltas: &[RiskLevel]) -> Option<Arc<SceneIndex>> {
        let v = self.inner.indexes.lock().ok()?;
        v.iter().find(|(d, _)| d == deltas).map(|e| e.1.clone())
    }

    /// The index at `deltas` with every obstacle's covers built (asking `stop` between
    /// obstacles; what a stop leaves unbuilt is built by a later call). Kept among the
    /// last [`INDEXES_PER_SCENE`].
    pub fn index(&self, deltas: &[RiskLevel], stop: &dyn Fn() -> bool) -> Arc<SceneIndex> {
        let index = self.lazy_index(deltas);
        index.ensure_all(&self.inner.scene, stop);
        index
    }

    /// The index at `deltas`, made if absent with no covers built but those taken over
    /// from the previous revision (its obstacles' covers are built on demand:
    /// [`SceneIndex::ensure`]). Kept among the last [`INDEXES_PER_SCENE`].
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
