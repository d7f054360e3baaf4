//! Verdicts of a positivity check of a univariate polynomial on [0, 1].
//!
//! Every certifier in riskplan reduces to one question (docs/design.md §5.1): given
//! `p(τ)`, the restriction of a contour constraint to a trajectory piece with the
//! piece's time interval rescaled to τ ∈ [0, 1], is `p(τ) > 0` for every τ in
//! [0, 1]? Strict positivity is required: touching the contour is unsafe (§3.2).
//!
//! Only [`Verdict::Safe`] may ever be treated as safe. [`Verdict::Undecided`] (a
//! tangency the method cannot resolve, a solver failure) counts as not safe.

use serde::Serialize;

/// A point that refutes positivity: `p(tau) ≤ 0`, proven (exactly or by an
/// outward-rounded enclosure whose upper end is ≤ 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Witness {
    /// Local time in [0, 1] (a float, so it can be re-checked exactly).
    pub tau: f64,
    /// `p(tau)` (rounded to f64 for reporting; its sign is proven).
    pub value: f64,
}

/// Why a method could not decide.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum Undecided {
    /// Subdivision reached its depth limit without a proof either way (near tangency).
    DepthLimit,
    /// The SDP solver did not return a usable solution (its status is given).
    Solver(String),
    /// The SDP solution did not survive the rigorous floating-point re-check.
    CertificateRejected(String),
    /// The margin is positive but too small to be trusted (below the acceptance threshold).
    MarginTooSmall(f64),
    /// Coefficients are not finite (overflow).
    NonFinite,
}

/// The outcome of a positivity check on [0, 1].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum Verdict {
    /// `p > 0` on [0, 1], proven. `margin` is a proven lower bound on `min p` (> 0)
    /// in the units of `p` as given.
    Safe {
        /// Proven lower bound on `min_{[0,1]} p`.
        margin: f64,
    },
    /// `p(τ) ≤ 0` somewhere, proven by the witness.
    Unsafe(Witness),
    /// No proof either way; never counts as safe.
    Undecided(Undecided),
}

impl Verdict {
    /// Whether this verdict proves safety.
    pub fn is_safe(&self) -> bool {
        matches!(self, Verdict::Safe { .. })
    }
    /// Whether this verdict proves a violation.
    pub fn is_unsafe(&self) -> bool {
        matches!(self, Verdict::Unsafe(_))
    }
}
