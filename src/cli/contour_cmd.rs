//! `riskplan contour`: figures of the Δ-risk contours.

use super::util::{delta_arg, exact_arg, load_scene, CliError};
use crate::viz::{self, ContourOptions};
use clap::Args;
use riskplan_math::contour::RiskLevel;
use riskplan_math::poly::rational_to_f64;
use std::path::PathBuf;

/// Draw the Δ-risk contours of a scene (like the paper's Figs. 1–3, 6–8).
///
/// Draws, for each Δ, the boundary of the Cantelli inner approximation of the Δ-risk
/// contour (eqs. 10/12: outside the curve the risk is at most Δ), the obstacle at the
/// mean of its parameters (grey), and with --mc the Monte Carlo estimate of the true
/// Δ-contour (green shading: where the estimated risk exceeds Δ). Moving obstacles
/// are drawn at each --time. A 3-D scene needs --slice x3=VALUE.
#[derive(Args, Debug)]
pub struct ContourArgs {
    /// Scene file (format v1).
    #[arg(long)]
    scene: PathBuf,
    /// Risk levels Δ (default: the scene's risk_levels, else its risk).
    #[arg(long, num_args = 1..)]
    delta: Vec<String>,
    /// Times to draw (default: the start of the horizon).
    #[arg(long, num_args = 1.., allow_negative_numbers = true)]
    time: Vec<String>,
    /// Monte Carlo samples per grid point for the true contour (0 = none).
    #[arg(long, default_value_t = 0)]
    mc: u64,
    /// Seed of the Monte Carlo sampler.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Fix a coordinate of a 3-D (or higher) scene, e.g. x3=0.
    #[arg(long, value_name = "xK=VALUE")]
    slice: Vec<String>,
    /// Grid points per axis for the Cantelli contours.
    #[arg(long, default_value_t = 300)]
    grid: usize,
    /// Grid points per axis for the Monte Carlo contour.
    #[arg(long, default_value_t = 90)]
    mc_grid: usize,
    /// Plot window in the plotted axes: X0 X1 Y0 Y1 (default: the workspace).
    #[arg(long, num_args = 4, allow_negative_numbers = true, value_names = ["X0", "X1", "Y0", "Y1"])]
    window: Vec<f64>,
    /// Output file, .svg or .png.
    #[arg(long)]
    out: PathBuf,
    /// Which bounds' Δ-contours to draw: cantelli (the paper's figures), auto (the best
    /// bound at each point, what `bound: auto` certifies, beside Cantelli's) or each (every
    /// bound — Cantelli, zero risk from the support, moment bounds of orders 4, 6, 8 — and
    /// the best, one colour each; use one Δ per figure).
    #[arg(long, default_value = "cantelli", value_parser = ["cantelli", "auto", "each"])]
    bound: String,
}

fn parse_slice(s: &str) -> Result<(usize, f64), CliError> {
    let bad = || CliError(format!("--slice: expected xK=VALUE (e.g. x3=0), got '{s}'"));
    let (name, v) = s.split_once('=').ok_or_else(bad)?;
    let k: usize = name.trim().strip_prefix('x').and_then(|d| d.parse().ok()).filter(|&k| k >= 1).ok_or_else(bad)?;
    let v = rational_to_f64(&exact_arg("--slice", v.trim())?);
    Ok((k - 1, v))
}

pub fn run(a: ContourArgs) -> Result<i32, CliError> {
    super::plan_cmd::writable("--out", &a.out)?;
    let scene = load_scene(&a.scene)?;
    let deltas: Vec<f64> = if a.delta.is_empty() {
        scene.risk_levels.iter().map(RiskLevel::to_f64).collect()
    } else {
        a.delta.iter().map(|d| delta_arg(d).map(|q| q.to_f64())).collect::<Result<_, _>>()?
    };
    let times: Vec<f64> = if a.time.is_empty() {
        vec![scene.horizon.0]
    } else {
        a.time.iter().map(|t| exact_arg("--time", t).map(|q| rational_to_f64(&q))).collect::<Result<_, _>>()?
    };
    for &t in &times {
        super::util::time_in_horizon("--time", &scene, t)?;
    }
    if a.grid < 8 || a.grid > 4000 || a.mc_grid < 8 || a.mc_grid > 1000 {
        return Err(CliError("--grid must be in 8..=4000 and --mc-grid in 8..=1000".into()));
    }
    let slices = a.slice.iter().map(|s| parse_slice(s)).collect::<Result<Vec<_>, _>>()?;
    let opts = ContourOptions {
        deltas,
        times,
        slices,
        slices_at: vec![],
        mc: (a.mc > 0).then_some((a.mc, a.seed)),
        grid: a.grid,
        mc_grid: a.mc_grid,
        title: None,
        window: match a.window[..] {
            [x0, x1, y0, y1] if x0 < x1 && y0 < y1 => Some((x0, x1, y0, y1)),
            [] => None,
            _ => return Err(CliError("--window: expected X0 X1 Y0 Y1 with X0 < X1 and Y0 < Y1".into())),
        },
        curves: {
            use riskplan_math::contour::BoundKind;
            use viz::BoundCurve;
            match a.bound.as_str() {
                "auto" => vec![BoundCurve::Kind(BoundKind::Cantelli), BoundCurve::Best],
                "each" => vec![
                    BoundCurve::Kind(BoundKind::Cantelli),
                    BoundCurve::Kind(BoundKind::Moment(4)),
                    BoundCurve::Kind(BoundKind::Moment(6)),
                    BoundCurve::Kind(BoundKind::Moment(8)),
                    BoundCurve::Kind(BoundKind::Support),
                    BoundCurve::Best,
                ],
                _ => vec![],
            }
        },
    };
    viz::draw(&scene, &opts, &[], &a.out).map_err(|e| CliError(e.to_string()))?;
    eprintln!("wrote {}", a.out.display());
    Ok(0)
}
