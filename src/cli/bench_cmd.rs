//! `riskplan bench`: planners as experiments (after OMPL's Benchmark). The suite
//! `paper` — every planning scene × planner × seed, with the paper's times beside ours
//! and a Monte Carlo audit of each returned plan — prints a Markdown table and writes
//! JSON lines. (The robustness suite is the `robustness` binary of `riskplan-testkit`,
//! not part of this tool.)

use super::util::{load_scene, print_out, time_limit_arg, CliError};
use clap::{Args, ValueEnum};
use riskplan_app::verify::{audit_trajectory, AuditOptions};
use riskplan_app::{PlanRequest, PlannerKind};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

/// Which benchmark suite.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Suite {
    /// The paper's reference planning scenes (scenes/), every planner, several seeds.
    Paper,
}

/// Benchmark the planners on the paper's reference scenes.
///
/// --suite paper (default, the only suite): for each scene of --scenes with a start and goal: rrt-sos
/// (the default), rrt-sos-paper (on static scenes also with its improve step) and the Monte
/// Carlo baseline mc-rrt, and where the scene records the paper's optimisation planners
/// (planner.time_varying_sos, planner.standard_sos) tv-sos, moment and moment-poly, over
/// --seeds seeds; medians are reported next to the paper's
/// run times. Every plan is audited by Monte Carlo: the largest estimated probability of
/// collision with any obstacle at --audit-times times per piece (--audit-samples
/// scenarios), and the count of plans whose Clopper–Pearson lower bound (99%) exceeds Δ.
///
/// The robustness suite (generated scenes judged by an independent oracle) is not part
/// of this tool: `cargo run --release -p riskplan-testkit --bin robustness`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Which suite to run.
    #[arg(long, value_enum, default_value_t = Suite::Paper)]
    suite: Suite,
    /// Directory of scene files (default: the paper's experiments in the repository's scenes/).
    #[arg(long, default_value = "scenes")]
    scenes: PathBuf,
    /// Seeds per planner and scene.
    #[arg(long, default_value_t = 5)]
    seeds: u64,
    /// Only these planners (comma-separated names: rrt-sos, rrt-sos-paper,
    /// mc-rrt, tv-sos, moment, moment-poly) [default: all].
    #[arg(long, value_delimiter = ',', value_parser = super::util::whole_plan_planner_parser())]
    planners: Vec<PlannerKind>,
    /// Time limit per run, seconds [default: 60].
    #[arg(long)]
    time_limit: Option<f64>,
    /// Monte Carlo scenarios per audited point [default: 20000].
    #[arg(long)]
    audit_samples: Option<u64>,
    /// Audited times per piece [default: 50].
    #[arg(long)]
    audit_times: Option<usize>,
    /// JSON lines of every run [default: bench-planners.jsonl].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Which risk bounds may prove safety (auto or cantelli) [default: the scene's
    /// planner.bound, else the default of `plan`].
    #[arg(long)]
    bound: Option<riskplan_math::contour::BoundChoice>,
    /// Risk level Δ of every run, and of the audit (default: each scene's risk).
    #[arg(long)]
    delta: Option<String>,
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(if v.len() % 2 == 1 { v[v.len() / 2] } else { 0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2]) })
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

pub fn run(a: BenchArgs) -> Result<i32, CliError> {
    match a.suite {
        Suite::Paper => run_paper(a),
    }
}

/// The commit the binary was built from (`build.rs`; "unknown" when it was built outside a
/// git checkout), shortened to 12 hex digits: the bench's runs are of this binary,
/// whatever directory it runs in.
fn git_rev() -> String {
    riskplan_app::GIT_COMMIT.chars().take(12).collect()
}

fn run_paper(a: BenchArgs) -> Result<i32, CliError> {
    let time_limit_s = a.time_limit.unwrap_or(60.0);
    let audit_samples = a.audit_samples.unwrap_or(20_000);
    let audit_times = a.audit_times.unwrap_or(50);
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("bench-planners.jsonl"));
    let time_limit = time_limit_arg(time_limit_s)?;
    let delta = a.delta.as_deref().map(super::util::delta_arg).transpose()?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(&a.scenes)
        .map_err(|e| CliError(format!("--scenes {}: {e}", a.scenes.display())))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    let mut log = std::fs::File::create(&out).map_err(|e| CliError(format!("{}: {e}", out.display())))?;
    let host = host();
    let rev = git_rev();
    let mut table = vec![
        format!(
            "Host: {host}; git {rev}; {} seeds; time limit {} s; audit {} scenarios × {} times per piece.",
            a.seeds, time_limit_s, audit_samples, audit_times
        ),
        String::new(),
        "| scene | planner | solved | median time to first plan (ms) | median time (s) | paper (s) | median length | max MC risk | plans over Δ (99%) |"
            .into(),
        "|---|---|---|---|---|---|---|---|---|".into(),
    ];
    for f in files {
        let scene = Arc::new(load_scene(&f)?);
        if scene.start.is_none() {
            continue;
        }
        // one kernel per scene, as the service keeps one per stored scene: the first seed
        // builds the compiled contours and covers (cold), the others reuse them (warm)
        let kernel = riskplan_app::verify::SceneKernel::new(scene.clone());
        let paper = scene.file.expected.as_ref().map(|e| e["run_time_s"].clone()).unwrap_or_default();
        let paper_t = |k: &str| paper[k]["paper"].as_f64().map(|v| format!("{v}")).unwrap_or_else(|| "–".into());
        // every planner, with the runs of the paper's table it makes on this scene
        let mut variants: Vec<(&str, PlannerKind, bool, String)> = vec![];
        for kind in PlannerKind::ALL {
            for run in (kind.spec().paper_runs)(&scene) {
                variants.push((run.label, kind, run.improve, run.paper_key.map_or_else(|| "–".into(), paper_t)));
            }
        }
        variants.retain(|v| a.planners.is_empty() || a.planners.contains(&v.1));
        for (label, planner, improve, paper_time) in variants {
            let (mut times, mut lens, mut worst, mut over, mut solved) = (vec![], vec![], 0.0f64, 0, 0);
            let mut first = vec![];
            for seed in 1..=a.seeds {
                let request = PlanRequest {
                    planner,
                    improve,
                    seed,
                    time_limit,
                    bound: a.bound,
                    delta: delta.clone(),
                    ..PlanRequest::default()
                };
                let bound_label = request.bound_on(&scene).to_string();
                let (_, out) = request.run(&kernel, None).map_err(|e| CliError(e.to_string()))?;
                let mut rec = json!({"scene": scene.name, "planner": label, "seed": seed, "host": host, "git": rev, "time_limit_s": time_limit_s, "bound": bound_label, "delta": delta.as_ref().map_or_else(|| scene.risk_f64(), |d| d.to_f64()), "status": out.status, "certified": out.certified, "stats": out.stats});
                if let Some(t) = &out.trajectory {
                    solved += 1;
                    times.push(out.stats.planning_time_s);
                    first.extend(out.stats.time_to_feasible_s);
                    lens.push(out.stats.path_length.unwrap_or(f64::NAN));
                    let opts = AuditOptions {
                        times_per_piece: audit_times,
                        samples: audit_samples,
                        seed: 7 + seed,
                        ..AuditOptions::default()
                    };
                    let audit_delta = delta.as_ref().map_or_else(|| scene.risk_f64(), |d| d.to_f64());
                    let audit = audit_trajectory(&scene, t, audit_delta, &opts)
                        .map_err(|e| CliError(format!("{}: Monte Carlo audit: {e}", scene.name)))?;
                    let (w, ex) = (audit.max_estimate, audit.exceeds());
                    worst = worst.max(w);
                    over += ex as usize;
                    rec["audit"] = json!({"max_risk_estimate": w, "exceeds_delta_99": ex, "samples": audit_samples});
                }
                writeln!(log, "{rec}").map_err(|e| CliError(e.to_string()))?;
            }
            let fmt = |v: Option<f64>| v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "–".into());
            table.push(format!(
                "| {} | {label} | {solved}/{} | {} | {} | {paper_time} | {} | {worst:.4} | {over}/{solved} |",
                scene.name,
                a.seeds,
                median(first).map(|x| format!("{:.3}", x * 1e3)).unwrap_or_else(|| "–".into()),
                fmt(median(times)),
                fmt(median(lens))
            ));
            eprintln!("{}", table.last().cloned().unwrap_or_default());
        }
    }
    print_out(&table.join("\n"))?;
    Ok(0)
}
