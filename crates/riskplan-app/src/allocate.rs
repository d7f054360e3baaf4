//! Risk allocation: the risk level Δᵢ of each obstacle for a risk mode (docs/design.md
//! §3.6).

use crate::verify::SceneKernel;
use num_rational::BigRational;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_plan::{PlanError, Problem, RiskMode};

/// The risk level of each obstacle for `mode` (docs/design.md §3.6): Δ for each in the
/// paper's mode; in a joint mode exact rationals with Σ Δᵢ = Δ, so that by Boole's
/// inequality the probability of colliding with any obstacle at an instant is ≤ Δ
/// (`kernel`: the scene's, whose covers weigh the obstacles near the straight path).
pub fn allocate(
    kernel: &SceneKernel,
    p: &Problem,
    mode: RiskMode,
    bounds: BoundChoice,
) -> Result<Vec<RiskLevel>, PlanError> {
    let n = p.scene.obstacles.len();
    let delta = p.delta.rational().clone();
    let weights: Vec<BigRational> = match mode {
        // trajectory: each obstacle's per-instant constraint at Δ (implied by the
        // whole-path budget, which the planners and the final check keep)
        RiskMode::PerObstacle | RiskMode::Trajectory => return Ok(vec![p.delta.clone(); n]),
        RiskMode::JointUniform => vec![BigRational::from_integer(1.into()); n],
        RiskMode::JointWeighted => {
            // covers at the uniform allocation locate each obstacle
            let uniform = RiskLevel::new(&delta / BigRational::from_integer(n.max(1).into()))
                .map_err(|e| PlanError::InvalidOption { option: "risk_mode".into(), message: e.to_string() })?;
            let index = kernel.index(&vec![uniform; n], &|| false);
            let side = riskplan_plan::scale::Scale::of(p).side.max(f64::MIN_POSITIVE);
            index
                .cover_hulls()
                .iter()
                .map(|h| {
                    let d = h.as_ref().map_or(f64::INFINITY, |b| box_segment_distance(b, &p.start, &p.goal));
                    // weights in [1/64, 1], rounded to a float and used exactly
                    let w = (1.0 / (1.0 + d / side)).clamp(1.0 / 64.0, 1.0);
                    BigRational::from_float(w).unwrap_or_else(|| BigRational::from_integer(1.into()))
                })
                .collect()
        }
    };
    // floors: what each obstacle needs at the start (t0) and the goal (tf) — the
    // bound there (Cantelli's, or with `auto` the best proven one; weighted mode only);
    // the rest of Δ is split by weight
    let point = |v: &[f64], t: f64| -> Option<Vec<BigRational>> {
        let mut x: Vec<BigRational> = v.iter().map(|&c| BigRational::from_float(c)).collect::<Option<_>>()?;
        x.push(BigRational::from_float(t)?);
        Some(x)
    };
    let (Some(a), Some(b)) = (point(&p.start, p.horizon.0), point(&p.goal, p.horizon.1)) else {
        return Err(PlanError::InvalidRequest { field: "start".into(), message: "not finite".into() });
    };
    // strictly above the bound (the endpoint must be strictly inside), by 1 %
    let margin = BigRational::new(101.into(), 100.into());
    let needs: Vec<(BigRational, BigRational)> = if mode == RiskMode::JointWeighted {
        p.scene
            .obstacles
            .iter()
            .map(|o| {
                let bound = |x: &[BigRational]| match bounds {
                    BoundChoice::Cantelli => o.contour.risk_at(x).bound,
                    BoundChoice::Auto => riskplan_certify::piece_bounds::point_bounds_proven(&o.contour, x).best().1,
                };
                (bound(&a) * &margin, bound(&b) * &margin)
            })
            .collect()
    } else {
        vec![(BigRational::from_integer(0.into()), BigRational::from_integer(0.into())); n]
    };
    let floors: Vec<BigRational> = needs.iter().map(|(s, g)| s.clone().max(g.clone())).collect();
    let floor_sum: BigRational = floors.iter().sum();
    if floor_sum >= delta {
        // the endpoints alone need more than Δ: name the obstacle that needs the most
        let worst = floors.iter().enumerate().max_by(|x, y| x.1.cmp(y.1)).map(|(i, _)| i).unwrap_or(0);
        let (which, point, t) = if needs[worst].0 >= needs[worst].1 {
            ("start", p.start.clone(), p.horizon.0)
        } else {
            ("goal", p.goal.clone(), p.horizon.1)
        };
        let obstacle = p.scene.obstacles[worst].id.clone();
        return Err(PlanError::UnsafeEndpoint { which: which.into(), point, t, obstacle });
    }
    let rest = &delta - &floor_sum;
    let total: BigRational = weights.iter().sum();
    weights
        .iter()
        .zip(&floors)
        .map(|(w, f)| {
            RiskLevel::new(f + &rest * w / &total)
                .map_err(|e| PlanError::InvalidOption { option: "risk_mode".into(), message: e.to_string() })
        })
        .collect()
}

/// Distance from a box to the segment `a–b` (sampled along the segment: a weight, not a
/// decision).
fn box_segment_distance(b: &[(f64, f64)], a: &[f64], c: &[f64]) -> f64 {
    (0..=64)
        .map(|k| {
            let s = k as f64 / 64.0;
            b.iter()
                .enumerate()
                .map(|(d, &(lo, hi))| {
                    let x = a[d] + (c[d] - a[d]) * s;
                    let e = if x < lo {
                        lo - x
                    } else if x > hi {
                        x - hi
                    } else {
                        0.0
                    };
                    e * e
                })
                .sum::<f64>()
                .sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}
