//! Every reference scene loads as it is, reproduces the values prepared with it,
//! and satisfies Theorem 1 against Monte Carlo.

use crate::common;

use num_rational::BigRational;
use rand::{Rng, SeedableRng};
use riskplan_math::mc::clopper_pearson;
use riskplan_math::poly::{parse, rational_to_f64};
use riskplan_scene::Scene;

#[test]
fn every_reference_scene_loads() {
    for f in common::reference_files() {
        let text = std::fs::read_to_string(&f).unwrap();
        let s = Scene::from_json(&text).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        assert!(!s.obstacles.is_empty(), "{}", f.display());
    }
}

/// The exact contour polynomials of illustrative-1 are the ones the scene file lists
/// (and the paper prints to four digits).
#[test]
fn illustrative_1_polynomials_match_the_file() {
    let s = common::scene("illustrative-1");
    let exp = &s.file.expected.as_ref().unwrap();
    let vars = s.vars.clone();
    let mut resolve = |n: &str| vars.get(n).ok_or_else(|| n.to_string());
    let e_p = parse(exp["E_P"].as_str().unwrap(), &mut resolve).unwrap();
    let e_p2 = parse(exp["E_P2"].as_str().unwrap(), &mut resolve).unwrap();
    let c = &s.obstacles[0].contour;
    assert_eq!(c.mean, e_p);
    assert_eq!(c.second, e_p2);
}

/// The spot values of `expected.derived_checks` (E[P], E[P²], Cantelli bound).
#[test]
fn spot_values_match_the_files() {
    let mut checked = 0;
    for f in common::reference_files() {
        let s = Scene::from_json(&std::fs::read_to_string(&f).unwrap()).unwrap();
        let Some(points) =
            s.file.expected.as_ref().and_then(|e| e["derived_checks"]["spot_values"]["points"].as_array().cloned())
        else {
            continue;
        };
        for p in points {
            let mut xt: Vec<f64> = p["x"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            xt.push(p["t"].as_f64().unwrap_or(0.0));
            let xq: Vec<BigRational> =
                xt.iter().map(|&v| riskplan_math::poly::f64_shortest_decimal(v).unwrap()).collect();
            for (id, want) in p["per_obstacle"].as_object().unwrap() {
                let o = s.obstacle(id).unwrap_or_else(|| panic!("{}: no obstacle {id}", f.display()));
                let r = o.contour.risk_at(&xq);
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-8 * (1.0 + b.abs());
                let (m, m2) = (rational_to_f64(&r.mean), rational_to_f64(&r.second_moment));
                assert!(close(m, want["E_P"].as_f64().unwrap()), "{} {id} E_P {m} vs {}", f.display(), want["E_P"]);
                assert!(
                    close(m2, want["E_P2"].as_f64().unwrap()),
                    "{} {id} E_P2 {m2} vs {}",
                    f.display(),
                    want["E_P2"]
                );
                if let Some(b) = want["cantelli_bound"].as_f64() {
                    assert!(close(rational_to_f64(&r.bound), b), "{} {id} bound", f.display());
                } else {
                    assert_eq!(r.bound, BigRational::from_integer(1.into()));
                }
                checked += 1;
            }
        }
    }
    assert!(checked >= 10, "only {checked} spot values checked");
}

/// Theorem 1 on every reference scene: at random points and times, and at points
/// near each Δ-contour (Δ ∈ {0.05, 0.1, 0.2}), the Cantelli bound is never below
/// the Monte Carlo lower confidence bound, and inside the Δ-contour the Monte Carlo
/// lower bound never exceeds Δ. The confidence is 1 − 1e-6 per comparison so that a
/// correct implementation fails with negligible probability over all comparisons.
#[test]
fn theorem_1_against_monte_carlo() {
    const SAMPLES: u64 = 20_000;
    const CONFIDENCE: f64 = 1.0 - 1e-6;
    let deltas = [0.05, 0.1, 0.2];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2021);
    let mut comparisons = 0;
    let mut inside = 0;
    let mut nontrivial = 0;
    for f in common::reference_files() {
        let s = Scene::from_json(&std::fs::read_to_string(&f).unwrap()).unwrap();
        let model = s.mc_model().unwrap();
        let random_point = |rng: &mut rand_chacha::ChaCha8Rng| -> Vec<f64> {
            let mut p: Vec<f64> =
                (0..s.dim).map(|i| rng.random_range(s.workspace.lower[i]..=s.workspace.upper[i])).collect();
            p.push(rng.random_range(s.horizon.0..=s.horizon.1));
            p
        };
        // 20 uniform points, plus for each obstacle and Δ up to 4 points with bound in [Δ/2, Δ].
        let mut points: Vec<Vec<f64>> = (0..20).map(|_| random_point(&mut rng)).collect();
        for o in &s.obstacles {
            for &d in &deltas {
                let mut found = 0;
                for _ in 0..20_000 {
                    let p = random_point(&mut rng);
                    let b = o.contour.bound_f64(&p);
                    if b <= d && b >= d / 2.0 {
                        points.push(p);
                        found += 1;
                        if found == 4 {
                            break;
                        }
                    }
                }
            }
        }
        let hits = model.hits(&points, SAMPLES, 7);
        for (p, h) in points.iter().zip(&hits) {
            let xq: Vec<BigRational> = p.iter().map(|&v| BigRational::from_float(v).unwrap()).collect();
            for (o, &k) in s.obstacles.iter().zip(h) {
                let bound = rational_to_f64(&o.contour.risk_at(&xq).bound);
                let (lower, _) = clopper_pearson(k, SAMPLES, CONFIDENCE);
                if lower > 0.0 {
                    nontrivial += 1;
                }
                assert!(
                    bound >= lower,
                    "{}: obstacle {} at {p:?}: Cantelli {bound} < MC lower {lower} ({k}/{SAMPLES})",
                    f.display(),
                    o.id
                );
                comparisons += 1;
                for &d in &deltas {
                    if bound <= d {
                        inside += 1;
                        assert!(
                            lower <= d,
                            "{}: {} at {p:?} is inside the {d}-contour but MC lower {lower} > Δ",
                            f.display(),
                            o.id
                        );
                    }
                }
            }
        }
    }
    println!("Theorem 1: {comparisons} point/obstacle comparisons, {inside} inside a Δ-contour, {nontrivial} with MC lower bound > 0");
    assert!(comparisons > 500 && inside > 200 && nontrivial > 20);
}
