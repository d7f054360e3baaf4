//! # riskplan
//!
//! Continuous-time risk-bounded trajectory planning with *certified* risk
//! contours, after Jasour, Han and Williams, "Convex Risk Bounded Continuous-Time
//! Trajectory Planning in Uncertain Nonconvex Environments" (RSS 2021).
//!
//! An obstacle is the set `{x : P(x, ω, t) ≥ 0}` with uncertain parameters ω. From
//! the moments of ω the polynomials E[P] and E[P²] in (x, t) give, for a risk
//! level Δ, the Cantelli inner approximation of the Δ-risk contour (eqs. 10, 12):
//!
//! ```text
//! Ĉ^Δ = { x : E[P]² − (1−Δ)·E[P²] ≥ 0,  −E[P] ≥ 0 }
//! ```
//!
//! Every point of Ĉ^Δ has probability of collision with that obstacle at most Δ
//! (Theorem 1). The guarantee is **per obstacle and per instant**; with several
//! obstacles the total probability of collision can reach (number of obstacles)·Δ.
//!
//! Layers, bottom to top (docs/architecture.md; `tests/integration/architecture.rs`
//! fails on any import that runs upward or loops): [`poly`] → [`moments`], [`sdp`] →
//! [`contour`], [`relax`] → [`mc`] → [`scene`] → [`motion`] → [`certify`] → [`plan`],
//! [`verify`] → [`app`] → `service`, `viz` → the command-line tool. The core (below
//! [`app`]) does no I/O and has no async code.
//!
//! Section numbers (§) in the doc comments refer to `docs/design.md`, the project's
//! design document; equation numbers refer to the paper.
#![warn(missing_docs)]

pub mod app;
pub mod certify;
pub mod contour;
pub mod mc;
pub mod moments;
pub mod motion;
pub mod plan;
pub mod poly;
pub mod relax;
pub mod scene;
pub mod sdp;
#[cfg(feature = "proto")]
pub mod service;
pub mod verify;
#[cfg(feature = "cli")]
pub mod viz;
