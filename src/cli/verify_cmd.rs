//! `riskplan verify`: certify a trajectory against a scene.

use super::util::{delta_arg, load_scene, method_parser, write_json, CliError};
use clap::Args;
use riskplan_app::verify::{Detail, Method, VerifyOptions};
use riskplan_scene::Trajectory;
use std::path::PathBuf;

/// Certify a trajectory against a scene, continuously in time (eq. 15).
///
/// For every piece and obstacle, both constraints of the Δ-risk contour
/// (−E[P] > 0 and E[P]² − (1−Δ)E[P²] > 0) are composed with the piece on its own time
/// interval and proven positive — by the exact checker (Bernstein subdivision in
/// outward-rounded interval arithmetic with an exact rational fallback), by an SOS
/// certificate (Clarabel, re-checked rigorously), or by both. Unsafe verdicts come
/// with a witness time; anything not proven is "undecided" and never safe. The
/// trajectory file is format v1 (or the output of `riskplan plan`).
///
/// Exit status: 0 every piece certified safe, 1 some piece not, 2 bad input.
// clap prints the doc comment as written: E[P] is math here, not an intra-doc link
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Args, Debug)]
pub struct VerifyArgs {
    /// Scene file (format v1).
    #[arg(long)]
    scene: PathBuf,
    /// Trajectory file (format v1, or `riskplan plan` output).
    #[arg(long)]
    trajectory: PathBuf,
    /// Decision method: exact (Bernstein), sos (eq. 15 on Clarabel) or both.
    #[arg(long, default_value = "exact", value_parser = method_parser())]
    method: Method,
    /// Risk level Δ (default: the scene's risk).
    #[arg(long)]
    delta: Option<String>,
    /// Which risk bounds may prove a piece: auto (Cantelli, then zero risk from bounded support and shifted moment bounds of orders 4–8 on sub-intervals; the report names the bound of each part) or cantelli (the paper's).
    #[arg(long, default_value = "auto")]
    bound: riskplan_math::contour::BoundChoice,
    /// Print the report on one line instead of pretty-printed.
    #[arg(long)]
    compact: bool,
    /// Report only the first piece not proven safe (with the counts `checked`,
    /// `not_safe` and `first_not_safe` that every report carries); the other pieces are
    /// decided and counted, with no report built — the fast way to check long
    /// trajectories.
    #[arg(long)]
    summary: bool,
    /// Threads for trajectories of at least 4096 pieces: contiguous runs of pieces are
    /// verified at once and the report is the same as with one thread (default: the
    /// machine's cores; at most 64).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=riskplan_app::verify::MAX_VERIFY_THREADS as i64))]
    threads: Option<u16>,
    /// Also bound the probability that the trajectory meets any obstacle at any time
    /// (ω drawn once; docs/design.md §5.14), beyond the per-instant risk of eq. (13):
    /// `whole_path_risk` in the report, per obstacle and piece (at most 2000 pieces; exact
    /// arithmetic, about a millisecond per piece and obstacle).
    #[arg(long)]
    whole_path: bool,
}

pub fn run(a: VerifyArgs) -> Result<i32, CliError> {
    let scene = load_scene(&a.scene)?;
    let text = std::fs::read_to_string(&a.trajectory)
        .map_err(|e| CliError(format!("{}: cannot read: {e}", a.trajectory.display())))?;
    let file = riskplan_scene::TrajectoryFile::from_json(&text)
        .map_err(|e| CliError(format!("{}: {e}", a.trajectory.display())))?;
    if let Some(other) = file.scene.as_deref().filter(|n| *n != scene.name) {
        eprintln!(
            "warning: {} was planned on scene '{other}', and is verified here against scene '{}'",
            a.trajectory.display(),
            scene.name
        );
    }
    let traj = Trajectory::new(file.pieces);
    let diag = riskplan_plan::dist(&scene.workspace.lower, &scene.workspace.upper);
    traj.validate_up_to(scene.dim, scene.horizon, diag, riskplan_app::verify::MAX_VERIFY_PIECES)
        .map_err(|e| CliError(format!("{}: {e}", a.trajectory.display())))?;
    let delta = match &a.delta {
        Some(d) => delta_arg(d)?,
        None => scene.risk.clone(),
    };
    let kernel = riskplan_app::verify::SceneKernel::new(std::sync::Arc::new(scene));
    let detail = if a.summary { Detail::FirstNotSafe } else { Detail::Every };
    let threads = a.threads.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), usize::from);
    if a.whole_path && traj.pieces.len() > riskplan_app::verify::MAX_WHOLE_PATH_PIECES {
        return Err(CliError(format!(
            "{}: --whole-path takes at most {} pieces, the trajectory has {}",
            a.trajectory.display(),
            riskplan_app::verify::MAX_WHOLE_PATH_PIECES,
            traj.pieces.len()
        )));
    }
    let opts = VerifyOptions {
        method: a.method,
        settings: Default::default(),
        bounds: a.bound,
        detail,
        threads,
        whole_path: a.whole_path,
    };
    let report = riskplan_app::verify::verify_with(&kernel, &traj.pieces, &delta, &opts, &|| false)
        .map_err(|_| CliError("verification interrupted".into()))?
        .report;
    write_json(&report, !a.compact)?;
    Ok(if report.safe { 0 } else { 1 })
}
