//! `riskplan risk`: the risk bound at a point, per obstacle, optionally with Monte Carlo.

use super::util::{delta_arg, exact_arg, load_scene, print_out, CliError};
use clap::Args;
use num_rational::BigRational;
use riskplan_math::mc::DEFAULT_CONFIDENCE;
use riskplan_math::poly::rational_to_f64;
use serde_json::json;
use std::path::PathBuf;

/// Risk at a point: E[P], E[P²] and every risk bound per obstacle, with the best (JSON on stdout).
///
/// Cantelli's bound (E[P²] − E[P]²)/E[P²] where E[P] ≤ 0, and 1 where E[P] > 0 (Theorem 1),
/// exactly (rational arithmetic, printed as a float and an exact fraction); zero risk where
/// P < 0 for every parameter in a bounded support (proven); the shifted moment bounds of
/// orders 4, 6 and 8 at their best shift (proven upper ends). `bound` is the smallest allowed
/// by --bound (docs/design.md §3.7–§3.10). With --mc, the Monte Carlo estimate of the true probability
/// Prob(P(x, ω, t) ≥ 0) is added with its exact Clopper–Pearson interval.
// clap prints the doc comment as written: E[P] is math here, not an intra-doc link
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Args, Debug)]
pub struct RiskArgs {
    /// Scene file (format v1).
    #[arg(long)]
    scene: PathBuf,
    /// The point: one coordinate per dimension (decimals or fractions like 1/3).
    #[arg(long, num_args = 1.., required = true, allow_negative_numbers = true, value_name = "X")]
    point: Vec<String>,
    /// Time (for moving obstacles); default: the start of the scene's horizon.
    #[arg(long, allow_negative_numbers = true)]
    time: Option<String>,
    /// Monte Carlo samples for an estimate of the true risk (0 = none).
    #[arg(long, default_value_t = 0)]
    mc: u64,
    /// Seed of the Monte Carlo sampler.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Two-sided confidence level of the Monte Carlo interval.
    #[arg(long, default_value_t = DEFAULT_CONFIDENCE)]
    confidence: f64,
    /// A risk level Δ: adds `"within_delta": bound ≤ Δ` per obstacle.
    #[arg(long)]
    delta: Option<String>,
    /// Which bound `bound` reports: auto (the smallest proven one: Cantelli, zero risk from bounded support, shifted moment bounds of orders 4–8) or cantelli. Every bound is listed under `bounds` either way.
    #[arg(long, default_value = "auto")]
    bound: riskplan_math::contour::BoundChoice,
}

pub fn run(a: RiskArgs) -> Result<i32, CliError> {
    let scene = load_scene(&a.scene)?;
    if a.point.len() != scene.dim {
        return Err(CliError(format!(
            "--point: the scene is {}-D, so give {} coordinates, got {}",
            scene.dim,
            scene.dim,
            a.point.len()
        )));
    }
    if !(a.confidence > 0.0 && a.confidence < 1.0) {
        return Err(CliError(format!("--confidence must be in (0, 1), got {}", a.confidence)));
    }
    let mut xt: Vec<BigRational> = a.point.iter().map(|s| exact_arg("--point", s)).collect::<Result<_, _>>()?;
    let t = match &a.time {
        Some(s) => exact_arg("--time", s)?,
        None => riskplan_math::poly::f64_shortest_decimal(scene.horizon.0).unwrap_or_default(),
    };
    xt.push(t.clone());
    let delta = a.delta.as_deref().map(delta_arg).transpose()?;
    let xt_f: Vec<f64> = xt.iter().map(rational_to_f64).collect();
    super::util::warn_outside_workspace("--point", &scene, &xt_f[..scene.dim]);
    let (h0, h1) = scene.horizon;
    if !(h0..=h1).contains(&xt_f[scene.dim]) {
        eprintln!(
            "warning: --time {} is outside the horizon [{h0}, {h1}] of scene '{}': the obstacles' polynomials are \
             evaluated there all the same, but the scene does not describe them there",
            xt_f[scene.dim], scene.name
        );
    }
    let mc = if a.mc > 0 {
        let model = scene.mc_model().map_err(|e| CliError(format!("--mc: {}: {e}", a.scene.display())))?;
        Some(model.point_risk(&xt_f, a.mc, a.seed, a.confidence))
    } else {
        None
    };
    let mut max_bound = 0.0f64;
    let mut obstacles = Vec::new();
    for (i, o) in scene.obstacles.iter().enumerate() {
        let r = o.contour.risk_at(&xt);
        let all = riskplan_certify::piece_bounds::point_bounds_proven(&o.contour, &xt);
        let (kind, best) = match a.bound {
            riskplan_math::contour::BoundChoice::Auto => all.best(),
            riskplan_math::contour::BoundChoice::Cantelli => {
                (riskplan_math::contour::BoundKind::Cantelli, r.bound.clone())
            }
        };
        let bound = rational_to_f64(&best);
        max_bound = max_bound.max(bound);
        let mut each = serde_json::Map::new();
        each.insert(
            "cantelli".into(),
            json!({"value": rational_to_f64(&all.cantelli), "exact": all.cantelli.to_string()}),
        );
        if let Some(z) = all.support_zero {
            each.insert("support".into(), json!({"value": if z { 0.0 } else { 1.0 }, "proven_zero": z}));
        }
        for m in &all.moments {
            each.insert(
                riskplan_math::contour::BoundKind::Moment(m.order).as_str().into(),
                json!({"value": rational_to_f64(&m.value), "exact": m.value.to_string(), "shift": m.shift}),
            );
        }
        let mut entry = json!({
            "id": o.id,
            "mean": rational_to_f64(&r.mean),
            "second_moment": rational_to_f64(&r.second_moment),
            "bound": bound,
            "bound_exact": best.to_string(),
            "best": kind.as_str(),
            "bounds": each,
        });
        if let Some(l) = &all.moment_limit {
            entry["moment_limit"] = json!(l.to_string());
        }
        if let Some(d) = &delta {
            entry["within_delta"] = json!(&best <= d.rational());
        }
        if let Some(mc) = &mc {
            let e = mc[i];
            entry["mc"] = json!({"estimate": e.estimate, "lower": e.lower, "upper": e.upper, "samples": e.samples, "confidence": a.confidence});
        }
        obstacles.push(entry);
    }
    let out = json!({
        "scene": scene.name,
        "bound": a.bound.as_str(),
        "point": xt_f[..scene.dim],
        "time": rational_to_f64(&t),
        "obstacles": obstacles,
        "max_bound": max_bound,
    });
    print_out(&serde_json::to_string_pretty(&out).unwrap_or_default())?;
    Ok(0)
}
