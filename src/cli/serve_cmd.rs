//! `riskplan serve`: the Zenoh planning service (the main job).

use super::util::CliError;
use clap::Args;
use riskplan_service::{serve, ServerConfig};
use std::path::PathBuf;
use std::time::Duration;

/// How long shutdown waits for jobs still running after their plans were cancelled.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(1);

/// Run the planning service over Zenoh (see proto/README.md for the protocol).
///
/// By default a Zenoh peer listens on tcp/127.0.0.1:7447 with multicast scouting off,
/// and scenes are persisted under --data. Queries (apply, plan, verify, risk, status)
/// are answered concurrently; certification and planning run on a bounded pool of
/// --workers threads, and a query that finds --queue jobs already waiting is answered
/// at once with the error "busy". Stops cleanly on SIGINT or SIGTERM. With --metrics,
/// Prometheus metrics are served over HTTP as well.
#[derive(Args, Debug)]
pub struct ServeArgs {
    /// A Zenoh JSON5 configuration file (the flags below override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Endpoints to listen on (default tcp/127.0.0.1:7447 without --config, none with
    /// --mode client).
    #[arg(long)]
    listen: Vec<String>,
    /// Endpoints to connect to (routers or peers).
    #[arg(long)]
    connect: Vec<String>,
    /// Data directory: acknowledged scene updates are persisted here.
    #[arg(long, default_value = "riskplan-data")]
    data: PathBuf,
    /// Load every *.json scene of this directory at start (name = file stem), unless stored
    /// already. `--preload` alone loads `scenes`: the paper's experiments in the repository.
    #[arg(long, num_args = 0..=1, default_missing_value = "scenes", value_name = "DIR")]
    preload: Option<PathBuf>,
    /// Worker threads for certification and planning (default: the number of cores).
    #[arg(long)]
    workers: Option<usize>,
    /// Jobs that may wait for a worker before queries are answered "busy".
    #[arg(long, default_value_t = 64)]
    queue: usize,
    /// Cap on a plan request's time limit, in seconds (queue time included).
    #[arg(long, default_value_t = 60.0)]
    max_plan_seconds: f64,
    /// Cap and default of the deadline of apply, verify and risk requests (their
    /// `deadline_ms`), in seconds from arrival, queue time included.
    #[arg(long, default_value_t = 60.0)]
    max_job_seconds: f64,
    /// Do not warm scenes in the background. By default, after each commit of a scene of 16
    /// obstacles or more, most of them new (a first upload or a replaced scene, not an update
    /// of a few obstacles), and after the stored scenes are loaded, a thread of its own
    /// (started when a worker is idle) builds its proven covers, the final check's box
    /// tests and the whole-path reaches (on 512 obstacles about 0.8 s), which the first plan
    /// would otherwise build before answering; it takes no worker from the requests.
    #[arg(long)]
    no_warm_up: bool,
    /// Log as JSON lines instead of human-readable text.
    #[arg(long)]
    log_json: bool,
    /// Run as a replica of the primary on the same Zenoh network (deploy/cluster):
    /// answer reads (status, scenes, plan, verify, risk) and follow the primary's
    /// revisions; writes (puts, deletes, apply) go to the primary only.
    #[arg(long)]
    replica: bool,
    /// This server's id among the servers of a cluster (default: random): its
    /// liveliness token `riskplan/_servers/<id>/<role>` and its own keys `riskplan/@<id>/...`,
    /// by which clients spread reads over the live servers (proto/README.md,
    /// "Discovery"). 1 to 64 characters from 0-9 a-z A-Z _ -.
    #[arg(long)]
    server_id: Option<String>,
    /// Zenoh mode: "peer" (default without --config) or "client" (attach to a router
    /// given by --connect, as the servers of deploy/cluster do).
    #[arg(long, value_parser = ["peer", "client"])]
    mode: Option<String>,
    /// Serve Prometheus metrics on this address: GET http://ADDR/metrics answers the
    /// OpenMetrics text exposition, or the Prometheus text format 0.0.4 when the request's
    /// Accept header prefers text/plain (request counts, outcomes and latencies per kind,
    /// queue depth, running jobs, scenes and their revisions, cache hits and misses, build
    /// info; listed in proto/README.md, "Metrics"). An IP and a port, e.g. 127.0.0.1:9464 (port 0:
    /// any free port; the address is printed on stderr). Off by default: no listener. The
    /// endpoint has no authentication: keep it on loopback or a trusted network.
    #[arg(long, value_name = "ADDR")]
    metrics: Option<std::net::SocketAddr>,
}

/// Run a Zenoh router for a cluster of servers and their clients (deploy/cluster):
/// servers (a primary and replicas, `serve --mode client --connect <router>`) and
/// clients connect to it; it routes each query to one server and every put to the
/// primary. It holds no scenes and does no planning. Stops on SIGINT or SIGTERM.
#[derive(Args, Debug)]
pub struct RouterArgs {
    /// A Zenoh JSON5 configuration file (the flags below override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Endpoints to listen on (default tcp/127.0.0.1:7446 without --config).
    #[arg(long)]
    listen: Vec<String>,
}

/// Runs `riskplan router`.
pub fn run_router(a: RouterArgs) -> Result<i32, CliError> {
    init_logging(false);
    let z = |e: zenoh::Error| CliError(format!("zenoh configuration: {e}"));
    let mut cfg = match &a.config {
        Some(p) => zenoh::Config::from_file(p).map_err(|e| CliError(format!("--config {}: {e}", p.display())))?,
        None => {
            let mut c = zenoh::Config::default();
            c.insert_json5("scouting/multicast/enabled", "false").map_err(z)?;
            c
        }
    };
    cfg.insert_json5("mode", r#""router""#).map_err(z)?;
    let listen = if a.listen.is_empty() && a.config.is_none() { vec!["tcp/127.0.0.1:7446".into()] } else { a.listen };
    if !listen.is_empty() {
        cfg.insert_json5("listen/endpoints", &serde_json::to_string(&listen).unwrap_or_default()).map_err(z)?;
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| CliError(e.to_string()))?;
    rt.block_on(async move {
        let session = zenoh::open(cfg).await.map_err(|e| CliError(format!("cannot open the Zenoh router: {e}")))?;
        eprintln!("riskplan: router listening on {}", listen.join(", "));
        riskplan_service::server::shutdown_signal().await;
        let _ = session.close().await;
        Ok::<(), CliError>(())
    })?;
    Ok(0)
}

/// The log filter without `RISKPLAN_LOG`: riskplan at info, Zenoh's warnings — but not the
/// orchestrator's about an endpoint it cannot listen on or connect to, which the server's
/// own error says once, with what to do (its warning would say the same again).
const DEFAULT_LOG_FILTER: &str = "info,zenoh=warn,zenoh::net::runtime::orchestrator=error";

fn init_logging(json: bool) {
    let filter = tracing_subscriber::EnvFilter::try_from_env("RISKPLAN_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(DEFAULT_LOG_FILTER));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr);
    let _ = if json { builder.json().try_init() } else { builder.try_init() };
}

pub fn run(a: ServeArgs) -> Result<i32, CliError> {
    init_logging(a.log_json);
    let z = |e: zenoh::Error| CliError(format!("zenoh configuration: {e}"));
    let mut cfg = match &a.config {
        Some(p) => zenoh::Config::from_file(p).map_err(|e| CliError(format!("--config {}: {e}", p.display())))?,
        None => {
            let mut c = zenoh::Config::default();
            c.insert_json5("mode", r#""peer""#).map_err(z)?;
            c.insert_json5("scouting/multicast/enabled", "false").map_err(z)?;
            c
        }
    };
    // a client-mode server (attached to a router) listens on nothing by default
    let listen = if a.listen.is_empty() && a.config.is_none() && a.mode.as_deref() != Some("client") {
        vec!["tcp/127.0.0.1:7447".to_string()]
    } else {
        a.listen.clone()
    };
    if !listen.is_empty() {
        cfg.insert_json5("listen/endpoints", &serde_json::to_string(&listen).unwrap_or_default()).map_err(z)?;
    }
    if let Some(m) = &a.mode {
        cfg.insert_json5("mode", &format!("{m:?}")).map_err(z)?;
    }
    if !a.connect.is_empty() {
        cfg.insert_json5("connect/endpoints", &serde_json::to_string(&a.connect).unwrap_or_default()).map_err(z)?;
    }
    if !(a.max_plan_seconds > 0.0 && a.max_plan_seconds.is_finite()) {
        return Err(CliError("--max-plan-seconds must be positive".into()));
    }
    if !(a.max_job_seconds > 0.0 && a.max_job_seconds.is_finite()) {
        return Err(CliError("--max-job-seconds must be positive".into()));
    }
    let preload = match &a.preload {
        Some(dir) => {
            let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
                .map_err(|e| CliError(format!("--preload {}: {e}", dir.display())))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "json"))
                .collect();
            v.sort();
            v
        }
        None => vec![],
    };
    let workers = a.workers.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(2));
    let config = ServerConfig {
        zenoh: cfg,
        data: a.data,
        preload,
        workers,
        queue: a.queue,
        max_plan_seconds: a.max_plan_seconds,
        max_job_seconds: a.max_job_seconds,
        warm_up: !a.no_warm_up,
        listen,
        replica: a.replica,
        server_id: a.server_id,
        metrics: a.metrics,
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .max_blocking_threads(workers.max(1) + riskplan_service::WRITE_LANES + 4)
        .build()
        .map_err(|e| CliError(e.to_string()))?;
    let served = rt.block_on(serve(config));
    // Running plans were cancelled at shutdown; do not wait long for a job that is
    // still finishing (a verify in progress): its client is gone with the server.
    rt.shutdown_timeout(SHUTDOWN_GRACE);
    served.map_err(CliError)?;
    Ok(0)
}
