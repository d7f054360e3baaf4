//! The mathematics of riskplan, below every scene and planner: sparse polynomials
//! over exact rationals, f64 and outward-rounded intervals (`poly`), the uncertain
//! parameters' distributions and exact moments (`moments`), the conic modelling layer
//! over Clarabel (`sdp`), risk contours and their bounds (`contour`, eqs. 10 and 12 of
//! the paper), moment relaxations (`relax`) and Monte Carlo risk estimates (`mc`).
//!
//! Layers inside this crate, bottom to top (docs/architecture.md): `poly` → `moments`,
//! `sdp` → `contour`, `relax` → `mc`. No I/O, no async. Section numbers (§) refer to
//! `docs/design.md`, equation numbers to the paper.
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan-scene`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan_scene::Scene;
//! ```
#![warn(missing_docs)]

pub mod contour;
pub mod mc;
pub mod moments;
pub mod poly;
pub mod relax;
pub mod sdp;
