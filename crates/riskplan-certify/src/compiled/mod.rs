//! The compiled restriction: contour polynomials prepared once per obstacle so that
//! restricting them to a trajectory piece allocates nothing (docs/design.md §5.1, §5.10).
//!
//! [`crate::restrict_interval`] composes the contour polynomials with a piece through
//! general polynomial objects, a heap allocation per product; for a planner's edge
//! that bookkeeping costs far more than the positivity proof itself. Here E\[P\] and
//! E\[P²\] are compiled once into a Horner tree ([`Compiled`]) over **centred**
//! variables `y = x − c`, `s = t − t_c`, and a piece's coordinates are substituted as
//! fixed-capacity univariate interval polynomials ([`FPoly`]), on the stack.
//!
//! Soundness is the same as the interval restriction's: the compiled coefficients are
//! outward-rounded enclosures of the *exact* centred polynomial (the shift is done in
//! rationals), every operation is outward rounded, so the resulting coefficients
//! enclose those of the exact restriction `e1(τ)`, `e2(τ)` of eq. (15). Centring
//! matters off the paper's unit scenes: a workspace at x ≈ 1000 makes the monomials of
//! the uncentred polynomial cancel by many orders of magnitude, and the enclosures
//! lose as many digits; in centred variables the coefficients stay at the scale of the
//! obstacle.

mod higher_bounds;
pub use higher_bounds::{restricted, CompiledBounds};

use crate::positivity::bernstein::MAX_DEGREE;
use crate::restrict::PieceRef;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};
use riskplan_math::contour::RiskContour;
use riskplan_math::poly::{Interval, Poly, QPoly, UPoly};

mod arith;
mod contour;
mod frame;
mod horner;
#[cfg(test)]
mod tests;

pub use arith::*;
pub use contour::*;
pub use frame::*;
pub use horner::*;
