//! The warm-up of a scene's kernel: what the first plans on a new scene would build,
//! built before any request (docs/design.md §3.11 "Warm-ups").

use crate::request::PlanRequest;
use crate::verify::SceneKernel;

/// What [`warm_up`] built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarmUp {
    /// Everything a default plan's checker and final check build on a cold scene
    /// ([`SceneKernel::is_warm`] at the scene's Δ).
    Done,
    /// `stop` said stop first: what was finished is kept, the rest is built on first use.
    Stopped,
}

/// Builds ahead of any request what a default plan (per-obstacle risk at the scene's Δ)
/// builds on first use on a new scene (docs/design.md §3.11 "Warm-ups", §5.10): the final
/// check's box tests and their grid (§5.12), the whole-path bound's frames and reaches
/// (§5.14), and the checker's proven covers and their grid (the scene index) — on 512
/// disks about 0.8 s that a cold plan would otherwise spend before its answer — and last
/// what plans build per obstacle where their edges go ([`SceneKernel::build_obstacle`]: the
/// compiled contour and bounds, the verify path's framed contours; without them a first pass
/// of plans on 512 disks took twice a steady plan's time). Every part is cached by `kernel`,
/// so the plans that follow find them, and a plan running meanwhile shares them: the covers
/// are built here from the last obstacle down, so that a plan building them from the first
/// up meets this warm-up halfway instead of building the same ones beside it. Nothing about
/// a plan's outcome depends on whether they were built before it. `stop` is asked between
/// obstacles.
pub fn warm_up(kernel: &SceneKernel, stop: &dyn Fn() -> bool) -> WarmUp {
    let scene = kernel.scene();
    let deltas = vec![scene.risk.clone(); scene.obstacles.len()];
    // (the final check's and the whole-path parts first: a plan that arrives meanwhile
    // builds the covers its search needs, and finds these built or being built)
    if kernel.framed().grid(scene, &deltas, stop).is_err() || kernel.path_reaches(stop).is_err() {
        return WarmUp::Stopped;
    }
    let index = kernel.lazy_index(&deltas);
    for i in (0..scene.obstacles.len()).rev() {
        if stop() {
            return WarmUp::Stopped;
        }
        index.ensure(scene, i, stop);
    }
    // (every cover built or tried: the grid over them)
    let _ = kernel.index(&deltas, stop);
    // then what a first pass of plans still builds per obstacle where its edges go (each
    // obstacle's compiled contour and bounds), so that the first plan after the warm-up
    // costs what a steady one does
    let beyond = PlanRequest::default().bound_on(scene).beyond_cantelli();
    for i in (0..scene.obstacles.len()).rev() {
        if stop() {
            return WarmUp::Stopped;
        }
        kernel.build_obstacle(i, beyond);
    }
    if kernel.is_warm(&deltas) {
        WarmUp::Done
    } else {
        WarmUp::Stopped
    }
}
