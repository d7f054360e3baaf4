//! The motion checker's fast path (docs/design.md §5.10): compiled contours, proven
//! covers of each obstacle's unsafe set, and a grid so that an edge meets only the
//! obstacles near it.
//!
//! Nothing here decides "safe" by itself except with a proof:
//! - an obstacle is skipped for a piece only when the piece lies in the workspace and
//!   its bounding box misses the obstacle's proven cover ([`crate::outer_boxes`])
//!   during every time slab the piece spans;
//! - the others are decided on the compiled restriction ([`crate::compiled`]) by
//!   the Bernstein checker, with the exact rational fallback unchanged.

use crate::compiled::{FPoly, Frame};
use crate::outer_boxes::{unsafe_cover, ConstraintBounds, Cover};
use crate::PieceRef;
use riskplan_math::contour::tail::tail_kappa;
use riskplan_math::contour::RiskLevel;
use riskplan_math::poly::Interval;
use riskplan_scene::{ContourCell, Scene};
use std::sync::Arc;

/// Time slabs per horizon for a moving obstacle's covers: a piece is tested against
/// the covers of the slabs it spans; more slabs give tighter boxes at more set-up cost.
pub const TIME_SLABS: usize = 8;

/// Below this many obstacles every obstacle's cover is tested directly (a grid costs
/// more than it saves).
pub const GRID_MIN_OBSTACLES: usize = 16;

/// Grid cells per obstacle (the grid has about this many cells per obstacle, at most
/// [`GRID_MAX_CELLS`]).
pub const GRID_CELLS_PER_OBSTACLE: usize = 4;

/// Upper bound on grid cells.
pub const GRID_MAX_CELLS: usize = 1 << 16;

/// The frame of the compiled contours (docs/design.md §5.10): centred at
/// [`Scene::center`], scaled by powers of two about the workspace's half-widths and half
/// the horizon, so that the compiled numbers do not depend on the scene's units.
pub fn scene_frame(scene: &Scene) -> Frame {
    let ws = &scene.workspace;
    let mut half: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(l, u)| 0.5 * u - 0.5 * l).collect();
    half.push(0.5 * scene.horizon.1 - 0.5 * scene.horizon.0);
    Frame::new(&scene.center(), &half)
}

/// Below this many obstacles an index builds each obstacle's covers lazily: the motion
/// checker decides an obstacle without covers directly (about a microsecond on the
/// compiled restriction) and asks for its covers only after [`LAZY_COVER_CHECKS`]
/// pieces were checked against it, so that a cold plan pays for the covers of the
/// obstacles its edges keep meeting, not for all (docs/design.md §5.10). From this many
/// on every cover is built at once, and the grid over them.
pub const LAZY_MAX_OBSTACLES: usize = GRID_MIN_OBSTACLES;

/// Fewest obstacles without covers for which [`SceneIndex::ensure_all_on`] builds covers
/// on more than one thread: a cover costs 0.3–1 ms (512 disks: about 0.5 ms each, half of a
/// cold plan's CPU), a scoped thread about 0.1 ms to start; from this many obstacles on a
/// plan builds every cover at once ([`LAZY_MAX_OBSTACLES`]).
pub const PARALLEL_COVERS_MIN: usize = GRID_MIN_OBSTACLES;

/// Most threads that build one index's covers at once ([`SceneIndex::ensure_all_on`]).
pub const MAX_COVER_BUILD_THREADS: usize = 4;

/// Direct checks of one obstacle after which its covers are built: a static obstacle's
/// covers cost about as much as a few hundred direct checks of it (0.3–1 ms against
/// 1–3 µs measured on the reference scenes), the rule of ski rental.
pub const LAZY_COVER_CHECKS: u32 = 256;

/// Obstacles' covers built and kept by every index of the process (a count for the
/// service's metrics, `riskplan_covers_built_total`).
static COVERS_BUILT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// How many obstacles' covers (all their time slabs) the process has built and kept so
/// far, over every scene and risk level; covers taken over from a previous revision are
/// not counted again.
pub fn covers_built_total() -> u64 {
    COVERS_BUILT.load(std::sync::atomic::Ordering::Relaxed)
}

/// Covers and a grid for one scene and one risk level per obstacle. Each obstacle's
/// covers are built once, on demand ([`SceneIndex::ensure`]) or all at once
/// ([`SceneIndex::ensure_all`]); an obstacle without covers is always a candidate.
#[derive(Debug)]
pub struct SceneIndex {
    covers: Vec<std::sync::OnceLock<ObstacleCovers>>,
    /// Pieces checked directly against each obstacle that has no covers yet.
    checks: Vec<std::sync::atomic::AtomicU32>,
    /// Each obstacle's contour cell and risk level the covers were built for (to take
    /// them over in the next revision of the scene when both are unchanged). The cells
    /// are held, so that their identities cannot be reused by other contours.
    keys: Vec<(ContourCell, RiskLevel)>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    horizon: (f64, f64),
    grid: std::sync::OnceLock<Grid>,
    /// Nanoseconds spent building the covers.
    build_nanos: std::sync::atomic::AtomicU64,
    /// Cells evaluated.
    cells: std::sync::atomic::AtomicUsize,
    /// [`SceneIndex::typical_extent`] once every cover is built.
    extent: std::sync::OnceLock<f64>,
}

mod covers;
mod grid;
mod lookup;
mod parts;
#[cfg(test)]
mod tests;

pub use covers::*;
pub use grid::*;
pub use parts::*;
