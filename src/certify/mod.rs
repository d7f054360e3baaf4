//! Continuous-time certification (eq. (15), `SOS_Cond`) — layer L2.
//!
//! A trajectory piece is safe for an obstacle over its whole time interval when both
//! contour constraints composed with the piece are positive on the interval
//! (algorithms.md §3). Everything here reduces to positivity of a univariate
//! polynomial on [0, 1]; see [`Verdict`].

pub mod sos;
mod verdict;

pub use verdict::{Undecided, Verdict, Witness};
