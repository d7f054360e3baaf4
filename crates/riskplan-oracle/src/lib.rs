//! # riskplan-oracle
//!
//! The robustness suite of riskplan without riskplan: a seeded scene generator
//! ([`generate()`]), an independent feasibility oracle ([`oracle`], with its own
//! quadrature in [`quadrature`]). The runner that plans, audits and certifies each scene
//! and summarises the results is `riskplan_testkit::runner`, and the bench is the
//! testkit's `robustness` binary
//! (`cargo run --release -p riskplan-testkit --bin robustness`).
//!
//! Beside it, an independent oracle for the product's risk **bounds** at a point
//! ([`bounds`]): scenes read from their JSON ([`SceneBounds`], with the oracle's own
//! polynomial-text parser and evaluator [`expr`] and distribution reader [`scene_json`]),
//! E[P^j] for j ≤ 8 by tensor-product Gauss rules of any order
//! ([`quadrature::rule_with_nodes`]), the Cantelli and shifted moment bounds computed
//! from node values, support-grid evidence, Monte Carlo counts and binomial confidence
//! limits.
//!
//! The generator covers 2-D and 3-D scenes, workspaces 1–100 units wide anywhere within
//! ±1000, horizons with t₀ ≠ 0, Δ in [0.01, 0.2], disks/balls, ellipses/ellipsoids and
//! nonconvex quartics, static, linearly and quadratically moving obstacles,
//! "pedestrians" (moving disks/balls with Gaussian position and velocity errors per
//! axis), every distribution family of the scene format, and intentionally infeasible
//! scenes of three kinds. The oracle judges each scene with none of riskplan's moment,
//! polynomial, contour, certification or verification code, so that a disagreement
//! between it and the planners points at one of them. This crate does not depend on
//! `riskplan` at all, so the compiler checks that independence.
//!
//! Pure computation: no file I/O, no async. Malformed input (a hand-made
//! [`GeneratedScene`] or [`generate::Dist`]) gives an error ([`OracleError`],
//! [`quadrature::QuadratureError`]) or a NaN, never a panic.
#![warn(missing_docs)]

pub mod bounds;
pub mod expr;
pub mod generate;
pub mod oracle;
pub mod quadrature;
pub mod scene_json;

pub use bounds::{
    binomial_lower_limit, binomial_upper_limit, BoundsError, ObstacleBounds, ParamRule, PointMoments, SceneBounds,
};
pub use expr::{Bound, Expr, ExprError};
pub use generate::{generate, GeneratedScene};
pub use oracle::{judge, Judgement, OracleError, OracleOptions, OracleReport};
pub use quadrature::{rule_exact_to, rule_with_nodes, QuadratureError, Rule};
pub use scene_json::SceneJsonError;

#[cfg(test)]
mod tests {
    use super::generate::Intent;
    use super::oracle::InfeasibleReason;
    use super::*;

    /// The oracle over a whole suite: every intentionally infeasible scene is judged
    /// infeasible for its intended reason, no intentionally infeasible scene is judged
    /// feasible, and most intended-feasible scenes are judged feasible. (The oracle's
    /// time over the suite is printed here and by the robustness bench, not asserted:
    /// a wall-clock limit depends on the machine and its load.)
    #[test]
    fn oracle_judges_the_suite() {
        let t = std::time::Instant::now();
        let mut counts = std::collections::BTreeMap::<String, usize>::new();
        let mut feasible_ok = 0;
        let mut intended_feasible = 0;
        let mut slowest = (0.0, 0);
        for i in 0..120 {
            let g = generate(1, i);
            let ti = std::time::Instant::now();
            let r = judge(&g, &OracleOptions::default()).unwrap();
            let dt = ti.elapsed().as_secs_f64();
            if dt > slowest.0 {
                slowest = (dt, i);
            }
            *counts.entry(format!("{:?} → {}", g.intent, r.judgement.label())).or_default() += 1;
            match (g.intent, &r.judgement) {
                (Intent::Feasible, Judgement::Feasible { .. }) => {
                    feasible_ok += 1;
                    intended_feasible += 1;
                }
                (Intent::Feasible, _) => intended_feasible += 1,
                (Intent::EndpointInObstacle, j) => assert!(
                    matches!(j, Judgement::Infeasible { reason: InfeasibleReason::EndpointUnsafe { .. } }),
                    "scene {i}: {j:?}"
                ),
                (Intent::OutOfReach, j) => assert!(
                    matches!(j, Judgement::Infeasible { reason: InfeasibleReason::OutOfReach { .. } }),
                    "scene {i}: {j:?}"
                ),
                (Intent::Wall, j) => assert!(
                    matches!(j, Judgement::Infeasible { reason: InfeasibleReason::Disconnected }),
                    "scene {i}: {j:?}"
                ),
            }
        }
        let total = t.elapsed().as_secs_f64();
        eprintln!("oracle over 120 scenes: {total:.2} s (slowest scene {} {:.2} s); {counts:?}", slowest.1, slowest.0);
        assert!(feasible_ok * 10 >= intended_feasible * 8, "{feasible_ok}/{intended_feasible} {counts:?}");
    }
}
