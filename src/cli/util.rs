//! Helpers shared by subcommands: loading scenes, parsing exact numbers.

use riskplan_app::verify::Method;
use riskplan_app::PlannerKind;
use riskplan_math::contour::RiskLevel;
use riskplan_scene::{parse_num_text, Scene};
use std::path::Path;

/// A user-facing error: one line, printed as `error: ...`, exit status 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct CliError(pub String);

/// Reads and validates a scene file; errors name the file, the field and the problem.
pub fn load_scene(path: &Path) -> Result<Scene, CliError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        let hint = if e.kind() == std::io::ErrorKind::NotFound { missing_scene_hint(path) } else { String::new() };
        CliError(format!("{}: cannot read: {e}{hint}", path.display()))
    })?;
    Scene::from_json(&text).map_err(|e| CliError(format!("{}: {e}", path.display())))
}

/// A warning (on stderr) when `x` lies outside the scene's workspace: what is asked there is
/// answered all the same (the bounds are polynomials), but no plan goes there.
pub fn warn_outside_workspace(flag: &str, scene: &Scene, x: &[f64]) {
    if !scene.workspace.contains(x) {
        eprintln!(
            "warning: {flag} {} is outside the workspace of scene '{}' ({}): answered all the same, but no plan goes there",
            fmt_point(x),
            scene.name,
            workspace_text(scene)
        );
    }
}

/// The workspace as `[l1, u1] × [l2, u2] …`.
pub fn workspace_text(scene: &Scene) -> String {
    let w = &scene.workspace;
    w.lower.iter().zip(&w.upper).map(|(l, u)| format!("[{l}, {u}]")).collect::<Vec<_>>().join(" × ")
}

/// `(x1, x2, …)`.
pub fn fmt_point(x: &[f64]) -> String {
    format!("({})", x.iter().map(|c| c.to_string()).collect::<Vec<_>>().join(", "))
}

/// Refuses a time outside the scene's horizon, where its obstacles are not described.
pub fn time_in_horizon(flag: &str, scene: &Scene, t: f64) -> Result<(), CliError> {
    let (h0, h1) = scene.horizon;
    if (h0..=h1).contains(&t) {
        return Ok(());
    }
    Err(CliError(format!(
        "{flag} {t} is outside the horizon [{h0}, {h1}] of scene '{}': give a time in it",
        scene.name
    )))
}

/// The hint for a scene file that does not exist: the closest scene file (by its name
/// without `.json`) in its directory or in `scenes/` — `--scene Illustrative-3` finds
/// `scenes/illustrative-3.json` — else what `--scene` takes.
fn missing_scene_hint(path: &Path) -> String {
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
    for d in [dir, Some(Path::new("scenes"))].into_iter().flatten() {
        let Ok(entries) = std::fs::read_dir(d) else { continue };
        let files: Vec<std::path::PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "json"))
            .collect();
        let stems: Vec<&str> = files.iter().filter_map(|p| p.file_stem().and_then(|s| s.to_str())).collect();
        if let Some(c) = riskplan_app::names::closest(stem, stems.iter().copied()) {
            return format!(": did you mean {}?", d.join(format!("{c}.json")).display());
        }
    }
    ": --scene takes a scene file (e.g. scenes/illustrative-3.json; `riskplan client` commands take a scene's name)"
        .into()
}

/// Parses a number given on the command line exactly (`0.5`, `1e-3`, `37/300`).
pub fn exact_arg(flag: &str, s: &str) -> Result<num_rational::BigRational, CliError> {
    parse_num_text(s).ok_or_else(|| CliError(format!("{flag}: '{s}' is not a number (decimal or p/q)")))
}

/// Parses a risk level: a number in (0, 1), exactly.
pub fn delta_arg(s: &str) -> Result<RiskLevel, CliError> {
    RiskLevel::parse(s).map_err(|e| CliError(format!("--delta: {e}")))
}

/// `--time-limit`: positive, finite seconds.
pub fn time_limit_arg(seconds: f64) -> Result<std::time::Duration, CliError> {
    riskplan_app::time_limit(seconds).map_err(|e| match e {
        riskplan_plan::PlanError::InvalidRequest { message, .. } => CliError(format!("--time-limit: {message}")),
        other => CliError(other.to_string()),
    })
}

/// `--planner`: the names of [`PlannerKind`], listed in `--help`.
pub fn planner_parser() -> impl clap::builder::TypedValueParser<Value = PlannerKind> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(PlannerKind::ALL.map(|k| k.as_str())).try_map(|s| s.parse::<PlannerKind>())
}

/// `bench --planners`: the planners of whole start-to-goal plans (every [`PlannerKind`]
/// but `receding`, which plans one window from a robot's state).
pub fn whole_plan_planner_parser() -> impl clap::builder::TypedValueParser<Value = PlannerKind> {
    use clap::builder::TypedValueParser;
    let names = PlannerKind::ALL.into_iter().filter(|k| *k != PlannerKind::Receding).map(|k| k.as_str());
    clap::builder::PossibleValuesParser::new(names).try_map(|s| s.parse::<PlannerKind>())
}

/// `--method` / `--certifier`: exact, sos or both.
pub fn method_parser() -> impl clap::builder::TypedValueParser<Value = Method> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(["exact", "sos", "both"]).try_map(|s| s.parse::<Method>())
}

/// Writes `text` and a newline to stdout; a closed pipe (`| head`) is not an error.
pub fn print_out(text: &str) -> Result<(), CliError> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|_| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(CliError(format!("cannot write to stdout: {e}"))),
        _ => Ok(()),
    }
}

/// Writes `value` as JSON (pretty or on one line) and a newline to stdout, serialized
/// straight into a buffered stdout (large reports are not built as one string first).
pub fn write_json(value: &impl serde::Serialize, pretty: bool) -> Result<(), CliError> {
    use std::io::Write;
    let mut out = std::io::BufWriter::with_capacity(1 << 16, std::io::stdout().lock());
    let written =
        if pretty { serde_json::to_writer_pretty(&mut out, value) } else { serde_json::to_writer(&mut out, value) }
            .map_err(std::io::Error::from)
            .and_then(|_| writeln!(out))
            .and_then(|_| out.flush());
    match written {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(CliError(format!("cannot write to stdout: {e}"))),
        _ => Ok(()),
    }
}

/// The tokio runtime of a command that talks to the service: one worker thread (a
/// client waits on replies; it does not compute).
#[cfg(feature = "service")]
pub fn client_runtime() -> Result<tokio::runtime::Runtime, CliError> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| CliError(e.to_string()))
}
