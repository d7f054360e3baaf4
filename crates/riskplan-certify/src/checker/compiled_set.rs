//! A scene's compiled contours, each compiled on first use (docs/design.md §5.10).

use super::cover_index::scene_frame;
use crate::compiled::{CompiledContour, Frame};
use riskplan_scene::Scene;
use std::sync::{Arc, OnceLock};

/// A scene's compiled contours (docs/design.md §5.10), one per obstacle, each compiled
/// on first use: an obstacle no edge comes near, or a pedestrian decided by its tail
/// bound (§3.11), is never compiled.
pub struct CompiledSet {
    scene: Arc<Scene>,
    frame: Frame,
    items: Vec<OnceLock<Arc<CompiledContour>>>,
}

impl std::fmt::Debug for CompiledSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CompiledSet").field("obstacles", &self.items.len()).field("built", &self.built()).finish()
    }
}

impl CompiledSet {
    /// Nothing compiled yet.
    pub fn new(scene: Arc<Scene>) -> CompiledSet {
        let frame = scene_frame(&scene);
        let items = scene.obstacles.iter().map(|_| OnceLock::new()).collect();
        CompiledSet { scene, frame, items }
    }

    /// The frame of every compiled contour of the scene.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Nothing compiled yet but what `old` (the previous revision's) compiled for the same
    /// contour in the same frame.
    pub fn reusing(scene: Arc<Scene>, old: &CompiledSet) -> CompiledSet {
        let set = CompiledSet::new(scene);
        if set.frame == old.frame {
            for (o, item) in set.scene.obstacles.iter().zip(&set.items) {
                let key = o.contour.key();
                let found = old.scene.obstacles.iter().zip(&old.items).find(|(p, _)| p.contour.key() == key);
                if let Some(c) = found.and_then(|(_, c)| c.get()) {
                    let _ = item.set(c.clone());
                }
            }
        }
        set
    }

    /// Obstacle `i`'s compiled contour (compiled now if it was not). `i` must be an
    /// obstacle of the scene.
    pub fn get(&self, i: usize) -> &CompiledContour {
        self.items[i].get_or_init(|| Arc::new(CompiledContour::new(&self.scene.obstacles[i].contour, &self.frame)))
    }

    /// Whether obstacle `i`'s contour is compiled, and with `bounds` its bounds beyond
    /// Cantelli too (for tests).
    pub fn is_built(&self, i: usize, bounds: bool) -> bool {
        self.items.get(i).and_then(|c| c.get()).is_some_and(|c| !bounds || c.bounds_built())
    }

    /// How many are compiled.
    pub fn built(&self) -> usize {
        self.items.iter().filter(|c| c.get().is_some()).count()
    }

    /// Number of obstacles.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether the scene has no obstacle.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}
