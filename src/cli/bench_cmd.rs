//! `riskplan bench`: planners as experiments (after OMPL's Benchmark): every planning
//! scene × planner × seed, with the paper's times beside ours and a Monte Carlo audit
//! of each returned plan. Prints a Markdown table and writes JSON lines.

use super::util::{load_scene, print_out, time_limit_arg, CliError};
use clap::Args;
use riskplan::app::{PlanRequest, PlannerKind};
use riskplan::verify::{audit_trajectory, AuditOptions};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

/// Benchmark the planners on the reference planning scenes.
///
/// For each scene with a start and goal: rrt-sos (time to a feasible plan; on static
/// scenes also with the improve step) and the Monte Carlo baseline mc-rrt, over
/// --seeds seeds; medians are reported next to the paper's run times. Every plan is
/// audited by Monte Carlo: the largest estimated probability of collision with any
/// obstacle at --audit-times times per piece (--audit-samples scenarios), and the
/// count of plans whose Clopper–Pearson lower bound (99%) exceeds Δ.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Directory of scene files (default: the paper's experiments in the repository's scenes/).
    #[arg(long, default_value = "scenes")]
    scenes: PathBuf,
    /// Seeds per planner and scene.
    #[arg(long, default_value_t = 5)]
    seeds: u64,
    /// Time limit per run, seconds.
    #[arg(long, default_value_t = 60.0)]
    time_limit: f64,
    /// Monte Carlo scenarios per audited point.
    #[arg(long, default_value_t = 20_000)]
    audit_samples: u64,
    /// Audited times per piece.
    #[arg(long, default_value_t = 50)]
    audit_times: usize,
    /// JSON lines of every run.
    #[arg(long, default_value = "bench-planners.jsonl")]
    out: PathBuf,
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
    let time_limit = time_limit_arg(a.time_limit)?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(&a.scenes)
        .map_err(|e| CliError(format!("--scenes {}: {e}", a.scenes.display())))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    let mut log = std::fs::File::create(&a.out).map_err(|e| CliError(format!("{}: {e}", a.out.display())))?;
    let host = host();
    let rev = std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let mut table = vec![
        format!(
            "Host: {host}; git {rev}; {} seeds; time limit {} s; audit {} scenarios × {} times per piece.",
            a.seeds, a.time_limit, a.audit_samples, a.audit_times
        ),
        String::new(),
        "| scene | planner | solved | median time (s) | paper (s) | median length | max MC risk | plans over Δ (99%) |"
            .into(),
        "|---|---|---|---|---|---|---|---|".into(),
    ];
    for f in files {
        let scene = Arc::new(load_scene(&f)?);
        if scene.start.is_none() {
            continue;
        }
        let dynamic = scene.obstacles.iter().any(|o| o.contour.is_dynamic());
        let paper = scene.file.expected.as_ref().map(|e| e["run_time_s"].clone()).unwrap_or_default();
        let paper_t = |k: &str| paper[k]["paper"].as_f64().map(|v| format!("{v}")).unwrap_or_else(|| "–".into());
        let mut variants: Vec<(&str, PlannerKind, bool, String)> = vec![];
        if dynamic {
            variants.push(("rrt-sos", PlannerKind::RrtSos, false, paper_t("rrt_sos")));
        } else {
            variants.push(("rrt-sos", PlannerKind::RrtSos, false, paper_t("rrt_sos_feasible")));
            variants.push(("rrt-sos --improve", PlannerKind::RrtSos, true, paper_t("rrt_sos_optimal")));
        }
        let mc_paper = if dynamic { "–".into() } else { paper_t("monte_carlo_rrt_feasible") };
        variants.push(("mc-rrt", PlannerKind::McRrt, false, mc_paper));
        for (label, planner, improve, paper_time) in variants {
            let (mut times, mut lens, mut worst, mut over, mut solved) = (vec![], vec![], 0.0f64, 0, 0);
            for seed in 1..=a.seeds {
                let request = PlanRequest { planner, improve, seed, time_limit, ..PlanRequest::default() };
                let (_, out) = request.run(scene.clone(), None).map_err(|e| CliError(e.to_string()))?;
                let mut rec = json!({"scene": scene.name, "planner": label, "seed": seed, "host": host, "git": rev, "time_limit_s": a.time_limit, "status": out.status, "certified": out.certified, "stats": out.stats});
                if let Some(t) = &out.trajectory {
                    solved += 1;
                    times.push(out.stats.planning_time_s);
                    lens.push(out.stats.path_length.unwrap_or(f64::NAN));
                    let opts = AuditOptions {
                        times_per_piece: a.audit_times,
                        samples: a.audit_samples,
                        seed: 7 + seed,
                        ..AuditOptions::default()
                    };
                    let audit = audit_trajectory(&scene, t, scene.risk_f64(), &opts)
                        .map_err(|e| CliError(format!("{}: Monte Carlo audit: {e}", scene.name)))?;
                    let (w, ex) = (audit.max_estimate, audit.exceeds());
                    worst = worst.max(w);
                    over += ex as usize;
                    rec["audit"] = json!({"max_risk_estimate": w, "exceeds_delta_99": ex, "samples": a.audit_samples});
                }
                writeln!(log, "{rec}").map_err(|e| CliError(e.to_string()))?;
            }
            let fmt = |v: Option<f64>| v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "–".into());
            table.push(format!(
                "| {} | {label} | {solved}/{} | {} | {paper_time} | {} | {worst:.4} | {over}/{solved} |",
                scene.name,
                a.seeds,
                fmt(median(times)),
                fmt(median(lens))
            ));
            eprintln!("{}", table.last().cloned().unwrap_or_default());
        }
    }
    print_out(&table.join("\n"))?;
    Ok(0)
}
