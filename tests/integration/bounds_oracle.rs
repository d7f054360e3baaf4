//! Every risk bound against an oracle that shares no code with the crate's moments,
//! contours or certifiers: `riskplan_oracle::bounds` parses the scene's polynomial text
//! itself, integrates with its own Gauss rules (exact to order 8) and samples the
//! parameters itself.
//!
//! At random points (x, t) of every reference scene and of two more uncertainty shapes (a
//! Gaussian-centre disk, a pedestrian with velocity error) — half uniform in the
//! workspace and horizon, half where the oracle's Cantelli bound of some obstacle is
//! between 10⁻⁶ and ½ (near the contours, where the bounds matter) — and every obstacle:
//! - Cantelli's bound is the oracle's (relative 10⁻⁹);
//! - every shifted moment bound's proven value is at least the oracle's value of the same
//!   formula at the same shift (never below it: sound) and at most 10⁻⁶ above it (the
//!   value is the formula's, not some looser number);
//! - where zero risk is claimed from the support, the oracle finds P < 0 on a grid of the
//!   support box and no hit in its own Monte Carlo draws;
//! - the best bound is at least the lower confidence limit (10⁻⁹) of the oracle's Monte
//!   Carlo estimate of the true risk.

use super::common::{reference_files, size};
use num_rational::BigRational;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha12Rng;
use riskplan_certify::piece_bounds::point_bounds_proven;
use riskplan_math::poly::rational_to_f64;
use riskplan_scene::Scene;
use riskplan_testkit::riskplan_oracle::bounds::{binomial_lower_limit, SceneBounds};
use std::path::PathBuf;

/// Relative agreement of Cantelli's bound with the oracle's: both are computed from moments
/// exact to rounding (the crate's in rationals, the oracle's by Gauss quadrature exact for
/// the degree, ~10⁻¹³ relative), so 10⁻⁹ leaves four orders of margin.
const CANTELLI_REL: f64 = 1e-9;
/// How far above the oracle's value of the same formula a proven moment bound may be, where
/// that value is at least [`TIGHT_FROM`]: the proven value is the upper end of an interval
/// computation at the point (the central moments formed there, `central_at_point`;
/// measured ≤ 2·10⁻⁶ relative). Evaluating the expanded cⱼ(x, t) in intervals instead
/// overestimates many times over on example-B (the dependency problem), which this catches.
const FORMULA_ABOVE_REL: f64 = 1e-5;
/// Smallest formula value whose proven value must be within [`FORMULA_ABOVE_REL`] (below any
/// risk level a user sets).
const TIGHT_FROM: f64 = 1e-9;
/// Uniform draws tried per "near" point (the oracle's quadrature of a four-parameter
/// obstacle costs a fraction of a millisecond per draw).
const NEAR_TRIES: usize = 40;
/// How far below the oracle's value a proven bound may be before it counts as unsound:
/// the oracle's own rounding only.
const FORMULA_BELOW_REL: f64 = 1e-9;
/// Absolute slack of the formula comparisons (values below it are 0 for the test).
const FORMULA_ABS: f64 = 1e-13;
/// Confidence of the Monte Carlo lower limit per check: 10⁻⁹, so that the ~10⁵ checks of a
/// run raise no false alarm with probability above 10⁻⁴.
const MC_ALPHA: f64 = 1e-9;

fn scenes() -> Vec<PathBuf> {
    let mut v = reference_files();
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/bounds");
    let mut extra: Vec<PathBuf> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    extra.sort();
    v.extend(extra);
    v
}

#[derive(Default, Debug)]
struct Tally {
    points: usize,
    checks: usize,
    moment_checks: usize,
    support_zero: usize,
    mc_checks: usize,
    best_below_cantelli: usize,
    /// Largest relative excess of a proven moment bound over the oracle's formula.
    max_above: f64,
}

#[test]
fn every_bound_against_the_independent_oracle() {
    let n_points = size("BOUND_ORACLE_POINTS", 200, 10_000);
    let n_mc = size("BOUND_ORACLE_MC", 300, 1000);
    let mut failures: Vec<String> = Vec::new();
    for path in scenes() {
        let text = std::fs::read_to_string(&path).unwrap();
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        let scene = Scene::from_json(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        if scene.obstacles.is_empty() {
            continue;
        }
        let oracle = SceneBounds::from_scene_json(&json).unwrap_or_else(|e| panic!("{}: oracle: {e}", path.display()));
        let mut rng = ChaCha12Rng::seed_from_u64(19);
        let (lo, hi) = (scene.workspace.lower.clone(), scene.workspace.upper.clone());
        let (t0, t1) = scene.horizon;
        let mut tally = Tally::default();
        for k in 0..n_points {
            // a point: uniform, or (odd k) near some obstacle's contour by the oracle's Cantelli
            let draw = |rng: &mut ChaCha12Rng| -> (Vec<f64>, f64) {
                let x: Vec<f64> = lo.iter().zip(&hi).map(|(l, h)| l + (h - l) * rng.random::<f64>()).collect();
                (x, t0 + (t1 - t0) * rng.random::<f64>())
            };
            let (mut x, mut t) = draw(&mut rng);
            if k % 2 == 1 {
                for _ in 0..NEAR_TRIES {
                    let near = oracle.obstacles.iter().any(|o| {
                        let c = o.moments_at(&x, t).cantelli();
                        (1e-6..=0.5).contains(&c)
                    });
                    if near {
                        break;
                    }
                    (x, t) = draw(&mut rng);
                }
            }
            tally.points += 1;
            let mut xt: Vec<BigRational> = x.iter().map(|&v| BigRational::from_float(v).unwrap()).collect();
            xt.push(BigRational::from_float(t).unwrap());
            for o in &scene.obstacles {
                let ob = oracle.obstacle(&o.id).unwrap_or_else(|| panic!("{}: oracle lacks {}", scene.name, o.id));
                let pm = ob.moments_at(&x, t);
                let pb = point_bounds_proven(&o.contour, &xt);
                let at = format!("{} / {} at x = {x:?}, t = {t}", scene.name, o.id);
                tally.checks += 1;
                // Cantelli
                let c_crate = rational_to_f64(&pb.cantelli);
                let c_oracle = pm.cantelli();
                if (c_crate - c_oracle).abs() > CANTELLI_REL * c_oracle.abs().max(1e-300) + FORMULA_ABS {
                    failures.push(format!("{at}: Cantelli {c_crate} vs oracle {c_oracle}"));
                }
                // the moment bounds: the proven value is the formula's at its shift
                let mut best = c_crate;
                for m in &pb.moments {
                    let v = rational_to_f64(&m.value);
                    best = best.min(v);
                    if m.order > pm.max_order() {
                        continue;
                    }
                    tally.moment_checks += 1;
                    let f = pm.shifted(m.order, m.shift).min(1.0);
                    if v < f * (1.0 - FORMULA_BELOW_REL) - FORMULA_ABS {
                        failures.push(format!(
                            "{at}: moment{} at b = {}: proven {v} < oracle formula {f}",
                            m.order, m.shift
                        ));
                    }
                    if (TIGHT_FROM..1.0).contains(&f) {
                        tally.max_above = tally.max_above.max(v / f - 1.0);
                        if v > f * (1.0 + FORMULA_ABOVE_REL) {
                            failures.push(format!(
                                "{at}: moment{} at b = {}: proven {v} ≫ oracle formula {f}",
                                m.order, m.shift
                            ));
                        }
                    }
                }
                // zero risk from the support
                if pb.support_zero == Some(true) {
                    tally.support_zero += 1;
                    best = 0.0;
                    match ob.max_on_support_grid(&x, t, 9) {
                        Some(g) if g < 0.0 => {}
                        g => failures.push(format!("{at}: zero risk claimed, oracle's support grid max {g:?}")),
                    }
                    if let Some(h) = ob.mc_hits(&x, t, n_mc, &mut rng) {
                        if h > 0 {
                            failures.push(format!("{at}: zero risk claimed, oracle's Monte Carlo hit {h}/{n_mc}"));
                        }
                    }
                }
                if best < c_crate {
                    tally.best_below_cantelli += 1;
                }
                // the best bound against the true risk's lower confidence limit
                if let Some(h) = ob.mc_hits(&x, t, n_mc, &mut rng) {
                    tally.mc_checks += 1;
                    let lcl = binomial_lower_limit(h as u64, n_mc as u64, MC_ALPHA);
                    if best < lcl {
                        failures.push(format!("{at}: best bound {best} < Monte Carlo lower limit {lcl} ({h}/{n_mc})"));
                    }
                }
            }
        }
        eprintln!("{}: {tally:?}", scene.name);
        assert!(tally.points >= n_points);
    }
    assert!(failures.is_empty(), "{} failures, first: {:#?}", failures.len(), &failures[..failures.len().min(10)]);
}
