//! Continuous-time certification (eq. (15), `SOS_Cond`).
//!
//! A trajectory piece is safe for an obstacle over its whole time interval when both
//! contour constraints composed with the piece are positive on the interval
//! (docs/design.md §5). The crate's parts, by job:
//!
//! - the constraints restricted to a piece ([`restrict_exact`], [`restrict_interval`]),
//!   and the same compiled once per obstacle so that a restriction allocates nothing
//!   ([`compiled`]);
//! - positivity of a univariate polynomial on [0, 1] ([`positivity`]: the exact
//!   Bernstein subdivision, the SOS certificate re-checked rigorously, Sturm sequences as
//!   the tests' oracle; their [`Verdict`]);
//! - the bounds beyond Cantelli over one piece ([`piece_bounds`]) and a pedestrian's
//!   Gaussian tail ([`gaussian_tail`]);
//! - proven outer boxes of an obstacle's unsafe set ([`outer_boxes`]), the checker's
//!   pre-filter;
//! - the whole-path bound ([`whole_path`], §5.14);
//! - certification against a whole scene ([`checker`]): the decision of one obstacle over
//!   one piece, the planners' motion checker with its index of covers, the verify path of
//!   the final check, and the kernel that caches what they build for one scene.
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan-plan`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan_plan::Problem;
//! ```

pub mod checker;
pub mod compiled;
pub mod gaussian_tail;
pub mod outer_boxes;
pub mod piece_bounds;
pub mod positivity;
mod restrict;
pub mod whole_path;

pub use positivity::bernstein::{check, check_exact, check_interval, DEFAULT_MAX_DEPTH};
pub use positivity::{Undecided, Verdict, Witness};
pub use restrict::{
    coordinates_exact, interval_substitutions, restrict_exact, restrict_interval, restrict_poly_exact, PieceRef,
    Restricted,
};
