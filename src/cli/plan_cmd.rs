//! `riskplan plan`: RRT-SOS (static or time-layered) and the Monte Carlo baseline.

use super::util::{delta_arg, load_scene, method_parser, planner_parser, print_out, time_limit_arg, CliError};
use crate::viz::{self, ContourOptions, Overlay};
use clap::Args;
use riskplan_app::verify::Method;
use riskplan_app::{PlanRequest, PlannerKind};
use riskplan_plan::{PlanStatus, Problem, Termination};
use riskplan_scene::{Scene, TrajectoryFile, TRAJECTORY_FORMAT};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

/// Plan a risk-bounded trajectory from the scene's start to its goal.
///
/// rrt-sos (default): every edge is certified safe in continuous time (eq. 15) against
/// every obstacle's Δ-risk contour. Static scenes: a bidirectional tree; moving
/// obstacles: the time-layered tree, trying 1, 2, 4, … 32 equal time intervals
/// (--pieces fixes the number), each edge certified on its own interval. The path is
/// then shortcut and its corners blended into C¹ pieces of degree ≤ 2, each certified
/// (--no-smooth keeps the raw path). Lengths are derived from the workspace, so any
/// scale and placement behaves alike.
///
/// rrt-sos-paper: the paper's RRT-SOS as published (widening stripes, rlim), with the
/// scene's planner.rrt_sos block or the paper's values scaled to the workspace;
/// --improve adds its improve step on static scenes. mc-rrt: the default search with
/// the paper's Monte Carlo edge check (10 scenarios × 20 waypoints per edge): its
/// output is marked "certified": false.
///
/// tv-sos: the paper's time-varying SOS planner (Section V-B): a moment relaxation
/// over straight pieces on equal time intervals (the scene's
/// planner.time_varying_sos.pieces, else 2; --pieces sets it), iterated towards point
/// measures and read out as waypoints; every piece certified. It starts from the
/// default planner's path (on static scenes next from the corners of its unsmoothed
/// path, one piece per segment), then the perturbed straight line, and retries with fresh
/// seeds, more pieces and a tighter optimisation risk; the stats report the SDP sizes,
/// solver time and each step of that ladder. --max-speed applies; --improve and
/// --max-accel do not.
///
/// moment: the paper's standard SOS planner with average risk (Section V-A.2): one
/// Lasserre moment relaxation over piecewise-linear trajectories (the scene's
/// planner.standard_sos.piecewise_linear_pieces, else 2; --pieces sets it) with time
/// averaged out, its atoms extracted (Henrion–Lasserre) and each atom's trajectory
/// certified against the per-instant Δ like any other; the average risk is a weak
/// guarantee and is reported beside (stats.average_risk). Retries with a tighter
/// optimisation risk, then one more piece. moment-poly: the same over one polynomial
/// of degree d (planner.standard_sos.polynomial_trajectory_degree, else 2).
///
/// --risk-mode joint bounds the probability of colliding with any obstacle at each
/// instant by Δ (obstacle i gets Δᵢ, ΣΔᵢ = Δ; the stats list them); the default
/// per-obstacle mode is the paper's. --risk-mode trajectory bounds the probability of
/// meeting any obstacle at any time along the plan, the parameters drawn once
/// (docs/design.md §5.14): rrt-sos keeps each partial path's whole-path bound within Δ
/// and the final check proves the plan's; slower (example-d1: about 0.4 s instead of 0.04 s).
/// Every certified plan reports its whole-path bound (stats.whole_path_risk).
///
/// --start and --goal plan between other endpoints than the scene's. --planner receding
/// plans one receding-horizon window from the robot's state (docs/design.md §6.9): from
/// --position (default: the scene's start) with --velocity (default: at rest) at --t-now
/// (default: the horizon's start) over --horizon time units (default: the scene's whole
/// horizon), towards --goal (default: the scene's); a plan that does not reach the goal
/// within the window ends where it got to ("progress").
///
/// Writes the trajectory (format v1 plus "planner", "certified", "stats") to --out or
/// stdout and a one-line summary to stderr. Exit status: 0 plan found, 1 none found
/// within the limits, 2 bad input.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Scene file (format v1) with start and goal.
    #[arg(long)]
    scene: PathBuf,
    /// Planner.
    #[arg(long, default_value = "rrt-sos", value_parser = planner_parser())]
    planner: PlannerKind,
    /// Start instead of the scene's: one coordinate per dimension.
    #[arg(long, num_args = 1.., allow_negative_numbers = true, value_name = "X")]
    start: Option<Vec<f64>>,
    /// Goal instead of the scene's: one coordinate per dimension.
    #[arg(long, num_args = 1.., allow_negative_numbers = true, value_name = "X")]
    goal: Option<Vec<f64>>,
    /// --planner receding: the current time (default: the scene's horizon start).
    #[arg(long, allow_negative_numbers = true, value_name = "T")]
    t_now: Option<f64>,
    /// --planner receding: the robot's position at --t-now (default: --start, else the scene's start).
    #[arg(long, num_args = 1.., allow_negative_numbers = true, value_name = "X")]
    position: Option<Vec<f64>>,
    /// --planner receding: the robot's velocity at --t-now (default: at rest).
    #[arg(long, num_args = 1.., allow_negative_numbers = true, value_name = "V")]
    velocity: Option<Vec<f64>>,
    /// --planner receding: the window's length in time units (default: to the scene's horizon end).
    #[arg(long, value_name = "H")]
    horizon: Option<f64>,
    /// Run the improve step of rrt-sos-paper on a static scene: shortest path over all certified edges between tree vertices.
    #[arg(long)]
    improve: bool,
    /// Seed of the planner's RNG (same seed, same plan).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Pieces of the time-layered planner (default: the ladder 1, 2, 4, … 32; rrt-sos-paper: the scene's planner block, else the ladder). Forces the layered planner.
    #[arg(long)]
    pieces: Option<usize>,
    /// Speed limit in workspace units per time unit (default: the scene's planner.max_speed, else none).
    #[arg(long)]
    max_speed: Option<f64>,
    /// Acceleration limit for the corner blends (default: the scene's planner.max_accel, else none).
    #[arg(long)]
    max_accel: Option<f64>,
    /// Return the raw tree path (straight pieces, velocity jumps at the corners).
    #[arg(long)]
    no_smooth: bool,
    /// What Δ bounds: per-obstacle (the paper's), joint (any obstacle; Δ split evenly), joint-weighted (more of Δ to obstacles near the start–goal line) or trajectory (any obstacle at any time along the plan).
    #[arg(long, default_value = "per-obstacle")]
    risk_mode: riskplan_app::RiskMode,
    /// Which risk bounds may prove safety: auto (the tightest sound one: Cantelli, zero risk from bounded support, shifted moment bounds of orders 4–8, on sub-intervals) or cantelli (the paper's). Default: the scene's planner.bound, else auto.
    #[arg(long)]
    bound: Option<riskplan_math::contour::BoundChoice>,
    /// Time limit in seconds.
    #[arg(long, default_value_t = 120.0)]
    time_limit: f64,
    /// Risk level Δ (default: the scene's risk).
    #[arg(long)]
    delta: Option<String>,
    /// Certification method of rrt-sos edges.
    #[arg(long, default_value = "exact", value_parser = method_parser())]
    certifier: Method,
    /// Write the trajectory here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Draw contours, tree and path (.svg or .png); 3-D scenes as the x1–x2 projection,
    /// each contour the section at the path's x3 at its time (legend: t and x3).
    #[arg(long)]
    figure: Option<PathBuf>,
}

pub fn run(a: PlanArgs) -> Result<i32, CliError> {
    // the outputs are checked before any work: a plan is not made to be lost
    for (flag, path) in [("--out", &a.out), ("--figure", &a.figure)] {
        if let Some(p) = path {
            writable(flag, p)?;
        }
    }
    let scene = Arc::new(load_scene(&a.scene)?);
    let point = |flag: &str, v: &Option<Vec<f64>>| -> Result<Option<Vec<f64>>, CliError> {
        match v {
            Some(x) if x.len() != scene.dim => Err(CliError(format!(
                "{flag}: the scene is {}-D, so give {} coordinates, got {}",
                scene.dim,
                scene.dim,
                x.len()
            ))),
            Some(x) if x.iter().any(|c| !c.is_finite()) => Err(CliError(format!("{flag}: coordinates must be finite"))),
            other => Ok(other.clone()),
        }
    };
    let (start, goal) = (point("--start", &a.start)?, point("--goal", &a.goal)?);
    let (position, velocity) = (point("--position", &a.position)?, point("--velocity", &a.velocity)?);
    let receding_flags = a.t_now.is_some() || position.is_some() || velocity.is_some() || a.horizon.is_some();
    if receding_flags && a.planner != PlannerKind::Receding {
        return Err(CliError(
            "--t-now, --position, --velocity and --horizon describe a receding-horizon request: add --planner receding"
                .into(),
        ));
    }
    // a point not given: the scene's own, else the flag to give
    let or_scene = |given: Option<Vec<f64>>, own: &Option<Vec<f64>>, what: &str| {
        given
            .or_else(|| own.clone())
            .ok_or_else(|| CliError(format!("{}: the scene has no {what}: give --{what}", a.scene.display())))
    };
    let (receding, endpoints) = if a.planner == PlannerKind::Receding {
        let t_now = a.t_now.unwrap_or(scene.horizon.0);
        let r = riskplan_app::RecedingRequest {
            t_now,
            position: or_scene(position.or(start), &scene.start, "start")?,
            velocity,
            horizon: a.horizon.unwrap_or(scene.horizon.1 - t_now),
            goal: or_scene(goal, &scene.goal, "goal")?,
            warm_start: None,
        };
        (Some(r), None)
    } else if start.is_none() && goal.is_none() {
        (None, None)
    } else {
        (None, Some((or_scene(start, &scene.start, "start")?, or_scene(goal, &scene.goal, "goal")?)))
    };
    let request = PlanRequest {
        planner: a.planner,
        certifier: a.certifier,
        delta: a.delta.as_deref().map(delta_arg).transpose()?,
        endpoints,
        seed: a.seed,
        pieces: a.pieces,
        improve: a.improve,
        time_limit: time_limit_arg(a.time_limit)?,
        max_speed: a.max_speed,
        max_accel: a.max_accel,
        smooth: !a.no_smooth,
        risk_mode: a.risk_mode,
        bound: a.bound,
        receding,
    };
    let mut prepared = request.prepare(scene.clone()).map_err(|e| CliError(format!("{}: {e}", a.scene.display())))?;
    let term = request.termination(None);
    let progress = Progress::start(term.clone());
    let result = prepared.solve(&term);
    progress.finish();
    let problem = prepared.problem;
    let outcome = result.map_err(|e| CliError(format!("{}: {e}", a.scene.display())))?;
    let s = &outcome.stats;
    eprintln!(
        "{}: {} ({}) in {:.3} s: {} iterations, {} vertices, {} edges checked, {} accepted{}",
        a.planner,
        match outcome.status {
            PlanStatus::Exact => "plan found",
            PlanStatus::DeadlineReached => "no plan before the time limit",
            PlanStatus::Cancelled => "cancelled",
            PlanStatus::Exhausted => "no plan within the iteration limits",
            PlanStatus::Progress => "plan towards the goal (not reached within the window)",
        },
        if outcome.certified { "certified" } else { "NOT certified" },
        s.planning_time_s,
        s.iterations,
        s.vertices,
        s.edges_checked,
        s.edges_accepted,
        s.path_length.map(|l| format!(", length {l:.4}")).unwrap_or_default()
    );
    if let Some(r) = &outcome.reason {
        eprintln!("{}: {}", a.planner, r.message());
    }
    if let Some(n) = s.final_check.as_ref().map(|f| f.disagreements).filter(|&n| n > 0) {
        eprintln!(
            "{}: internal error: the final check rejected {n} trajectory(ies) the fast edge check had accepted (a bug; \
             planned again without the fast path; please report it with the scene)",
            a.planner
        );
    }
    if let Some(n) = s.final_check.as_ref().map(|f| f.invalid).filter(|&n| n > 0) {
        eprintln!(
            "{}: internal error: the planner returned {n} trajectory(ies) that are not valid (a bug; planned again \
             without smoothing; please report it with the scene and seed)",
            a.planner
        );
    }
    if let Some(fig) = &a.figure {
        draw_figure(&scene, &problem, &outcome, !a.planner.certifies(), fig)?;
    }
    let Some(traj) = outcome.trajectory else { return Ok(1) };
    let file = TrajectoryFile {
        format: TRAJECTORY_FORMAT.to_string(),
        pieces: traj.pieces,
        planner: Some(a.planner.to_string()),
        certified: Some(outcome.certified),
        stats: serde_json::to_value(&outcome.stats).ok(),
        revision: None,
        scene: Some(scene.name.clone()),
        risk: Some(problem.delta.to_f64()),
    };
    let text = serde_json::to_string_pretty(&file).map_err(|e| CliError(e.to_string()))?;
    match &a.out {
        Some(p) => {
            std::fs::write(p, text + "\n").map_err(|e| CliError(format!("{}: cannot write: {e}", p.display())))?
        }
        None => print_out(&text)?,
    }
    Ok(0)
}

/// Refuses an output path whose directory does not exist (or is not a directory), before
/// the work that would write it.
pub(crate) fn writable(flag: &str, path: &std::path::Path) -> Result<(), CliError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    if !dir.is_dir() {
        return Err(CliError(format!(
            "{flag} {}: the directory {} does not exist: create it first (mkdir -p {})",
            path.display(),
            dir.display(),
            dir.display()
        )));
    }
    if path.is_dir() {
        return Err(CliError(format!("{flag} {}: is a directory: name a file in it", path.display())));
    }
    Ok(())
}

fn draw_figure(
    scene: &Scene,
    p: &Problem,
    out: &riskplan_plan::PlanOutcome,
    sampled_edges: bool,
    fig: &std::path::Path,
) -> Result<(), CliError> {
    let mut overlays = vec![Overlay::Segments {
        segments: out.tree.clone(),
        color: (120, 120, 120),
        // mc-rrt's edges passed a Monte Carlo test only: the legend says which
        label: Some(
            if sampled_edges { "tree (edges passed Monte Carlo only)" } else { "tree (certified edges)" }.into(),
        ),
    }];
    let path = out.trajectory.as_ref().filter(|t| !t.pieces.is_empty());
    // the contours' times: on a moving scene those of the waypoints
    let mut times = vec![p.horizon.0];
    let mut marked: Option<(Vec<Vec<f64>>, String)> = None;
    if let Some(t) = path.filter(|_| p.is_dynamic()) {
        times = t.pieces.iter().map(|pc| pc.t0).chain(std::iter::once(p.horizon.1)).collect();
        let points = t.pieces.iter().map(|pc| pc.at(pc.t0)).chain(std::iter::once(p.goal.clone())).collect();
        let at: Vec<String> = times.iter().map(|&t| viz::legend_number(t)).collect();
        marked = Some((points, format!("waypoints, coloured as their contours, at t = {}", at.join(", "))));
    }
    let (mut slices, mut slices_at, mut title) = (vec![], vec![], scene.name.clone());
    if scene.dim == 3 {
        let s = sections_at_path(p, path, &times);
        times = s.times;
        slices = vec![(2, 0.0)];
        slices_at = s.levels.iter().map(|&z| vec![(2, z)]).collect();
        title = format!("{} (sections at {})", scene.name, s.what);
        if marked.is_none() && !s.points.is_empty() {
            marked = Some((s.points, "the path's points of the sections, coloured as their contours".into()));
        }
    }
    if let Some(t) = path {
        let mut pts: Vec<Vec<f64>> = Vec::new();
        for pc in &t.pieces {
            for k in 0..=16 {
                pts.push(pc.at(pc.t0 + (pc.t1 - pc.t0) * k as f64 / 16.0));
            }
        }
        let label = if out.certified { "certified path" } else { "path (NOT certified)" };
        overlays.push(Overlay::Path { points: pts, color: (20, 60, 200), width: 3, label: Some(label.into()) });
    }
    // each marked point in the colour of its time's contour
    if let Some((points, label)) = marked {
        for (k, q) in points.into_iter().enumerate() {
            overlays.push(Overlay::Points {
                points: vec![q],
                color: viz::time_color(k),
                size: 4,
                label: (k == 0).then(|| label.clone()),
            });
        }
    }
    overlays.push(Overlay::Points {
        points: vec![p.start.clone(), p.goal.clone()],
        color: (0, 0, 0),
        size: 5,
        label: Some("start, goal".into()),
    });
    let opts = ContourOptions {
        deltas: vec![p.delta.to_f64()],
        times,
        slices,
        slices_at,
        grid: 250,
        title: Some(title),
        ..Default::default()
    };
    viz::draw(scene, &opts, &overlays, fig).map_err(|e| CliError(e.to_string()))?;
    eprintln!("wrote {}", fig.display());
    Ok(())
}

/// The sections of a 3-D scene's plan figure (x1–x2 sections at heights x3).
struct Sections {
    /// The time of each section's contour.
    times: Vec<f64>,
    /// The x3 level of each.
    levels: Vec<f64>,
    /// The path's point at each section (empty without a path).
    points: Vec<Vec<f64>>,
    /// What the levels are, for the title.
    what: &'static str,
}

/// The sections of a 3-D plan figure. With a path: at the path's x3 at each contour's
/// time (`times`, the waypoints' on a moving scene); on a static scene, where each piece
/// starts and where the last ends. Without a path: the start's x3 and the goal's.
fn sections_at_path(p: &Problem, path: Option<&riskplan_scene::Trajectory>, times: &[f64]) -> Sections {
    let dynamic = p.is_dynamic();
    let Some(t) = path else {
        let times = if dynamic { vec![p.horizon.0, p.horizon.1] } else { vec![p.horizon.0; 2] };
        return Sections {
            times,
            levels: vec![p.start[2], p.goal[2]],
            points: vec![],
            what: "the start's and goal's x3",
        };
    };
    let at = |s: f64| -> Vec<f64> {
        let pc = t.pieces.iter().find(|pc| s <= pc.t1).unwrap_or(&t.pieces[t.pieces.len() - 1]);
        pc.at(s.clamp(pc.t0, pc.t1))
    };
    let (section_times, what) = if dynamic {
        (times.to_vec(), "the path's x3 at each time")
    } else {
        (
            t.pieces.iter().map(|pc| pc.t0).chain(t.pieces.last().map(|pc| pc.t1)).collect(),
            "the path's x3 at piece ends",
        )
    };
    let points: Vec<Vec<f64>> = section_times.iter().map(|&s| at(s)).collect();
    Sections {
        times: if dynamic { section_times } else { vec![p.horizon.0; points.len()] },
        levels: points.iter().map(|q| q[2]).collect(),
        points,
        what,
    }
}

/// A spinner on stderr, shown only on a terminal and only for plans over a second.
struct Progress {
    done: std::sync::mpsc::Sender<()>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl Progress {
    fn start(term: Termination) -> Progress {
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let handle = std::io::stderr().is_terminal().then(|| {
            std::thread::spawn(move || {
                if rx.recv_timeout(Duration::from_secs(1)).is_ok() {
                    return;
                }
                let bar = indicatif::ProgressBar::new_spinner();
                bar.set_style(
                    indicatif::ProgressStyle::with_template("{spinner} planning… {elapsed} {msg}")
                        .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
                );
                bar.enable_steady_tick(Duration::from_millis(120));
                loop {
                    if let Some(left) = term.remaining() {
                        bar.set_message(format!("({:.0} s left)", left.as_secs_f64()));
                    }
                    if rx.recv_timeout(Duration::from_millis(250)).is_ok() {
                        break;
                    }
                }
                bar.finish_and_clear();
            })
        });
        Progress { done: tx, handle }
    }
    fn finish(mut self) {
        let _ = self.done.send(());
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}
