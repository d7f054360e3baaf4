//! `riskplan client ...`: talk to a running `riskplan serve`.

use super::util::{print_out, write_json, CliError};
use clap::{Args, Subcommand};
use riskplan_service::proto::*;
use riskplan_service::{Client, ClientError, Route};
use std::path::PathBuf;
use std::time::Duration;

/// The endpoint of `riskplan client` without --endpoint or --config.
const DEFAULT_ENDPOINT: &str = "tcp/127.0.0.1:7447";

/// Talk to a running server: put scenes, apply updates, plan, verify, query risk.
#[derive(Args, Debug)]
pub struct ClientArgs {
    /// The server's endpoint (default tcp/127.0.0.1:7447; with --config, replaces the
    /// configuration's connect endpoints).
    #[arg(long, global = true)]
    endpoint: Option<String>,
    /// A Zenoh JSON5 client configuration, e.g. a role's configuration of the secure
    /// deployment (deploy/secure: TLS, user and password).
    #[arg(long, global = true)]
    config: Option<PathBuf>,
    /// Query timeout in seconds (a plan adds its own time limit).
    #[arg(long, default_value_t = 30.0, global = true)]
    timeout: f64,
    /// Speak JSON instead of bincode.
    #[arg(long, global = true)]
    json: bool,
    /// Reads ask for at least this revision of their scene (e.g. the one an `apply`
    /// acknowledged): a server behind its primary waits up to 1.5 s for it, else answers
    /// `stale_revision` (proto/README.md, "Discovery and load sharing").
    #[arg(long, global = true)]
    min_revision: Option<u64>,
    #[command(subcommand)]
    command: ClientCommand,
}

#[derive(Subcommand, Debug)]
enum ClientCommand {
    /// Put a whole scene file (fire and forget; prefer `apply` for an acknowledgement).
    Put {
        /// Scene name on the server.
        #[arg(long)]
        scene: String,
        /// Scene file (format v1).
        #[arg(long)]
        file: PathBuf,
    },
    /// Acknowledged update: a whole scene (--file) or obstacle changes (--changes, a JSON list).
    Apply {
        /// Scene name on the server.
        #[arg(long)]
        scene: String,
        /// Scene file (format v1).
        #[arg(long, conflicts_with = "changes")]
        file: Option<PathBuf>,
        /// JSON file with a list of changes [{"op": "put", "id", "poly", "params"?} | {"op": "delete", "id"}].
        #[arg(long)]
        changes: Option<PathBuf>,
    },
    /// Plan on a scene; prints the trajectory.
    Plan {
        /// Scene name on the server.
        #[arg(long)]
        scene: String,
        /// rrt-sos (default), rrt-sos-paper, mc-rrt, tv-sos, moment or moment-poly.
        #[arg(long, default_value = "rrt-sos")]
        planner: String,
        /// Time limit, seconds.
        #[arg(long, default_value_t = 10.0)]
        time_limit: f64,
        /// Seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Pieces (layered planner).
        #[arg(long)]
        pieces: Option<u64>,
        /// Improve step (rrt-sos-paper on static scenes).
        #[arg(long)]
        improve: bool,
        /// Speed limit (default: the scene's planner.max_speed).
        #[arg(long)]
        max_speed: Option<f64>,
        /// Acceleration limit of the corner blends (default: the scene's planner.max_accel).
        #[arg(long)]
        max_accel: Option<f64>,
        /// Return the raw tree path (no shortcut, no blends).
        #[arg(long)]
        no_smooth: bool,
        /// per-obstacle (default), joint, joint-weighted or trajectory (any obstacle at any
        /// time along the plan).
        #[arg(long)]
        risk_mode: Option<String>,
        /// Write the trajectory here instead of stdout.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Verify a trajectory file or a segment (--from ... --to ...). Exit 1 when not safe.
    Verify {
        /// Scene name on the server.
        #[arg(long)]
        scene: String,
        /// Trajectory file.
        #[arg(long)]
        trajectory: Option<PathBuf>,
        /// Segment start.
        #[arg(long, num_args = 1.., allow_negative_numbers = true)]
        from: Vec<f64>,
        /// Segment end.
        #[arg(long, num_args = 1.., allow_negative_numbers = true)]
        to: Vec<f64>,
        /// exact, sos or both.
        #[arg(long)]
        method: Option<String>,
        /// Only the first piece not proven safe is reported (with the counts); no report
        /// is built for the others.
        #[arg(long)]
        summary: bool,
    },
    /// Risk bound at a point.
    Risk {
        /// Scene name on the server.
        #[arg(long)]
        scene: String,
        /// The point.
        #[arg(long, num_args = 1.., allow_negative_numbers = true, required = true)]
        point: Vec<f64>,
        /// Time.
        #[arg(long)]
        time: Option<f64>,
    },
    /// The scene and its revision.
    Get {
        /// Scene name on the server.
        #[arg(long)]
        scene: String,
    },
    /// Server status.
    Status,
    /// Load benchmark: N concurrent clients send verify queries (or, with --bare, empty
    /// queries to the server's echo key: the bare Zenoh round trip) for S seconds;
    /// prints throughput, latency percentiles and how many replies each query got.
    Load {
        /// Scene name (verify target).
        #[arg(long, default_value = "illustrative-3")]
        scene: String,
        /// Concurrent clients.
        #[arg(long, default_value_t = 16)]
        clients: usize,
        /// Duration, seconds.
        #[arg(long, default_value_t = 30.0)]
        seconds: f64,
        /// Query riskplan/echo instead (no work): the bare round trip.
        #[arg(long, conflicts_with = "mix")]
        bare: bool,
        /// A mixed workload on the scene instead: in every ten queries of a client, one
        /// plan (time limit 1 s), five verifies, three risk queries (16 points) and one
        /// apply (replacing that client's own tiny obstacle in a corner); prints
        /// latencies and outcomes per kind.
        #[arg(long)]
        mix: bool,
    },
}

fn read_json(p: &PathBuf) -> Result<serde_json::Value, CliError> {
    let t = std::fs::read_to_string(p).map_err(|e| CliError(format!("{}: cannot read: {e}", p.display())))?;
    serde_json::from_str(&t).map_err(|e| CliError(format!("{}: {e}", p.display())))
}

/// A scene file to send: checked here first as `riskplan plan` would load it, so that
/// its errors name the line and column in the file (the server sees the parsed value and
/// can name only the field); then as the JSON value sent.
fn read_scene_json(p: &PathBuf) -> Result<serde_json::Value, CliError> {
    super::util::load_scene(p)?;
    read_json(p)
}

fn show<T: serde::Serialize>(v: &T) -> Result<(), CliError> {
    write_json(v, true)
}

pub fn run(a: ClientArgs) -> Result<i32, CliError> {
    let rt = super::util::client_runtime()?;
    rt.block_on(async move {
        let codec = if a.json { Codec::Json } else { Codec::Bincode };
        let timeout = Duration::from_secs_f64(a.timeout.max(0.1));
        let client = match &a.config {
            None => Client::connect(a.endpoint.as_deref().unwrap_or(DEFAULT_ENDPOINT), timeout, codec).await,
            Some(path) => {
                let mut cfg = zenoh::Config::from_file(path)
                    .map_err(|e| CliError(format!("--config {}: {e}", path.display())))?;
                if let Some(ep) = &a.endpoint {
                    cfg.insert_json5("connect/endpoints", &serde_json::to_string(&[ep]).unwrap_or_default())
                        .map_err(|e| CliError(format!("--endpoint {ep}: {e}")))?;
                }
                Client::connect_with(cfg, timeout, codec).await
            }
        }
        .map_err(err)?;
        let client = match a.min_revision {
            Some(r) => client.at_least_everywhere(r),
            None => client,
        };
        let code = exec(&client, a.command).await;
        client.close().await;
        code
    })
}

fn err(e: ClientError) -> CliError {
    CliError(e.to_string())
}

async fn exec(client: &Client, cmd: ClientCommand) -> Result<i32, CliError> {
    match cmd {
        ClientCommand::Put { scene, file } => {
            client.put_scene(&scene, &read_scene_json(&file)?).await.map_err(err)?;
            let key = Route::Scene { name: scene };
            eprintln!("put {key} (not acknowledged; use `client apply` to wait for persistence)");
            Ok(0)
        }
        ClientCommand::Apply { scene, file, changes } => {
            let req = match (file, changes) {
                (Some(f), None) => {
                    ApplyRequest { scene: Some(EmbeddedJson(read_scene_json(&f)?)), ..Default::default() }
                }
                (None, Some(c)) => {
                    let ch: Vec<Change> = serde_json::from_value(read_json(&c)?)
                        .map_err(|e| CliError(format!("{}: {e}", c.display())))?;
                    ApplyRequest { changes: Some(ch), ..Default::default() }
                }
                _ => return Err(CliError("give --file or --changes".into())),
            };
            show(&client.apply(&scene, &req).await.map_err(err)?)?;
            Ok(0)
        }
        ClientCommand::Plan {
            scene,
            planner,
            time_limit,
            seed,
            pieces,
            improve,
            max_speed,
            max_accel,
            no_smooth,
            risk_mode,
            out,
        } => {
            if let Some(p) = &out {
                super::plan_cmd::writable("--out", p)?;
            }
            // the names go to the server as typed: it answers a name it does not know
            // (`invalid_request`, naming the field)
            let req = PlanRequest {
                planner: Some(Named::parse(&planner)),
                time_limit: Some(time_limit),
                seed: Some(seed),
                pieces,
                improve: Some(improve),
                max_speed,
                max_accel,
                smooth: Some(!no_smooth),
                risk_mode: risk_mode.as_deref().map(Named::parse),
                ..Default::default()
            };
            match client.plan(&scene, &req).await {
                Ok(r) => {
                    eprintln!(
                        "{}: plan ({}) at revision {}, {} pieces, {:.3} s",
                        r.planner,
                        if r.certified { "certified" } else { "NOT certified" },
                        r.revision,
                        r.pieces.len(),
                        r.stats.planning_time_s
                    );
                    let text = serde_json::to_string_pretty(&r).map_err(|e| CliError(e.to_string()))?;
                    match out {
                        Some(p) => {
                            std::fs::write(&p, text + "\n").map_err(|e| CliError(format!("{}: {e}", p.display())))?
                        }
                        None => print_out(&text)?,
                    }
                    Ok(0)
                }
                Err(ClientError::Server(e)) if e.code == ErrorCode::NoPlan => {
                    eprintln!("no_plan: {}", e.message);
                    Ok(1)
                }
                Err(e) => Err(err(e)),
            }
        }
        ClientCommand::Verify { scene, trajectory, from, to, method, summary } => {
            let mut req = VerifyRequest {
                method: method.as_deref().map(Named::parse),
                summary: summary.then_some(true),
                ..Default::default()
            };
            match trajectory {
                Some(p) => {
                    let text = std::fs::read_to_string(&p)
                        .map_err(|e| CliError(format!("{}: cannot read: {e}", p.display())))?;
                    req.trajectory = Some(
                        riskplan_scene::Trajectory::from_json(&text)
                            .map_err(|e| CliError(format!("{}: {e}", p.display())))?,
                    )
                }
                None if !from.is_empty() && !to.is_empty() => {
                    req.segment = Some(Segment { from, to, t0: None, t1: None })
                }
                None => return Err(CliError("give --trajectory or --from ... --to ...".into())),
            }
            let r = client.verify(&scene, &req).await.map_err(err)?;
            show(&r)?;
            Ok(if r.safe { 0 } else { 1 })
        }
        ClientCommand::Risk { scene, point, time } => {
            show(
                &client
                    .risk(&scene, &RiskRequest { points: Some(vec![point]), time, ..Default::default() })
                    .await
                    .map_err(err)?,
            )?;
            Ok(0)
        }
        ClientCommand::Get { scene } => {
            show(&client.get_scene(&scene).await.map_err(err)?)?;
            Ok(0)
        }
        ClientCommand::Status => {
            show(&client.status().await.map_err(err)?)?;
            Ok(0)
        }
        ClientCommand::Load { scene, clients, seconds, bare, mix } => {
            load(client, &scene, clients, seconds, bare, mix).await
        }
    }
}

/// Per kind of query: latencies (s), outcomes (ok or error code), replies per query.
type LoadStats = (Vec<f64>, std::collections::BTreeMap<String, u64>, std::collections::BTreeMap<usize, u64>);

/// The queries of one load client: (kind, route, payload), cycled through. Their
/// geometry is derived from the scene's workspace box `(lower, upper)` (no absolute
/// lengths): a verify segment along the lower edge, sixteen risk points across the
/// box, and the client's own tiny disk (radius 0.25 % of the box) near the corner
/// (upper x₁, lower x₂), away from the paths between opposite corners.
fn load_queries(
    client: &Client,
    scene: &str,
    ws: &(Vec<f64>, Vec<f64>),
    id: usize,
    bare: bool,
    mix: bool,
) -> Vec<(&'static str, Route, Vec<u8>)> {
    let (lo, hi) = ws;
    // a point of the box at shares `u` of its sides (the other coordinates at mid-box)
    let at = |u: &[f64]| -> Vec<f64> {
        (0..lo.len()).map(|d| lo[d] + (hi[d] - lo[d]) * u.get(d).copied().unwrap_or(0.5)).collect()
    };
    let verify = VerifyRequest {
        segment: Some(Segment { from: at(&[0.0, 0.05]), to: at(&[1.0, 0.25]), t0: None, t1: None }),
        ..Default::default()
    };
    let scene = || scene.to_string();
    // each query is counted under its route's kind: echo, plan, verify, risk, apply
    let query = |route: Route, payload: Vec<u8>| (route.kind().label(), route, payload);
    if bare {
        return vec![query(Route::Echo, client.encode(&"ping"))];
    }
    let v = query(Route::Verify { scene: scene() }, client.encode(&verify));
    if !mix {
        return vec![v];
    }
    let plan = PlanRequest { time_limit: Some(1.0), seed: Some(id as u64), ..Default::default() };
    let points: Vec<Vec<f64>> = (0..16).map(|k| at(&[0.05 + 0.05 * k as f64, 0.65])).collect();
    let risk = RiskRequest { points: Some(points), ..Default::default() };
    let shift = 0.0005 * (id % 50) as f64;
    let c = at(&[0.95 + shift, 0.05 - shift]);
    let w = (hi[0] - lo[0]).min(hi.get(1).copied().unwrap_or(hi[0]) - lo.get(1).copied().unwrap_or(lo[0]));
    let r2 = (0.0025 * w).powi(2);
    let terms: Vec<String> = c.iter().enumerate().map(|(d, cd)| format!(" - (x{} - ({cd:e}))^2", d + 1)).collect();
    let apply = ApplyRequest {
        changes: Some(vec![Change {
            op: ChangeOp::Put.into(),
            id: format!("load-{id}"),
            poly: Some(format!("{r2:e}{}", terms.join(""))),
            params: None,
            pedestrian: None,
        }]),
        ..Default::default()
    };
    let p = query(Route::Plan { scene: scene() }, client.encode(&plan));
    let r = query(Route::Risk { scene: scene() }, client.encode(&risk));
    let a = query(Route::Apply { scene: scene() }, client.encode(&apply));
    vec![p, v.clone(), r.clone(), v.clone(), r.clone(), v.clone(), a, v.clone(), r, v]
}

/// The workspace box of `scene` (from the server), for the load's queries; the box
/// [-1, 1]² for `--bare`, which sends no geometry.
async fn load_workspace(client: &Client, scene: &str, bare: bool) -> Result<(Vec<f64>, Vec<f64>), CliError> {
    if bare {
        return Ok((vec![-1.0, -1.0], vec![1.0, 1.0]));
    }
    let s = client.get_scene(scene).await.map_err(|e| CliError(format!("scene '{scene}': {e}")))?;
    let side = |k: &str| -> Option<Vec<f64>> {
        s.scene.0.get("workspace")?.get(k)?.as_array()?.iter().map(|v| v.as_f64()).collect()
    };
    match (side("lower"), side("upper")) {
        (Some(lo), Some(hi)) if !lo.is_empty() && lo.len() == hi.len() => Ok((lo, hi)),
        _ => Err(CliError(format!("scene '{scene}' has no readable workspace box"))),
    }
}

async fn load(
    client: &Client,
    scene: &str,
    clients: usize,
    seconds: f64,
    bare: bool,
    mix: bool,
) -> Result<i32, CliError> {
    use std::collections::BTreeMap;
    use std::time::Instant;
    let ws = load_workspace(client, scene, bare).await?;
    let deadline = Instant::now() + Duration::from_secs_f64(seconds.max(0.1));
    let started = Instant::now();
    let mut tasks = Vec::new();
    for id in 0..clients.max(1) {
        let queries = load_queries(client, scene, &ws, id, bare, mix);
        let c = client.clone();
        tasks.push(tokio::spawn(async move {
            let mut stats: BTreeMap<&'static str, LoadStats> = BTreeMap::new();
            let mut k = id; // clients start at different points of the cycle
            while Instant::now() < deadline {
                let (kind, route, payload) = &queries[k % queries.len()];
                k += 1;
                let t = Instant::now();
                let r = c.raw_query(route, payload.clone()).await;
                let e = stats.entry(kind).or_default();
                e.0.push(t.elapsed().as_secs_f64());
                let (n, code) = match r {
                    Ok(v) => v,
                    Err(e) => (0, Some(format!("client error: {e}"))),
                };
                *e.2.entry(n).or_default() += 1;
                *e.1.entry(code.unwrap_or_else(|| "ok".into())).or_default() += 1;
            }
            stats
        }));
    }
    let mut merged: BTreeMap<&'static str, LoadStats> = BTreeMap::new();
    for t in tasks {
        for (kind, (l, o, c)) in t.await.map_err(|e| CliError(format!("load task failed: {e}")))? {
            let m = merged.entry(kind).or_default();
            m.0.extend(l);
            for (k, v) in o {
                *m.1.entry(k).or_default() += v;
            }
            for (k, v) in c {
                *m.2.entry(k).or_default() += v;
            }
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    // the requests each live server has answered since it started (its status, on its own key)
    let mut per_server = serde_json::Map::new();
    for id in client.servers() {
        if let Ok(st) = client.status_of(&id).await {
            let served: u64 = st.requests.values().map(|c| c.served + c.failed).sum();
            per_server.insert(id, serde_json::json!({"role": st.role, "requests": served}));
        }
    }
    let summary = |lat: &mut Vec<f64>| {
        lat.sort_by(f64::total_cmp);
        let pct = |p: f64| lat.get(((lat.len() as f64 - 1.0) * p).round() as usize).copied().unwrap_or(f64::NAN) * 1e3;
        serde_json::json!({"p50": pct(0.5), "p90": pct(0.9), "p99": pct(0.99), "max": pct(1.0)})
    };
    let mut all_lat = Vec::new();
    let mut outcomes: BTreeMap<String, u64> = BTreeMap::new();
    let mut counts: BTreeMap<usize, u64> = BTreeMap::new();
    let mut kinds = serde_json::Map::new();
    for (kind, (mut l, o, c)) in merged {
        all_lat.extend_from_slice(&l);
        for (k, v) in &o {
            *outcomes.entry(k.clone()).or_default() += v;
        }
        for (k, v) in &c {
            *counts.entry(*k).or_default() += v;
        }
        kinds.insert(
            kind.to_string(),
            serde_json::json!({
                "queries": l.len(), "latency_ms": summary(&mut l), "outcomes": o,
                "replies_per_query": c.iter().map(|(k, v)| (k.to_string(), *v)).collect::<BTreeMap<_, _>>(),
            }),
        );
    }
    let out = serde_json::json!({
        "scene": scene, "clients": clients, "seconds": elapsed, "queries": all_lat.len(),
        "throughput_qps": all_lat.len() as f64 / elapsed,
        "latency_ms": summary(&mut all_lat),
        "outcomes": outcomes,
        "replies_per_query": counts.iter().map(|(k, v)| (k.to_string(), *v)).collect::<BTreeMap<_, _>>(),
        "kinds": kinds,
        "servers": per_server,
    });
    show(&out)?;
    // every query exactly one reply from a server: a local timeout (code "timeout")
    // or a client error is not one
    let unanswered = outcomes.keys().any(|k| k == "timeout" || k.starts_with("client error"));
    Ok(if counts.keys().all(|&k| k == 1) && !unanswered { 0 } else { 1 })
}
