//! What the checkers of one scene share, built on first use and kept by whoever keeps
//! the scene alive (a server's registry entry, a prepared plan): the compiled contours
//! (independent of Δ), the verify path's framed contours, and the covers of the last
//! few risk allocations (docs/design.md §5.10, §5.12).
//!
//! The kernel owns its scene (`Arc<Scene>`), so what it caches can never belong to
//! another scene: a changed scene is a new scene and gets a new kernel.

use super::framed::FramedContours;
use super::index::{scene_frame, SceneIndex};
use crate::certify::fast::CompiledContour;
use crate::contour::RiskLevel;
use crate::scene::Scene;
use std::sync::{Arc, Mutex, OnceLock};

/// Indexes kept per scene (one per distinct list of per-obstacle risk levels).
pub const INDEXES_PER_SCENE: usize = 4;

/// A scene with what its checkers cache (cheap to clone: the caches are shared).
#[derive(Clone)]
pub struct SceneKernel {
    inner: Arc<Inner>,
}

struct Inner {
    scene: Arc<Scene>,
    compiled: OnceLock<Arc<Vec<CompiledContour>>>,
    framed: OnceLock<Arc<FramedContours>>,
    indexes: Mutex<Vec<(Vec<RiskLevel>, Arc<SceneIndex>)>>,
}

impl std::fmt::Debug for SceneKernel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneKernel")
            .field("scene", &self.inner.scene.name)
            .field("compiled", &self.inner.compiled.get().map(|c| c.len()))
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
        SceneKernel {
            inner: Arc::new(Inner {
                scene,
                compiled: OnceLock::new(),
                framed: OnceLock::new(),
                indexes: Mutex::new(Vec::new()),
            }),
        }
    }

    /// The scene.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.inner.scene
    }

    /// The scene's compiled contours (built once, shared by every checker of the scene).
    pub fn compiled(&self) -> Arc<Vec<CompiledContour>> {
        let scene = &self.inner.scene;
        self.inner
            .compiled
            .get_or_init(|| {
                let frame = scene_frame(scene);
                Arc::new(scene.obstacles.iter().map(|o| CompiledContour::new(&o.contour, &frame)).collect())
            })
            .clone()
    }

    /// The scene's contours in the verify path's own frame (built once, shared by every
    /// final check of the scene; docs/design.md §5.12).
    pub fn framed(&self) -> Arc<FramedContours> {
        self.inner.framed.get_or_init(|| Arc::new(FramedContours::new(&self.inner.scene))).clone()
    }

    /// The index at `deltas` if this kernel holds it (never builds).
    pub fn peek_index(&self, deltas: &[RiskLevel]) -> Option<Arc<SceneIndex>> {
        let v = self.inner.indexes.lock().ok()?;
        v.iter().find(|(d, _)| d == deltas).map(|e| e.1.clone())
    }

    /// The index at `deltas`, built if absent (asking `stop` between obstacles); kept
    /// only when complete, among the last `INDEXES_PER_SCENE`.
    pub fn index(&self, deltas: &[RiskLevel], stop: &dyn Fn() -> bool) -> Arc<SceneIndex> {
        if let Some(i) = self.peek_index(deltas) {
            return i;
        }
        let built = Arc::new(SceneIndex::build(&self.inner.scene, deltas, stop));
        if built.complete() {
            if let Ok(mut v) = self.inner.indexes.lock() {
                v.retain(|(d, _)| d != deltas);
                if v.len() >= INDEXES_PER_SCENE {
                    v.remove(0);
                }
                v.push((deltas.to_vec(), built.clone()));
            }
        }
        built
    }
}
