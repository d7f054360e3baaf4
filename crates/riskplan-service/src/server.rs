//! The Zenoh server, wired from its parts: one queryable on `riskplan/**` (a
//! replica: the read keys) answering queries by [`Route`](super::routes::Route)
//! (`queries.rs`), one subscriber on `riskplan/scenes/**` for puts and deletes
//! (`puts.rs`), replication between a primary and its replicas (`replication.rs`), a
//! bounded blocking job pool for computation (`jobs.rs`), start-up, readiness and
//! clean shutdown on SIGINT/SIGTERM (`startup.rs`), and with `--metrics` the Prometheus
//! metrics (`metrics.rs`) and their HTTP endpoint (`metrics_http.rs`).

use super::jobs::{Cancels, Jobs};
use super::metrics::{Metrics, DROPPED, PUT};
use super::metrics_http;
use super::proto::Role;
use super::puts::{spawn_put_worker, PUT_QUEUE};
use super::registry::Registry;
use super::replication::{spawn_publisher, spawn_sync};
use super::routes::{REPLICATED_COMMITS, SCENE_UPDATES};
use super::startup::{declare, early_keys, load_scenes, serve_queries, serve_when_ready};
use super::state::State;
use super::store::Store;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tracing::{info, warn};

pub use super::startup::shutdown_signal;

/// Server settings (from `riskplan serve` flags).
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// The Zenoh configuration.
    pub zenoh: zenoh::Config,
    /// Data directory (scenes are persisted under it).
    pub data: PathBuf,
    /// Scene files to load at start (name = file stem), unless already stored.
    pub preload: Vec<PathBuf>,
    /// Blocking worker threads.
    pub workers: usize,
    /// Jobs that may wait for a worker before `busy`.
    pub queue: usize,
    /// Cap on a plan's time limit, seconds.
    pub max_plan_seconds: f64,
    /// Cap (and default) of the deadline of apply, verify and risk jobs, seconds.
    pub max_job_seconds: f64,
    /// Endpoints printed in the ready line.
    pub listen: Vec<String>,
    /// Run as a replica: answer reads only, following the primary's revisions
    /// (deploy/cluster/README.md). Otherwise the server is a primary: it takes
    /// writes and publishes its commits for replicas.
    pub replica: bool,
    /// The server's id (`None`: a random one): its liveliness token and own keys
    /// (proto/README.md, "Discovery").
    pub server_id: Option<String>,
    /// Serve Prometheus metrics over HTTP on this address (`GET /metrics`; proto/README.md
    /// "Metrics"); `None`: no metrics, no listener.
    pub metrics: Option<SocketAddr>,
    /// Build a committed scene's covers, final-check box tests and whole-path reaches in
    /// the background when a worker is idle (docs/design.md §3.11, "Warm-ups"); `false`: each is built
    /// by the first request that needs it.
    pub warm_up: bool,
}

/// The error of a session that did not open, said for its user: an endpoint that is taken
/// names the flag to choose another, and Zenoh's source locations (`… at /path/x.rs:61.`)
/// are left out.
fn session_error(text: &str) -> String {
    let plain = super::error::strip_source_locations(text);
    if plain.contains("Address already in use") {
        // "… bound to tcp/127.0.0.1:7447: [127.0.0.1:7447: Address already in use (os error 98)]"
        let endpoint = plain.split("bound to ").nth(1).and_then(|r| r.split(": [").next()).unwrap_or("the endpoint");
        return format!(
            "cannot listen on {endpoint}: the address is in use (another `riskplan serve`, or another program, \
             listens there): stop it, or listen elsewhere with --listen (e.g. --listen tcp/127.0.0.1:7448)"
        );
    }
    format!("cannot open the Zenoh session: {plain}")
}

/// Runs the server until SIGINT or SIGTERM.
pub async fn serve(cfg: ServerConfig) -> Result<(), String> {
    let store = Store::open(&cfg.data).map_err(|e| format!("--data {}: {e}", cfg.data.display()))?;
    // the metrics' listener first: an address that cannot be listened on stops the start
    let scrapes = match cfg.metrics {
        Some(addr) => Some(metrics_http::bind(addr).await.map_err(|e| e.to_string())?),
        None => None,
    };
    let server_id = match &cfg.server_id {
        Some(id) if super::routes::valid_server_id(id) => id.clone(),
        Some(id) => return Err(format!("--server-id '{id}': use 1 to 64 characters from 0-9 a-z A-Z _ -")),
        None => format!("{:016x}", rand::random::<u64>()),
    };
    let role = if cfg.replica { Role::Replica } else { Role::Primary };
    let metrics = scrapes.as_ref().map(|_| Arc::new(Metrics::new(role, &server_id)));
    let state = Arc::new(State {
        registry: Registry::new(store),
        jobs: Jobs::new(cfg.workers.max(1), cfg.queue),
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        started: Instant::now(),
        counters: Mutex::new(BTreeMap::new()),
        max_plan_seconds: Duration::try_from_secs_f64(cfg.max_plan_seconds)
            .map_err(|e| format!("--max-plan-seconds {}: {e}", cfg.max_plan_seconds))?,
        max_job_seconds: Duration::try_from_secs_f64(cfg.max_job_seconds)
            .map_err(|e| format!("--max-job-seconds {}: {e}", cfg.max_job_seconds))?,
        cancels: Cancels::default(),
        ready: AtomicBool::new(false),
        loaded: AtomicBool::new(false),
        primary_id: Mutex::new(None),
        replica: cfg.replica,
        server_id,
        revision_waiters: std::sync::atomic::AtomicUsize::new(0),
        metrics: metrics.clone(),
        warm_up: cfg.warm_up,
        warming: AtomicBool::new(false),
        warm_queue: Mutex::new(Vec::new()),
    });
    // Scrapes read the state through a weak reference (the state holds the metrics),
    // on their own tasks: the loops below never wait for them.
    let mut scraper = None;
    if let (Some(m), Some((listener, local))) = (metrics, scrapes) {
        let weak = Arc::downgrade(&state);
        m.set_sampler(move || weak.upgrade().map(|st| st.snapshot()));
        scraper = Some(metrics_http::spawn(listener, m));
        eprintln!("riskplan: metrics on http://{local}{}", metrics_http::PATH);
        info!(%local, "metrics endpoint");
    }
    let session = zenoh::open(cfg.zenoh.clone()).await.map_err(|e| session_error(&e.to_string()))?;
    // Complete queryables: with several servers behind a router, a query goes to one
    // of them (Zenoh's BestMatching), never to all. Only `status` and `echo` are
    // declared now; the rest once the stored scenes are in (see `serve_when_ready`),
    // so that a loading server takes no work: in a cluster another one does, and
    // clients repeat reads that no server took.
    let mut early = Vec::new();
    for k in early_keys() {
        early.push(declare(&session, k).await?);
    }
    // a primary receives clients' puts; a replica its primary's commits
    let sub_key = if cfg.replica { REPLICATED_COMMITS } else { SCENE_UPDATES };
    let subscriber =
        session.declare_subscriber(sub_key).await.map_err(|e| format!("cannot declare the subscriber: {e}"))?;
    eprintln!(
        "riskplan: listening on {} ({} workers, queue {}{}); loading stored scenes",
        cfg.listen.join(", "),
        cfg.workers,
        cfg.queue,
        if cfg.replica { ", replica" } else { "" }
    );
    info!(listen = %cfg.listen.join(","), replica = cfg.replica, "listening");
    if !cfg.replica {
        spawn_publisher(&state, session.clone());
    }
    // Loading runs on a blocking thread while the queries below are answered:
    // `status` ("loading") and `echo`; other requests get `unavailable` until it is
    // done, and puts wait in the put worker's queue. A replica is ready after its
    // first catch-up with the primary (or the first attempt, when none answers).
    let loading = {
        let st = state.clone();
        let preload = cfg.preload.clone();
        let replica = cfg.replica;
        tokio::task::spawn_blocking(move || {
            load_scenes(&st.registry, if replica { &[] } else { &preload });
            st.loaded.store(true, Ordering::SeqCst);
            if !replica {
                st.ready.store(true, Ordering::SeqCst);
            }
            // (on its own thread: the put worker waits for this task)
            super::warm::after_load(&st);
        })
    };
    let puts = spawn_put_worker(state.clone(), loading);
    if cfg.replica {
        spawn_sync(state.clone(), session.clone());
    }
    let mut tasks: Vec<tokio::task::JoinHandle<()>> =
        early.into_iter().map(|q| tokio::spawn(serve_queries(state.clone(), q, false))).collect();
    tasks.push(tokio::spawn(serve_when_ready(state.clone(), session.clone())));
    let shutdown = shutdown_signal();
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            _ = &mut shutdown => break,
            s = subscriber.recv_async() => match s {
                Ok(sample) => {
                    let key = sample.key_expr().as_str().to_string();
                    let arrived = Instant::now();
                    let put = (key, sample.kind(), sample.payload().to_bytes().into_owned(), arrived);
                    // Never wait here: the put worker applies puts in arrival order; when
                    // its queue is full the put is dropped (puts have no reply) and counted.
                    if let Err(e) = puts.try_send(put) {
                        state.count("put", false);
                        state.record(PUT, DROPPED, arrived.elapsed());
                        warn!(key = %e.into_inner().0, "put dropped: {PUT_QUEUE} puts are already waiting");
                    }
                }
                Err(_) => break,
            },
        }
    }
    for t in tasks.iter().chain(&scraper) {
        t.abort();
    }
    let cancelled = state.cancels.cancel_all();
    info!(cancelled, "shutting down");
    let _ = session.close().await;
    Ok(())
}
