//! Deciders of positivity on [0, 1] for one univariate polynomial (eq. (15)): the exact
//! Bernstein subdivision (`bernstein`), the SOS certificate re-checked rigorously
//! (`sos`), and Sturm sequences (`sturm`, the tests' exact oracle); their verdicts
//! (`Verdict`, with a witness or why undecided).

pub mod bernstein;
pub mod sos;
pub mod sturm;
mod verdict;

pub use verdict::{Undecided, Verdict, Witness};
