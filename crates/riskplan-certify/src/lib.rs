//! Continuous-time certification (eq. (15), `SOS_Cond`).
//!
//! A trajectory piece is safe for an obstacle over its whole time interval when both
//! contour constraints composed with the piece are positive on the interval
//! (docs/design.md §5). Everything here reduces to positivity of a univariate
//! polynomial on [0, 1]; see [`Verdict`]. Two independent deciders: [`bernstein`]
//! (exact subdivision, no SDP) and [`sos`] (the SOS certificate of eq. (15) on
//! Clarabel, re-checked rigorously); [`sturm`] is the exact oracle of the tests.
//! [`scene`] certifies pieces against a whole scene: the planners' motion checker and
//! the verify path.
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan-plan`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan_plan::Problem;
//! ```

pub mod bernstein;
pub mod bounds;
mod compose;
pub mod fast;
pub mod path_risk;
pub mod region;
pub mod scene;
pub mod sos;
pub mod sturm;
pub mod tail;
mod verdict;

pub use bernstein::{check, check_exact, check_interval, DEFAULT_MAX_DEPTH};
pub use compose::{
    coordinates_exact, interval_substitutions, restrict_exact, restrict_interval, restrict_poly_exact, PieceRef,
    Restricted,
};
pub use verdict::{Undecided, Verdict, Witness};
