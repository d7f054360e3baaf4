//! The verify path's own frame for the final check (docs/design.md §5.12).

use super::decide::Interrupted;
use super::workspace::{check_workspace, interval_hull};
use super::Status;
use crate::piece_bounds::{Level, PieceBounds};
use crate::{positivity::bernstein, restrict_exact, PieceRef, Verdict};
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
/// deliberately not the compiled path's frame code (`certify::compiled`, whose exact
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

mod contours;
mod grid;
mod near;
mod piece;
#[cfg(test)]
mod tests;

pub use grid::*;
pub use near::*;
pub use piece::*;
