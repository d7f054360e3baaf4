//! `riskplan sim crowd`: the closed-loop crowd simulation against a running service,
//! over Zenoh, exactly as a robot would use it (docs/design.md §6.10).

use super::util::CliError;
use clap::{Args, Subcommand};
use riskplan_app::crowd::{self, Crowd, CrowdParams, STEP};
use riskplan_scene::{Trajectory, TRAJECTORY_FORMAT};
use riskplan_service::proto::{ApplyRequest, Change, ChangeOp, Codec, EmbeddedJson, PlanRequest};
use riskplan_service::Client;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Simulations that use the running service as a robot would.
#[derive(Args, Debug)]
pub struct SimArgs {
    #[command(subcommand)]
    command: SimCommand,
}

#[derive(Subcommand, Debug)]
enum SimCommand {
    /// A robot crossing a corridor (16 × 6) among walking pedestrians, replanning every
    /// 0.1 s: each step sends the pedestrians' predictions (measured position, nominal
    /// velocity, Gaussian errors; their true velocities are drawn from those
    /// distributions) as one `apply`, then a receding-horizon plan request from the
    /// robot's state, and moves the robot along the answer (keeping the previous plan
    /// when a replan fails, stopping at the end of a plan). The last line of output is
    /// one JSON object: episodes, reached_goal, collisions, time_to_goal_s_median,
    /// replan_ms_p50, replan_ms_p99 (client-measured update + plan), no_plan.
    Crowd(CrowdArgs),
}

/// `riskplan sim crowd`.
#[derive(Args, Debug)]
pub struct CrowdArgs {
    /// Pedestrians in the corridor.
    #[arg(long, default_value_t = 30)]
    pedestrians: usize,
    /// Episodes.
    #[arg(long, default_value_t = 10)]
    episodes: usize,
    /// Seed (episode k uses seed + k).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Risk level Δ per pedestrian and instant.
    #[arg(long, default_value_t = 0.01)]
    delta: f64,
    /// The robot's body radius.
    #[arg(long, default_value_t = 0.25)]
    robot_radius: f64,
    /// The robot's speed limit.
    #[arg(long, default_value_t = 1.5)]
    max_speed: f64,
    /// The robot's acceleration limit (default: twice the speed limit per second).
    #[arg(long)]
    max_accel: Option<f64>,
    /// The planning window H, seconds.
    #[arg(long, default_value_t = 3.0)]
    window: f64,
    /// Each replan's time limit, seconds.
    #[arg(long, default_value_t = 0.03)]
    plan_time: f64,
    /// The service's endpoint.
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    endpoint: String,
    /// Write an animation of the first episode (animated SVG).
    #[arg(long)]
    animate: Option<PathBuf>,
    /// One line per replan on stderr: latency, planning time, edges, the plan's end.
    #[arg(long)]
    verbose: bool,
}

pub fn run(a: SimArgs) -> Result<i32, CliError> {
    match a.command {
        SimCommand::Crowd(c) => run_crowd(c),
    }
}

/// How far ahead of each prediction the animation draws the pedestrians' Δ-contours,
/// seconds.
const CONTOUR_AHEAD: f64 = 1.0;

/// One frame of the animation.
struct Frame {
    robot: [f64; 2],
    plan: Vec<[f64; 2]>,
    walkers: Vec<FrameWalker>,
}

/// One pedestrian in a frame.
struct FrameWalker {
    /// True position now.
    x: [f64; 2],
    /// True radius.
    radius: f64,
    /// The predicted centre [`CONTOUR_AHEAD`] seconds after the prediction sent now
    /// (measured position plus nominal velocity times that time).
    ahead: [f64; 2],
    /// The radius of the Δ-contour there (see [`delta_radius`]).
    delta_radius: f64,
}

fn run_crowd(a: CrowdArgs) -> Result<i32, CliError> {
    let bad = |m: String| CliError(m);
    let within = |v: f64, lo: f64, hi: f64| v.is_finite() && v > lo && v < hi;
    if !within(a.delta, 0.0, 1.0) {
        return Err(bad(format!("--delta must be in (0, 1), got {}", a.delta)));
    }
    let body_max = crowd::CORRIDOR_WIDTH / 4.0;
    if !(a.robot_radius == 0.0 || within(a.robot_radius, 0.0, body_max)) {
        return Err(bad(format!("--robot-radius must be in [0, {body_max}), got {}", a.robot_radius)));
    }
    let positive = |v: f64| within(v, 0.0, f64::INFINITY);
    if !positive(a.max_speed) || !within(a.window, STEP, f64::INFINITY) || !positive(a.plan_time) {
        return Err(bad("--max-speed and --plan-time must be positive, --window above 0.1".into()));
    }
    if a.max_accel.is_some_and(|v| !positive(v)) {
        return Err(bad("--max-accel must be positive".into()));
    }
    if a.pedestrians > 200 || a.episodes == 0 || a.episodes > 10_000 {
        return Err(bad("--pedestrians at most 200, --episodes between 1 and 10000".into()));
    }
    let accel = a.max_accel.unwrap_or(2.0 * a.max_speed);
    let rt = super::util::client_runtime()?;
    rt.block_on(async move {
        let client = Client::connect(&a.endpoint, Duration::from_secs(10), Codec::Bincode)
            .await
            .map_err(|e| CliError(e.to_string()))?;
        let r = episodes(&client, &a, accel).await;
        client.close().await;
        r
    })
}

async fn episodes(client: &Client, a: &CrowdArgs, accel: f64) -> Result<i32, CliError> {
    let mut tally = Tally::default();
    for ep in 0..a.episodes {
        episode(client, a, accel, ep, &mut tally).await?;
    }
    if let Some(path) = &a.animate {
        std::fs::write(path, animation(&tally.frames, a.pedestrians, a.delta, a.robot_radius))
            .map_err(|e| CliError(format!("{}: {e}", path.display())))?;
    }
    println!("{}", tally.summary(a));
    Ok(0)
}

/// What the episodes of a crowd simulation found, added up.
#[derive(Default)]
struct Tally {
    reached: usize,
    collisions: usize,
    no_plan: usize,
    /// Times to the goal (s).
    times: Vec<f64>,
    /// Replan round trips, update and plan (ms).
    lat: Vec<f64>,
    /// Update round trips (ms).
    upd: Vec<f64>,
    /// Failed replans by error code.
    reasons: std::collections::BTreeMap<String, usize>,
    /// The first episode's frames (`--animate`).
    frames: Vec<Frame>,
}

impl Tally {
    /// The summary line (JSON): outcomes, medians and 99th percentiles.
    fn summary(&mut self, a: &CrowdArgs) -> serde_json::Value {
        let pct = |v: &mut Vec<f64>, q: f64| -> Option<f64> {
            v.sort_by(f64::total_cmp);
            (!v.is_empty()).then(|| v[((v.len() - 1) as f64 * q).round() as usize])
        };
        serde_json::json!({
            "episodes": a.episodes, "reached_goal": self.reached, "collisions": self.collisions,
            "time_to_goal_s_median": pct(&mut self.times, 0.5), "replan_ms_p50": pct(&mut self.lat, 0.5),
            "replan_ms_p99": pct(&mut self.lat, 0.99), "no_plan": self.no_plan, "no_plan_reasons": self.reasons,
            "replans": self.lat.len(),
            "update_ms_p50": pct(&mut self.upd, 0.5), "update_ms_p99": pct(&mut self.upd, 0.99),
            "pedestrians": a.pedestrians, "delta": a.delta, "robot_radius": a.robot_radius,
        })
    }
}

/// The scene of episode `name`: the corridor, each pedestrian's prediction at time 0, the
/// horizon `t_max` and a window beyond it.
fn episode_scene(world: &mut Crowd, name: &str, a: &CrowdArgs, accel: f64, t_max: f64) -> serde_json::Value {
    let (lo, hi) = crowd::bounds();
    let obstacles: Vec<serde_json::Value> = (0..world.walkers.len())
        .map(|i| serde_json::json!({"id": world.walkers[i].id.clone(), "pedestrian": world.prediction(i, 0.0)}))
        .collect();
    serde_json::json!({"format": "riskplan-scene/1", "name": name, "dim": 2,
        "workspace": {"lower": lo, "upper": hi}, "horizon": [0.0, t_max + a.window], "risk": a.delta,
        "robot_radius": a.robot_radius, "obstacles": obstacles,
        "planner": {"max_speed": a.max_speed, "max_accel": accel}})
}

/// The update at time `t`: the pedestrians that left deleted, every other one's prediction
/// put; and where each is predicted [`CONTOUR_AHEAD`] later (for the animation).
fn predictions(world: &mut Crowd, t: f64, removed: &mut Vec<String>) -> (Vec<Change>, Vec<[f64; 2]>) {
    let mut changes: Vec<Change> = removed
        .drain(..)
        .map(|id| Change { op: ChangeOp::Delete.into(), id, poly: None, params: None, pedestrian: None })
        .collect();
    let mut ahead: Vec<[f64; 2]> = Vec::with_capacity(world.walkers.len());
    for i in 0..world.walkers.len() {
        let p = world.prediction(i, t);
        let (m, n) = (&p["position"], world.walkers[i].nominal);
        let at = |d: usize| m[d].as_f64().unwrap_or(world.walkers[i].x[d]) + n[d] * CONTOUR_AHEAD;
        ahead.push([at(0), at(1)]);
        changes.push(Change {
            op: ChangeOp::Put.into(),
            id: world.walkers[i].id.clone(),
            poly: None,
            params: None,
            pedestrian: Some(EmbeddedJson(p)),
        });
    }
    (changes, ahead)
}

/// One frame of the animation: the robot at `x`, its plan from `t`, the pedestrians and
/// their contours `ahead`.
fn frame(world: &Crowd, plan: Option<&Trajectory>, x: [f64; 2], t: f64, ahead: &[[f64; 2]], radius: f64) -> Frame {
    let plan_pts = plan
        .map(|p| {
            let (t0, t1) = (t, p.pieces.last().map_or(t, |q| q.t1));
            (0..=20).map(|k| crowd::follow(p, t0 + (t1 - t0) * k as f64 / 20.0).0).collect()
        })
        .unwrap_or_default();
    let walkers = world
        .walkers
        .iter()
        .zip(ahead)
        .map(|(w, c)| FrameWalker { x: w.x, radius: w.radius, ahead: *c, delta_radius: radius })
        .collect();
    Frame { robot: x, plan: plan_pts, walkers }
}

/// One episode: the scene put, then every [`STEP`] the pedestrians' update, a replan
/// from the robot's state, a step along the plan (at rest where none is left), until the
/// goal, a contact or the time limit.
async fn episode(client: &Client, a: &CrowdArgs, accel: f64, ep: usize, tally: &mut Tally) -> Result<(), CliError> {
    let (start, goal) = crowd::start_goal();
    let straight = (goal[0] - start[0]).hypot(goal[1] - start[1]);
    // an episode lasts at most four times the straight crossing at full speed
    let t_max = 4.0 * straight / a.max_speed;
    let params = CrowdParams::default();
    let clear = 2.0 * (params.radius.1 + a.robot_radius) + 1.0;
    let mut world = Crowd::new(a.pedestrians, a.seed.wrapping_add(ep as u64), params, start, clear);
    let name = format!("sim-crowd-{}", a.seed.wrapping_add(ep as u64));
    let scene = episode_scene(&mut world, &name, a, accel, t_max);
    client
        .apply(&name, &ApplyRequest { scene: Some(EmbeddedJson(scene)), ..Default::default() })
        .await
        .map_err(|e| CliError(format!("episode {ep}: cannot put the scene: {e}")))?;
    let (mut x, mut v) = (start, [0.0, 0.0]);
    let mut plan: Option<Trajectory> = None;
    let mut t = 0.0;
    let mut outcome = "timeout";
    let mut removed: Vec<String> = Vec::new();
    while t < t_max {
        let (changes, ahead) = predictions(&mut world, t, &mut removed);
        let began = Instant::now();
        let applied = client.apply(&name, &ApplyRequest { changes: Some(changes), ..Default::default() }).await;
        tally.upd.push(began.elapsed().as_secs_f64() * 1e3);
        if let Err(e) = applied {
            return Err(CliError(format!("episode {ep} at t = {t:.1}: the update failed: {e}")));
        }
        let state = Robot { t, x, v, goal, began };
        let failed_last = !replan(client, a, &name, ep, &state, &mut plan, tally).await;
        // move along the plan (at rest where none is left)
        let follow = |s: f64| -> [f64; 2] {
            match &plan {
                Some(p) => crowd::follow(p, s).0,
                None => x,
            }
        };
        if ep == 0 && a.animate.is_some() {
            let radius = delta_radius(&params, a, CONTOUR_AHEAD);
            tally.frames.push(frame(&world, plan.as_ref(), x, t, &ahead, radius));
        }
        if let Some(id) = world.contact(&follow, t, STEP, a.robot_radius) {
            tally.collisions += 1;
            outcome = "collision";
            let end = plan.as_ref().and_then(|p| p.pieces.last()).map_or(t, |p| p.t1);
            eprintln!(
                "episode {ep}: contact with {id} at t = {t:.1} (robot at {x:?}, speed {:.2}; its plan ends at {end:.2}; last replan {})",
                v[0].hypot(v[1]),
                if failed_last { "failed" } else { "succeeded" }
            );
            break;
        }
        let next = t + STEP;
        (x, v) = match &plan {
            Some(p) => crowd::follow(p, next),
            None => (x, [0.0, 0.0]),
        };
        t = next;
        removed = world.step(STEP, x, clear);
        if (x[0] - goal[0]).hypot(x[1] - goal[1]) <= 1e-6 * straight {
            tally.reached += 1;
            tally.times.push(t);
            outcome = "goal";
            break;
        }
    }
    let left = (x[0] - goal[0]).hypot(x[1] - goal[1]);
    println!("episode {ep}: {outcome} at t = {t:.1} s (robot at [{:.2}, {:.2}], {left:.2} from the goal)", x[0], x[1]);
    Ok(())
}

/// The robot's state at a replan: the time, position, velocity and goal, and when the
/// cycle's round trip began.
struct Robot {
    t: f64,
    x: [f64; 2],
    v: [f64; 2],
    goal: [f64; 2],
    began: Instant,
}

/// A receding-horizon replan from the robot's state (the round trip counted from the
/// cycle's start): `plan` becomes the reply's pieces; on a failure the last plan stays,
/// and its error code is counted. Whether it succeeded.
async fn replan(
    client: &Client,
    a: &CrowdArgs,
    name: &str,
    ep: usize,
    r: &Robot,
    plan: &mut Option<Trajectory>,
    tally: &mut Tally,
) -> bool {
    let req = PlanRequest {
        goal: Some(r.goal.to_vec()),
        time_limit: Some(a.plan_time),
        seed: Some(1 + (r.t / STEP).round() as u64),
        t_now: Some(r.t),
        position: Some(r.x.to_vec()),
        velocity: Some(r.v.to_vec()),
        horizon: Some(a.window),
        robot_id: Some("sim-robot".into()),
        ..Default::default()
    };
    let reply = client.plan(name, &req).await;
    tally.lat.push(r.began.elapsed().as_secs_f64() * 1e3);
    match reply {
        Ok(reply) => {
            if a.verbose {
                log_reply(ep, r.t, r.began, &reply);
            }
            *plan = Some(Trajectory { format: TRAJECTORY_FORMAT.into(), pieces: reply.pieces });
            true
        }
        Err(e) => {
            tally.no_plan += 1;
            if a.verbose {
                eprintln!("episode {ep} t = {:.1}: no plan: {e}", r.t);
            }
            let code = match &e {
                riskplan_service::ClientError::Server(r) => r.code.as_str().to_string(),
                other => other.to_string(),
            };
            *tally.reasons.entry(code).or_insert(0usize) += 1;
            false
        }
    }
}

/// `--verbose`: one replan's round trip, planner time, edges and where its plan ends.
fn log_reply(ep: usize, t: f64, began: Instant, r: &riskplan_service::proto::PlanReply) {
    let p = r.stats.progress.as_ref();
    eprintln!(
        "episode {ep} t = {t:.1}: {:.1} ms (plan {:.1} ms, {} of {} edges accepted), plan to {:.2} s, {}",
        began.elapsed().as_secs_f64() * 1e3,
        r.stats.planning_time_s * 1e3,
        r.stats.edges_accepted,
        r.stats.edges_checked,
        r.pieces.last().map_or(t, |p| p.t1),
        match p {
            Some(p) if p.reached_goal => "reaches the goal".to_string(),
            Some(p) => format!("{:.2} from the goal at its end", p.remaining_distance),
            None => String::new(),
        }
    );
}

/// The radius of a pedestrian's Δ-contour `tau` seconds after its prediction, for the
/// robot's centre: the largest body radius, the robot's radius and κ·√s(τ) (the
/// Gaussian tail bound's sure region, `contour::tail`).
fn delta_radius(p: &CrowdParams, a: &CrowdArgs, tau: f64) -> f64 {
    let k = riskplan_math::contour::tail::tail_kappa(
        2,
        &num_rational::BigRational::from_float(a.delta).unwrap_or_default(),
    )
    .unwrap_or(0.0);
    p.radius.1 + a.robot_radius + k * (p.position_std.powi(2) + (p.velocity_std * tau).powi(2)).sqrt()
}

/// Height of the caption band above the corridor in the animation, pixels.
const CAPTION_BAND: f64 = 36.0;

/// An animated SVG of the frames, one frame per [`STEP`], looping: each pedestrian (grey
/// disk, its true position and radius now) with its Δ-contour for the robot's centre
/// [`CONTOUR_AHEAD`] seconds ahead (dashed red circle around its predicted centre then);
/// the robot (blue disk, its body) and its current plan (blue line); the goal (green).
/// The first frame is visible without animation (SMIL hides it after its step), so
/// static renderers show it; every other frame is hidden except during its step.
fn animation(frames: &[Frame], pedestrians: usize, delta: f64, robot_radius: f64) -> String {
    let (lo, hi) = crowd::bounds();
    let scale = 50.0;
    let (w, h) = ((hi[0] - lo[0]) * scale, (hi[1] - lo[1]) * scale);
    let total_h = h + CAPTION_BAND;
    let px = |p: [f64; 2]| ((p[0] - lo[0]) * scale, (hi[1] - p[1]) * scale);
    let dur = frames.len() as f64 * STEP;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{total_h}\" viewBox=\"0 0 {w} {total_h}\">\n\
         <title>riskplan sim crowd: a robot crossing a corridor among pedestrians</title>\n\
         <rect width=\"{w}\" height=\"{total_h}\" fill=\"#fff\"/>\n\
         <text x=\"8\" y=\"14\" font-family=\"sans-serif\" font-size=\"11\">riskplan sim crowd: {pedestrians} pedestrians, Δ = {delta}, robot radius {robot_radius}. \
         Blue: the robot and its plan; green: the goal; grey: the pedestrians now.</text>\n\
         <text x=\"8\" y=\"29\" font-family=\"sans-serif\" font-size=\"11\">Dashed red: each pedestrian's Δ-contour {CONTOUR_AHEAD} s ahead \
         (around its predicted centre then; for the robot's centre).</text>\n\
         <clipPath id=\"corridor\"><rect width=\"{w}\" height=\"{h}\"/></clipPath>\n\
         <g transform=\"translate(0,{CAPTION_BAND})\" clip-path=\"url(#corridor)\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"#fafafa\" stroke=\"#333\"/>\n"
    );
    let (_, goal) = crowd::start_goal();
    let g = px(goal);
    s += &format!(
        "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"6\" fill=\"none\" stroke=\"green\" stroke-width=\"2\"/>\n",
        g.0, g.1
    );
    for (k, f) in frames.iter().enumerate() {
        let begin = k as f64 * STEP;
        if k == 0 {
            // visible by default; hidden from the end of its step to the end of the loop
            s += "<g id=\"frame-0\">";
            if frames.len() > 1 {
                s += &format!(
                    "<set attributeName=\"visibility\" to=\"hidden\" begin=\"{STEP:.1}s;loop.end+{STEP:.1}s\" dur=\"{:.1}s\"/>",
                    dur - STEP
                );
            }
            s += "\n";
        } else {
            s += &format!(
                "<g id=\"frame-{k}\" visibility=\"hidden\"><set attributeName=\"visibility\" to=\"visible\" begin=\"{begin:.1}s;loop.end+{begin:.1}s\" dur=\"{STEP}s\"/>\n"
            );
        }
        for p in &f.walkers {
            let (c, e) = (px(p.x), px(p.ahead));
            s += &format!("<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{:.1}\" fill=\"#999\"/>", c.0, c.1, p.radius * scale);
            s += &format!(
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{:.1}\" fill=\"none\" stroke=\"#c33\" stroke-dasharray=\"3 3\"/>\n",
                e.0,
                e.1,
                p.delta_radius * scale
            );
        }
        if f.plan.len() > 1 {
            let pts: Vec<String> = f.plan.iter().map(|p| px(*p)).map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
            s += &format!(
                "<polyline points=\"{}\" fill=\"none\" stroke=\"#1f5fbf\" stroke-width=\"2\"/>\n",
                pts.join(" ")
            );
        }
        let r = px(f.robot);
        s += &format!(
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{:.1}\" fill=\"#1f5fbf\" fill-opacity=\"0.8\"/>\n</g>\n",
            r.0,
            r.1,
            robot_radius * scale
        );
    }
    s += &format!(
        "</g>\n<rect width=\"0\" height=\"0\"><animate id=\"loop\" attributeName=\"width\" from=\"0\" to=\"0\" begin=\"0s;loop.end\" dur=\"{dur:.1}s\"/></rect>\n</svg>\n"
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(k: usize) -> Frame {
        let s = k as f64 * 0.1;
        Frame {
            robot: [-7.0 + s, 0.0],
            plan: vec![[-7.0 + s, 0.0], [0.0, 0.0]],
            walkers: vec![FrameWalker { x: [s, 1.0], radius: 0.25, ahead: [s + 1.0, 1.0], delta_radius: 0.7 }],
        }
    }

    /// The first frame's group is visible without SMIL (a `<set>` hides it after its
    /// step, each loop); every later frame is hidden until its own `<set>` shows it.
    #[test]
    fn first_animation_frame_is_visible_without_smil() {
        let svg = animation(&[frame(0), frame(1), frame(2)], 1, 0.01, 0.25);
        let groups: Vec<&str> = svg
            .split("<g")
            .skip(1)
            .filter(|g| !g.starts_with(" transform"))
            .map(|g| &g[..g.find('>').unwrap()])
            .collect();
        assert_eq!(groups.len(), 3, "{svg}");
        assert!(!groups[0].contains("visibility=\"hidden\""), "frame 0: <g{}>", groups[0]);
        assert!(svg.contains("to=\"hidden\" begin=\"0.1s;loop.end+0.1s\" dur=\"0.2s\""), "{svg}");
        for (k, g) in groups.iter().enumerate().skip(1) {
            assert!(g.contains("visibility=\"hidden\""), "frame {k}: <g{g}>");
            assert!(svg.contains(&format!("to=\"visible\" begin=\"0.{k}s;loop.end+0.{k}s\"")), "frame {k}");
        }
    }

    /// The dashed contour is drawn around the predicted centre ahead, the grey disk at
    /// the pedestrian's position now.
    #[test]
    fn contours_are_drawn_at_the_predicted_centre_ahead() {
        let svg = animation(&[frame(0)], 1, 0.01, 0.25);
        let (lo, hi) = crowd::bounds();
        let px = |p: [f64; 2]| format!("cx=\"{:.1}\" cy=\"{:.1}\"", (p[0] - lo[0]) * 50.0, (hi[1] - p[1]) * 50.0);
        assert!(svg.contains(&format!("<circle {} r=\"12.5\" fill=\"#999\"/>", px([0.0, 1.0]))), "{svg}");
        assert!(svg.contains(&format!("<circle {} r=\"35.0\" fill=\"none\" stroke=\"#c33\"", px([1.0, 1.0]))), "{svg}");
    }
}
