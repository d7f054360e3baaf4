//! The robustness bench: see `--help`.
//!
//! ```sh
//! OPENBLAS_NUM_THREADS=1 cargo run --release -p riskplan-testkit --bin robustness -- \
//!     --count 120 --suite-seed 1 --out bench-robustness.jsonl
//! # every scene at one Δ, with one bound (docs/benchmarks.md, "Risk levels and bounds")
//! OPENBLAS_NUM_THREADS=1 cargo run --release -p riskplan-testkit --bin robustness -- \
//!     --count 120 --suite-seed 1 --delta 0.01 --bound cantelli --out /tmp/rob-0.01-cantelli.jsonl
//! # trajectory mode: Δ bounds the whole path; each plan's whole-path bound audited
//! OPENBLAS_NUM_THREADS=1 cargo run --release -p riskplan-testkit --bin robustness -- \
//!     --count 120 --suite-seed 1 --delta 0.1 --risk-mode trajectory --out /tmp/rob-traj-0.1.jsonl
//! ```
//!
//! Exit status: 0 success, 2 bad usage or an I/O error (one line on stderr).

use clap::Parser;
use riskplan_app::RiskMode;
use riskplan_math::contour::{BoundChoice, RiskLevel};
use riskplan_oracle::generate;
use riskplan_oracle::oracle::OracleOptions;
use riskplan_testkit::runner::{
    delta_bound_row, run_scene, summary_table, whole_path_row, RunOptions, DELTA_BOUND_HEADER, WHOLE_PATH_HEADER,
    WHOLE_PATH_MIN_TIMES,
};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;
use thiserror::Error;

/// The robustness suite of riskplan: generated scenes judged by an independent oracle,
/// planned with the default options, audited and certified.
///
/// --count scenes generated from --suite-seed (2-D and 3-D, widths 1–100 anywhere
/// within ±1000, static and moving obstacles, disks, ellipses and nonconvex quartics,
/// every distribution family, pedestrians with Gaussian position and velocity errors,
/// about 18 % intentionally infeasible). Each is judged feasible / infeasible / ambiguous
/// by an oracle independent of riskplan's moment and certification code
/// (riskplan-oracle: Cantelli's contour, a clearance grid search at Δ/2, a relaxed
/// connectivity check at 1.5·Δ), then planned by rrt-sos with default options (the
/// scene's speed limit passed, --bound if given), its plan audited by Monte Carlo (the
/// generator's true distributions for `moments` parameters) and its pieces certified by
/// the exact and the SOS method. With --delta, every scene is run at that Δ (its `risk`,
/// the request, the oracle, the audits). Prints a summary by scene class and the row of
/// the Δ × bound table; one JSON line per scene (with the scene, its Δ and bound) goes to
/// --out. The oracle's time over the suite is in the header and, with its slowest scene,
/// on stderr at the end.
///
/// With --risk-mode trajectory (or --whole-path-all-modes), each plan's certified
/// whole-path bound (stats.whole_path_risk) is audited by Monte Carlo with one draw of
/// every parameter per scenario (--whole-path-samples scenarios, max(--audit-times, 100)
/// times per piece; the crate's audit_whole_path, or the runner's own for scenes with a
/// `moments` parameter), and a second table gives plans, bounds within Δ, audits over Δ
/// (99 % upper end), bounds below the audit (99 % lower end) and the conservatism.
#[derive(Parser, Debug)]
#[command(name = "robustness", about, long_about, max_term_width = 100)]
struct Args {
    /// Generated scenes.
    #[arg(long, default_value_t = 120)]
    count: usize,
    /// Seed of the generated scenes; scene i of a seed is always the same.
    #[arg(long, default_value_t = 1)]
    suite_seed: u64,
    /// Time limit per scene, seconds.
    #[arg(long, default_value_t = 10.0)]
    time_limit: f64,
    /// Monte Carlo scenarios per audited point.
    #[arg(long, default_value_t = 4000)]
    audit_samples: u64,
    /// Audited times per piece.
    #[arg(long, default_value_t = 20)]
    audit_times: usize,
    /// Δ for every scene, in (0, 1) [default: each scene's generated Δ].
    #[arg(long)]
    delta: Option<f64>,
    /// Which risk bounds the planner may use: auto or cantelli [default: riskplan's
    /// default]. The oracle judges with Cantelli's bound either way.
    #[arg(long)]
    bound: Option<BoundChoice>,
    /// What Δ bounds: per-obstacle, joint, joint-weighted or trajectory (the whole
    /// path; its plans get a whole-path audit).
    #[arg(long, default_value = "per-obstacle", value_parser = parse_risk_mode)]
    risk_mode: RiskMode,
    /// Monte Carlo scenarios of the whole-path audit (0: none).
    #[arg(long, default_value_t = 100_000)]
    whole_path_samples: u64,
    /// Audit the whole path of the plans in every risk mode, not only in trajectory mode.
    #[arg(long)]
    whole_path_all_modes: bool,
    /// JSON lines of every scene.
    #[arg(long, default_value = "bench-robustness.jsonl")]
    out: PathBuf,
}

/// Why the bench stopped.
#[derive(Debug, Error)]
enum BenchError {
    /// A time limit that is not a positive, finite number of seconds.
    #[error("--time-limit: {0}")]
    TimeLimit(String),
    /// A Δ outside (0, 1).
    #[error("--delta: {0}")]
    Delta(String),
    /// The JSON lines file cannot be created.
    #[error("{}: {source}", .path.display())]
    Create { path: PathBuf, source: std::io::Error },
    /// A line cannot be written to it.
    #[error("{0}")]
    Write(std::io::Error),
    /// A record does not serialise.
    #[error("{0}")]
    Json(#[from] serde_json::Error),
    /// The table cannot be printed.
    #[error("cannot write to stdout: {0}")]
    Stdout(std::io::Error),
}

fn main() {
    let args = match Args::try_parse() {
        Ok(a) => a,
        Err(e) => {
            let _ = e.print();
            std::process::exit(if e.use_stderr() { 2 } else { 0 });
        }
    };
    if let Err(e) = run(args) {
        eprintln!("error: {e}");
        std::process::exit(2);
    }
}

fn parse_risk_mode(s: &str) -> Result<RiskMode, String> {
    s.parse::<RiskMode>().map_err(|e| e.to_string())
}

fn time_limit(seconds: f64) -> Result<Duration, BenchError> {
    riskplan_app::time_limit(seconds).map_err(|e| match e {
        riskplan_plan::PlanError::InvalidRequest { message, .. } => BenchError::TimeLimit(message),
        other => BenchError::TimeLimit(other.to_string()),
    })
}

fn host() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|c| {
            c.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_default();
    format!("{} cores, {cpu}", std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0))
}

fn git_rev() -> String {
    std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default()
}

/// Writes `text` and a newline to stdout; a closed pipe (`| head`) is not an error.
fn print_out(text: &str) -> Result<(), BenchError> {
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|_| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(BenchError::Stdout(e)),
        _ => Ok(()),
    }
}

fn run(a: Args) -> Result<(), BenchError> {
    let seconds = a.time_limit;
    if let Some(d) = a.delta {
        RiskLevel::from_f64(d).map_err(|e| BenchError::Delta(e.to_string()))?;
    }
    let opts = RunOptions {
        time_limit: time_limit(seconds)?,
        audit_samples: a.audit_samples,
        audit_times: a.audit_times,
        audit_seed: 7,
        oracle: OracleOptions::default(),
        delta: a.delta,
        bound: a.bound,
        risk_mode: a.risk_mode,
        whole_path_samples: a.whole_path_samples,
        whole_path_all_modes: a.whole_path_all_modes,
    };
    let t_run = std::time::Instant::now();
    let out = a.out;
    let mut log = std::fs::File::create(&out).map_err(|source| BenchError::Create { path: out.clone(), source })?;
    let (host, rev) = (host(), git_rev());
    let t_gen = std::time::Instant::now();
    let scenes: Vec<_> = (0..a.count).map(|i| generate(a.suite_seed, i)).collect();
    let gen_s = t_gen.elapsed().as_secs_f64();
    let mut records = Vec::with_capacity(scenes.len());
    for g in &scenes {
        let rec = run_scene(g, &opts);
        let plan = rec.plan.as_ref();
        eprintln!(
            "[{}/{}] {} {}-D {} {}{}: oracle {} ({:.2} s); plan {} ({:.2} s){}{}",
            g.index + 1,
            a.count,
            g.name,
            g.dim,
            if rec.moving { "moving" } else { "static" },
            rec.shape_mix,
            if rec.pedestrians > 0 { format!(" ({} pedestrians)", rec.pedestrians) } else { String::new() },
            rec.label(),
            rec.oracle.as_ref().map(|o| o.time_s).unwrap_or(0.0),
            if plan.is_some_and(|p| p.planned) { "found" } else { "none" },
            plan.map(|p| p.time_s).unwrap_or(0.0),
            rec.audit.as_ref().filter(|a| a.over_delta).map(|_| " OVER Δ").unwrap_or(""),
            rec.whole_path
                .as_ref()
                .map(|w| match &w.error {
                    Some(e) => format!("; whole path: no audit ({e})"),
                    None => format!(
                        "; whole path: bound {} audit {:.2e} [{:.2e}, {:.2e}] ({}, {:.1} s){}{}",
                        w.bound.map_or("none".to_string(), |b| format!("{b:.3e}")),
                        w.estimate,
                        w.lower,
                        w.upper,
                        w.method,
                        w.time_s,
                        if w.over_delta { " AUDIT OVER Δ" } else { "" },
                        if w.bound_below_audit { " BOUND BELOW AUDIT" } else { "" },
                    ),
                })
                .unwrap_or_default(),
        );
        let mut v = serde_json::to_value(&rec)?;
        v["host"] = json!(host);
        v["git"] = json!(rev);
        v["time_limit_s"] = json!(seconds);
        writeln!(log, "{v}").map_err(BenchError::Write)?;
        records.push(rec);
    }
    let oracle_s: f64 = records.iter().filter_map(|r| r.oracle.as_ref()).map(|o| o.time_s).sum();
    let header = format!(
        "Host: {host}; git {rev}; robustness suite seed {}, {} scenes; Δ {}; bound {}; risk mode {}; time limit {seconds} s; audit {} scenarios × {} times per piece; generation {gen_s:.2} s, oracle {oracle_s:.2} s in total; run {:.1} s.\n",
        a.suite_seed,
        a.count,
        a.delta.map_or_else(|| "generated".to_string(), |d| d.to_string()),
        a.bound.map_or("riskplan's default", |b| b.as_str()),
        a.risk_mode.as_str(),
        opts.audit_samples,
        opts.audit_times,
        t_run.elapsed().as_secs_f64(),
    );
    print_out(&(header + &summary_table(&records)))?;
    print_out(&format!("\n{DELTA_BOUND_HEADER}\n{}", delta_bound_row(&records)))?;
    if let Some(row) = whole_path_row(&records) {
        print_out(&format!(
            "\nWhole-path audit: {} scenarios per plan, one draw of every parameter per scenario, {} times per piece; Clopper–Pearson ends one-sided 99 %; over Δ: upper end > Δ; below audit: certified bound < lower end.\n{WHOLE_PATH_HEADER}\n{row}",
            opts.whole_path_samples,
            opts.audit_times.max(WHOLE_PATH_MIN_TIMES),
        ))?;
    }
    // the oracle's time over the suite (what the oracle's unit test once bounded by a
    // wall-clock assertion), with its slowest scene
    let slowest = records
        .iter()
        .filter_map(|r| r.oracle.as_ref().map(|o| (o.time_s, r.name.as_str())))
        .max_by(|x, y| x.0.total_cmp(&y.0));
    eprintln!(
        "oracle over {} scenes: {oracle_s:.2} s in total, generation {gen_s:.2} s{}",
        records.len(),
        slowest.map(|(s, n)| format!(" (slowest scene {n}: {s:.2} s)")).unwrap_or_default()
    );
    Ok(())
}
