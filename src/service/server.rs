//! The Zenoh server: one queryable on `riskplan/**` dispatching by key, one
//! subscriber on `riskplan/scenes/**` for puts and deletes, a bounded blocking job
//! pool for computation, clean shutdown on SIGINT/SIGTERM.

use super::error::{invalid, ServiceError};
use super::handlers;
use super::proto::*;
use super::registry::{Commit, CommitListener, Registry};
use super::store::{embedded, Store};
use std::collections::BTreeMap;
use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::Semaphore;
use tracing::{info, warn, Instrument};
use zenoh::bytes::Encoding;
use zenoh::query::Query;
use zenoh::sample::SampleKind;

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
}

/// Key of the primary's published commits (`<prefix>/<scene>`) and catch-up answers.
pub const REPLICATION_SCENES: &str = "riskplan/_replication/scenes";
/// Key of the primary's index of scene versions.
pub const REPLICATION_INDEX: &str = "riskplan/_replication/index";
/// How often a replica compares its versions with the primary's index and fetches
/// what it missed (a lost publication is caught up within this).
pub const SYNC_INTERVAL: Duration = Duration::from_secs(1);
/// Timeout of a replica's catch-up queries to the primary.
const SYNC_TIMEOUT: Duration = Duration::from_secs(5);

/// Keys answered from the start, while the stored scenes load.
const EARLY_KEYS: [&str; 2] = ["riskplan/status", "riskplan/echo"];

/// The keys a replica answers once ready, besides [`EARLY_KEYS`]: reads only (a query
/// on `*/apply` is a write and must reach the primary, so a replica declares no
/// queryable that includes it).
const REPLICA_KEYS: [&str; 4] =
    ["riskplan/scenes/*", "riskplan/scenes/*/plan", "riskplan/scenes/*/verify", "riskplan/scenes/*/risk"];
/// The bounded job pool: `workers` permits; at most `workers + queue` jobs admitted.
#[derive(Debug)]
pub struct Jobs {
    sem: Arc<Semaphore>,
    workers: usize,
    capacity: usize,
    admitted: AtomicUsize,
    running: AtomicUsize,
}

impl Jobs {
    fn new(workers: usize, capacity: usize) -> Jobs {
        Jobs {
            sem: Arc::new(Semaphore::new(workers)),
            workers,
            capacity,
            admitted: AtomicUsize::new(0),
            running: AtomicUsize::new(0),
        }
    }

    /// Runs `f` on a blocking thread, or answers `busy` at once when full. A job
    /// still waiting for a worker at `deadline` is dropped with `deadline_exceeded`
    /// (its work never starts). A panic in `f` becomes an `internal` error.
    pub async fn run<T: Send + 'static>(
        &self,
        deadline: Instant,
        f: impl FnOnce() -> Result<T, ServiceError> + Send + 'static,
    ) -> Result<T, ServiceError> {
        let limit = self.workers + self.capacity;
        let before = self.admitted.fetch_add(1, Ordering::SeqCst);
        if before >= limit {
            self.admitted.fetch_sub(1, Ordering::SeqCst);
            return Err(ServiceError::Busy(limit));
        }
        let permit = match tokio::time::timeout_at(deadline.into(), self.sem.clone().acquire_owned()).await {
            Ok(p) if Instant::now() < deadline => p,
            _ => {
                self.admitted.fetch_sub(1, Ordering::SeqCst);
                return Err(ServiceError::DeadlineExceeded("the request waited for a worker past its deadline".into()));
            }
        };
        self.running.fetch_add(1, Ordering::SeqCst);
        let r = tokio::task::spawn_blocking(move || std::panic::catch_unwind(AssertUnwindSafe(f))).await;
        self.running.fetch_sub(1, Ordering::SeqCst);
        self.admitted.fetch_sub(1, Ordering::SeqCst);
        drop(permit);
        match r {
            Ok(Ok(v)) => v,
            Ok(Err(p)) => Err(ServiceError::Internal(format!("a job panicked: {}", panic_text(&p)))),
            Err(e) => Err(ServiceError::Internal(format!("a job failed: {e}"))),
        }
    }

    fn status(&self) -> QueueStatus {
        let admitted = self.admitted.load(Ordering::SeqCst) as u64;
        let running = self.running.load(Ordering::SeqCst) as u64;
        QueueStatus {
            depth: admitted.saturating_sub(running),
            running,
            workers: self.workers as u64,
            capacity: self.capacity as u64,
        }
    }
}

/// The cancellation flags of running jobs. Shutdown sets them all, so long plans
/// stop within one planner iteration instead of holding the process.
#[derive(Debug, Default)]
pub struct Cancels {
    flags: Mutex<BTreeMap<u64, Arc<AtomicBool>>>,
    next: AtomicU64,
    shutting_down: AtomicBool,
}

/// A registered cancellation flag; dropping it unregisters the flag.
pub struct CancelGuard<'a> {
    owner: &'a Cancels,
    id: u64,
    /// The flag to hand to the job.
    pub flag: Arc<AtomicBool>,
}

impl Drop for CancelGuard<'_> {
    fn drop(&mut self) {
        if let Ok(mut m) = self.owner.flags.lock() {
            m.remove(&self.id);
        }
    }
}

impl Cancels {
    /// A new flag, already set when shutdown has begun.
    pub fn register(&self) -> CancelGuard<'_> {
        let id = self.next.fetch_add(1, Ordering::Relaxed);
        let flag = Arc::new(AtomicBool::new(self.shutting_down.load(Ordering::SeqCst)));
        if let Ok(mut m) = self.flags.lock() {
            m.insert(id, flag.clone());
        }
        // A shutdown between the load above and the insert must not be missed.
        if self.shutting_down.load(Ordering::SeqCst) {
            flag.store(true, Ordering::SeqCst);
        }
        CancelGuard { owner: self, id, flag }
    }

    /// Sets every flag, now and for jobs registered later.
    pub fn cancel_all(&self) -> usize {
        self.shutting_down.store(true, Ordering::SeqCst);
        let m = self.flags.lock().map(|m| m.values().cloned().collect::<Vec<_>>()).unwrap_or_default();
        for f in &m {
            f.store(true, Ordering::SeqCst);
        }
        m.len()
    }
}

fn panic_text(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Shared server state.
#[derive(Debug)]
pub struct State {
    /// Scenes.
    pub registry: Registry,
    /// Job pool.
    pub jobs: Jobs,
    started: Instant,
    counters: Mutex<BTreeMap<String, Counter>>,
    max_plan_seconds: Duration,
    max_job_seconds: Duration,
    /// Cancellation flags of running plans.
    pub cancels: Cancels,
    /// Set once the stored scenes and the `--preload` files are in.
    ready: AtomicBool,
    /// Set once the stored scenes are loaded (a replica is ready after catching up).
    loaded: AtomicBool,
    /// A replica's primary, by data-directory identity (`None` before the first
    /// catch-up).
    primary_id: Mutex<Option<u64>>,
    replica: bool,
}

impl State {
    fn count(&self, kind: &str, ok: bool) {
        if let Ok(mut c) = self.counters.lock() {
            let e = c.entry(kind.to_string()).or_default();
            if ok {
                e.served += 1;
            } else {
                e.failed += 1;
            }
        }
    }

    fn status(&self) -> StatusReply {
        let (entries, hits, misses) = self.registry.cache.stats();
        StatusReply {
            state: if self.ready.load(Ordering::SeqCst) { "ready" } else { "loading" }.into(),
            role: if self.replica { "replica" } else { "primary" }.into(),
            uptime_s: self.started.elapsed().as_secs_f64(),
            scenes: self
                .registry
                .list()
                .into_iter()
                .map(|(name, revision, n)| SceneStatus { name, revision, obstacles: n as u64 })
                .collect(),
            cache: CacheStatus { entries: entries as u64, hits, misses },
            queue: self.jobs.status(),
            requests: self.counters.lock().map(|c| c.clone()).unwrap_or_default(),
            problems: self.registry.problems(),
        }
    }
}

fn bincode_encoding() -> Encoding {
    Encoding::from(BINCODE)
}

fn encoding_of(c: Codec) -> Encoding {
    match c {
        Codec::Json => Encoding::APPLICATION_JSON,
        Codec::Bincode => bincode_encoding(),
    }
}

/// Runs the server until SIGINT or SIGTERM.
pub async fn serve(cfg: ServerConfig) -> Result<(), String> {
    let store = Store::open(&cfg.data).map_err(|e| format!("--data {}: {e}", cfg.data.display()))?;
    let state = Arc::new(State {
        registry: Registry::new(store),
        jobs: Jobs::new(cfg.workers.max(1), cfg.queue),
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
    });
    let session = zenoh::open(cfg.zenoh.clone()).await.map_err(|e| format!("cannot open the Zenoh session: {e}"))?;
    // Complete queryables: with several servers behind a router, a query goes to one
    // of them (Zenoh's BestMatching), never to all. Only `status` and `echo` are
    // declared now; the rest once the stored scenes are in (see `serve_when_ready`),
    // so that a loading server takes no work: in a cluster another one does, and
    // clients repeat reads that no server took.
    let mut early = Vec::new();
    for k in EARLY_KEYS {
        early.push(declare(&session, k).await?);
    }
    // a primary receives clients' puts; a replica its primary's commits
    let sub_key = if cfg.replica { format!("{REPLICATION_SCENES}/**") } else { "riskplan/scenes/**".to_string() };
    let subscriber =
        session.declare_subscriber(&sub_key).await.map_err(|e| format!("cannot declare the subscriber: {e}"))?;
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
                    let put = (key, sample.kind(), sample.payload().to_bytes().into_owned());
                    // Never wait here: the put worker applies puts in arrival order; when
                    // its queue is full the put is dropped (puts have no reply) and counted.
                    if let Err(e) = puts.try_send(put) {
                        state.count("put", false);
                        warn!(key = %e.into_inner().0, "put dropped: {PUT_QUEUE} puts are already waiting");
                    }
                }
                Err(_) => break,
            },
        }
    }
    for t in &tasks {
        t.abort();
    }
    let cancelled = state.cancels.cancel_all();
    info!(cancelled, "shutting down");
    let _ = session.close().await;
    Ok(())
}

/// Puts and deletes waiting for the put worker before new ones are dropped.
pub const PUT_QUEUE: usize = 256;

type PutMsg = (String, SampleKind, Vec<u8>);

/// The put worker: applies puts and deletes one after another, in arrival order, on
/// a blocking thread, so that the loop receiving messages never waits for one.
fn spawn_put_worker(state: Arc<State>, loading: tokio::task::JoinHandle<()>) -> tokio::sync::mpsc::Sender<PutMsg> {
    let (tx, mut rx) = tokio::sync::mpsc::channel::<PutMsg>(PUT_QUEUE);
    tokio::spawn(async move {
        if let Err(e) = loading.await {
            warn!("loading the stored scenes failed: {e}");
            state.ready.store(true, Ordering::SeqCst);
        }
        while let Some((key, kind, bytes)) = rx.recv().await {
            let st = state.clone();
            if let Err(e) = tokio::task::spawn_blocking(move || handle_put(&st, &key, kind, &bytes)).await {
                warn!("put handler failed: {e}");
            }
        }
    });
    tx
}

async fn declare(
    session: &zenoh::Session,
    key: &str,
) -> Result<zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<Query>>, String> {
    session.declare_queryable(key).complete(true).await.map_err(|e| format!("cannot declare the queryable {key}: {e}"))
}

/// Answers the queries of one queryable, each in its own task. `skip_early`: leave
/// `status` and `echo` to their own queryables (a primary's `riskplan/**` includes
/// them; a query dropped here gets no reply from this queryable).
async fn serve_queries(
    state: Arc<State>,
    q: zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<Query>>,
    skip_early: bool,
) {
    let own = q.key_expr().as_str().to_string();
    while let Ok(query) = q.recv_async().await {
        let key = query.key_expr().as_str();
        // `riskplan/**` leaves status and echo to their own queryables; those take
        // only their exact key (a wildcard query is answered once, by `riskplan/**`)
        let early = EARLY_KEYS.contains(&own.as_str());
        if (skip_early && EARLY_KEYS.contains(&key)) || (early && key != own) {
            continue;
        }
        let st = state.clone();
        tokio::spawn(async move { handle_query(st, query).await });
    }
}

/// Declares the work queryables once the server is ready (a primary: `riskplan/**`;
/// a replica: the read keys), and serves them.
async fn serve_when_ready(state: Arc<State>, session: zenoh::Session) {
    while !state.ready.load(Ordering::SeqCst) {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let keys: Vec<&str> = if state.replica { REPLICA_KEYS.to_vec() } else { vec!["riskplan/**"] };
    let mut loops = Vec::new();
    for k in keys {
        match declare(&session, k).await {
            Ok(q) => loops.push(tokio::spawn(serve_queries(state.clone(), q, !state.replica))),
            Err(e) => warn!("{e}"),
        }
    }
    let n = state.registry.list().len();
    eprintln!("riskplan: ready ({n} scenes{})", if state.replica { ", replica" } else { "" });
    info!(scenes = n, "ready");
    for l in loops {
        let _ = l.await;
    }
}

/// A primary publishes each commit on `riskplan/_replication/scenes/<scene>`, in
/// commit order (the registry calls the listener under the scene's write lock).
fn spawn_publisher(state: &Arc<State>, session: zenoh::Session) {
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Commit>();
    state.registry.set_listener(CommitListener::new(move |c| {
        let _ = tx.send(c.clone());
    }));
    tokio::spawn(async move {
        while let Some(c) = rx.recv().await {
            let key = format!("{REPLICATION_SCENES}/{}", c.name);
            let entry = replication_entry(&c);
            if let Err(e) = session.put(&key, Codec::Json.encode(&entry)).encoding(Encoding::APPLICATION_JSON).await {
                warn!(scene = %c.name, "cannot publish the commit: {e}");
            }
        }
    });
}

fn replication_entry(c: &Commit) -> ReplicationEntry {
    ReplicationEntry {
        name: c.name.clone(),
        revision: c.revision,
        deleted: c.json.is_none(),
        scene: c.json.as_ref().map(embedded),
    }
}

/// The commit of a replication entry; an error when it is neither a deletion nor a
/// scene.
fn commit_of(e: ReplicationEntry) -> Result<Commit, ServiceError> {
    let json = match (e.deleted, e.scene) {
        (true, None) => None,
        (false, Some(j)) => Some(j.0),
        _ => return Err(invalid("scene", "a commit is either deleted or has a scene")),
    };
    Ok(Commit { name: e.name, revision: e.revision, json })
}

/// A replica's catch-up: every [`SYNC_INTERVAL`], the primary's index against its own
/// versions, and the scenes it is behind on fetched and installed. The first round
/// (after the stored scenes are loaded) makes the replica ready.
fn spawn_sync(state: Arc<State>, session: zenoh::Session) {
    tokio::spawn(async move {
        while !state.ready.load(Ordering::SeqCst) && !state.loaded.load(Ordering::SeqCst) {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        loop {
            let synced = match sync_once(&state, &session).await {
                Ok(n) => {
                    if n > 0 {
                        info!(changed = n, "caught up with the primary");
                    }
                    true
                }
                Err(e) => {
                    warn!("catch-up with the primary failed: {e}");
                    false
                }
            };
            // ready after a catch-up, or (primary unreachable) with stored scenes to serve
            if synced || !state.registry.list().is_empty() {
                state.ready.store(true, Ordering::SeqCst);
            }
            tokio::time::sleep(SYNC_INTERVAL).await;
        }
    });
}

async fn get_json<T: serde::de::DeserializeOwned>(session: &zenoh::Session, key: &str) -> Result<T, String> {
    let replies = session
        .get(key)
        .consolidation(zenoh::query::ConsolidationMode::None)
        .timeout(SYNC_TIMEOUT)
        .await
        .map_err(|e| e.to_string())?;
    let reply = replies.recv_async().await.map_err(|_| format!("no primary answered {key}"))?;
    let sample = reply.result().map_err(|e| format!("{key}: {}", e.payload().try_to_string().unwrap_or_default()))?;
    Codec::Json.decode(&sample.payload().to_bytes()).map_err(|(m, _)| format!("{key}: {m}"))
}

async fn sync_once(state: &Arc<State>, session: &zenoh::Session) -> Result<usize, String> {
    let index: ReplicationIndex = get_json(session, REPLICATION_INDEX).await?;
    let changed = state.primary_id.lock().map(|mut p| p.replace(index.primary) != Some(index.primary)).unwrap_or(true);
    if changed {
        info!(primary = index.primary, "following a primary: full catch-up");
    }
    let listed: std::collections::BTreeSet<String> = index.scenes.iter().map(|(n, _, _)| n.clone()).collect();
    let mut installed = 0;
    for (name, revision, deleted) in index.scenes {
        if !changed && state.registry.replicated_version(&name).is_some_and(|v| v >= (revision, deleted)) {
            continue;
        }
        // one scene that cannot be fetched or installed does not stop the others
        let entry: ReplicationEntry = match get_json(session, &format!("{REPLICATION_SCENES}/{name}")).await {
            Ok(e) => e,
            Err(e) => {
                warn!(scene = %name, "cannot fetch the primary's scene: {e}");
                continue;
            }
        };
        if entry.name != name {
            warn!(scene = %name, "the primary's answer names another scene ({}): ignored", entry.name);
            continue;
        }
        let st = state.clone();
        let r = tokio::task::spawn_blocking(move || st.registry.install(&commit_of(entry)?, changed))
            .await
            .map_err(|e| e.to_string())?;
        match r {
            Ok(true) => installed += 1,
            Ok(false) => {}
            Err(e) => warn!(scene = %name, "cannot install the primary's scene: {e}"),
        }
    }
    let st = state.clone();
    let dropped =
        tokio::task::spawn_blocking(move || st.registry.drop_missing(&listed)).await.map_err(|e| e.to_string())?;
    if !dropped.is_empty() {
        info!(?dropped, "dropped scenes the primary no longer has");
    }
    Ok(installed + dropped.len())
}

/// Loads the stored scenes, then the `--preload` files whose names are neither live
/// nor deleted by a client.
fn load_scenes(registry: &Registry, preload: &[PathBuf]) {
    for p in registry.load() {
        warn!("{p}");
    }
    for path in preload {
        let name = path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        if registry.known(&name) {
            continue;
        }
        let loaded = std::fs::read_to_string(path)
            .map_err(|e| e.to_string())
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).map_err(|e| e.to_string()));
        match loaded.map(|json| registry.put_scene(&name, json)) {
            Ok(Ok(rev)) => info!(scene = %name, revision = rev, "preloaded {}", path.display()),
            Ok(Err(e)) => warn!("--preload {}: {e}", path.display()),
            Err(e) => warn!("--preload {}: {e}", path.display()),
        }
    }
}

/// Resolves on SIGINT or SIGTERM.
pub async fn shutdown_signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut term = match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(t) => t,
            Err(_) => {
                let _ = ctrl_c.await;
                return;
            }
        };
        tokio::select! { _ = ctrl_c => {}, _ = term.recv() => {} }
    }
    #[cfg(not(unix))]
    {
        let _ = ctrl_c.await;
    }
}

/// `riskplan/scenes/<scene>` and `.../obstacles/<id>` puts and deletes.
fn handle_put(state: &State, key: &str, kind: SampleKind, bytes: &[u8]) {
    let parts: Vec<&str> = key.split('/').collect();
    let span = tracing::info_span!("put", key = %key);
    let _g = span.enter();
    let r: Result<Option<u64>, ServiceError> = (|| match (parts.as_slice(), kind) {
        (["riskplan", "_replication", "scenes", name], SampleKind::Put) if state.replica => {
            let entry: ReplicationEntry =
                Codec::Json.decode(bytes).map_err(|(m, f)| ServiceError::Malformed { message: m, field: f })?;
            if entry.name != *name {
                return Err(invalid("name", format!("a commit for '{}' published on '{key}'", entry.name)));
            }
            let c = commit_of(entry)?;
            state.registry.install(&c, false).map(|done| done.then_some(c.revision))
        }
        (["riskplan", "_replication", ..], _) => Ok(None),
        (["riskplan", "scenes", name], SampleKind::Put) => {
            if bytes.len() > MAX_PAYLOAD_BYTES {
                return Err(ServiceError::PayloadTooLarge(bytes.len(), MAX_PAYLOAD_BYTES));
            }
            let json: serde_json::Value =
                Codec::Json.decode(bytes).map_err(|(m, f)| ServiceError::Malformed { message: m, field: f })?;
            state.registry.put_scene(name, json).map(Some)
        }
        (["riskplan", "scenes", name], SampleKind::Delete) => state.registry.delete_scene(name).map(|_| None),
        (["riskplan", "scenes", name, "obstacles", id], SampleKind::Put) => {
            if bytes.len() > MAX_PAYLOAD_BYTES {
                return Err(ServiceError::PayloadTooLarge(bytes.len(), MAX_PAYLOAD_BYTES));
            }
            let put: ObstaclePut =
                Codec::Json.decode(bytes).map_err(|(m, f)| ServiceError::Malformed { message: m, field: f })?;
            state.registry.put_obstacle(name, id, &put).map(Some)
        }
        (["riskplan", "scenes", name, "obstacles", id], SampleKind::Delete) => {
            state.registry.delete_obstacle(name, id).map(Some)
        }
        _ => Ok(None),
    })();
    match r {
        Ok(rev) => {
            state.count("put", true);
            info!(revision = ?rev, "applied");
        }
        Err(e) => {
            state.count("put", false);
            warn!(code = e.code(), "put rejected: {e}");
        }
    }
}

async fn handle_query(state: Arc<State>, query: Query) {
    let t0 = Instant::now();
    let key = query.key_expr().as_str().to_string();
    let parts: Vec<String> = key.split('/').map(str::to_string).collect();
    let kind = match parts.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["riskplan", "_replication", "index"] => "replication_index",
        ["riskplan", "_replication", "scenes", _] => "replication_scene",
        ["riskplan", "status"] => "status",
        ["riskplan", "echo"] => "echo",
        ["riskplan", "scenes", _] => "scene",
        ["riskplan", "scenes", _, k @ ("apply" | "plan" | "verify" | "risk")] => k,
        _ => "unknown",
    }
    .to_string();
    let scene = match parts.as_slice() {
        [_, s, name, ..] if s == "scenes" => name.clone(),
        [_, r, s, name] if r == "_replication" && s == "scenes" => name.clone(),
        _ => String::new(),
    };
    let span = tracing::info_span!("request", kind = %kind, scene = %scene, planner = tracing::field::Empty, revision = tracing::field::Empty, duration_ms = tracing::field::Empty);
    async move {
        let enc = query.encoding().map(|e| e.to_string()).unwrap_or_default();
        let bytes = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
        let (codec, result) = match Codec::from_encoding(&enc) {
            None => (Codec::Json, Err(ServiceError::UnsupportedEncoding(enc.clone()))),
            Some(c) if bytes.len() > MAX_PAYLOAD_BYTES => {
                (c, Err(ServiceError::PayloadTooLarge(bytes.len(), MAX_PAYLOAD_BYTES)))
            }
            Some(c) => (
                c,
                dispatch(&state, &kind, &scene, c, bytes, t0).await.and_then(|(payload, rev)| {
                    if payload.len() > MAX_REPLY_BYTES {
                        Err(ServiceError::LimitExceeded {
                            message: format!(
                            "the reply would be {} bytes, over the limit of {MAX_REPLY_BYTES}: ask for fewer points, \
                             a smaller grid, or a verify summary (\"summary\": true)",
                            payload.len()
                        ),
                            field: None,
                        })
                    } else {
                        Ok((payload, rev))
                    }
                }),
            ),
        };
        let ok = result.is_ok();
        state.count(&kind, ok);
        let span = tracing::Span::current();
        span.record("duration_ms", t0.elapsed().as_secs_f64() * 1e3);
        let sent = match result {
            Ok((payload, rev)) => {
                if let Some(r) = rev {
                    span.record("revision", r);
                }
                query.reply(query.key_expr().clone(), payload).encoding(encoding_of(codec)).await
            }
            Err(e) => {
                info!(code = e.code(), "error reply: {e}");
                query.reply_err(codec.encode(&e.reply())).encoding(encoding_of(codec)).await
            }
        };
        if let Err(e) = sent {
            warn!("cannot send the reply: {e}");
        }
        info!(ok, "done");
    }
    .instrument(span)
    .await
}

fn malformed((message, field): (String, Option<String>)) -> ServiceError {
    ServiceError::Malformed { message, field }
}

async fn dispatch(
    state: &Arc<State>,
    kind: &str,
    scene: &str,
    codec: Codec,
    bytes: Vec<u8>,
    arrival: Instant,
) -> Result<(Vec<u8>, Option<u64>), ServiceError> {
    // apply, verify and risk: the request's deadline, capped (and defaulted) by the server's
    let deadline = |ms: Option<u64>| {
        let d = ms.map_or(state.max_job_seconds, |ms| Duration::from_millis(ms).min(state.max_job_seconds));
        arrival + d
    };
    match kind {
        "status" => return Ok((codec.encode(&state.status()), None)),
        // The bare round trip of the load benchmark: the payload back, no work, no pool.
        "echo" => return Ok((bytes, None)),
        // a replica's catch-up queries (only a primary declares these keys)
        "replication_index" => {
            let index = ReplicationIndex { primary: state.registry.store_id(), scenes: state.registry.index() };
            return Ok((Codec::Json.encode(&index), None));
        }
        "replication_scene" => {
            let c = state.registry.commit(scene)?.ok_or_else(|| ServiceError::UnknownScene(scene.to_string()))?;
            return Ok((Codec::Json.encode(&replication_entry(&c)), Some(c.revision)));
        }
        _ if !state.ready.load(Ordering::SeqCst) => {
            return Err(ServiceError::Unavailable("the server is loading its stored scenes: try again shortly".into()))
        }
        _ => {}
    }
    match kind {
        "scene" => {
            let e = state.registry.get(scene)?;
            Ok((codec.encode(&SceneReply { name: scene.to_string(), revision: e.revision, scene: embedded(&e.json) }), Some(e.revision)))
        }
        "apply" => {
            let req: ApplyRequest = codec.decode(&bytes).map_err(malformed)?;
            let st = state.clone();
            let name = scene.to_string();
            let rev = state
                .jobs
                .run(deadline(req.deadline_ms), move || handlers::apply(&st.registry, &name, req))
                .await?;
            Ok((codec.encode(&ApplyReply { scene: scene.to_string(), revision: rev }), Some(rev)))
        }
        "plan" => {
            let req: PlanRequest = codec.decode(&bytes).map_err(malformed)?;
            let entry = state.registry.get(scene)?;
            tracing::Span::current().record("planner", req.planner.as_deref().unwrap_or("rrt-sos"));
            let cap = state.max_plan_seconds;
            let guard = state.cancels.register();
            let cancel = guard.flag.clone();
            let rev = entry.revision;
            // the queue wait counts against the plan's time limit (handlers::plan); a plan
            // can never wait longer than the cap
            let reply = state.jobs.run(arrival + cap, move || handlers::plan(&entry, &req, cap, arrival, cancel)).await;
            drop(guard);
            let reply = reply?;
            Ok((codec.encode(&reply), Some(rev)))
        }
        "verify" => {
            let req: VerifyRequest = codec.decode(&bytes).map_err(malformed)?;
            let entry = state.registry.get(scene)?;
            let rev = entry.revision;
            let until = deadline(req.deadline_ms);
            let reply = state.jobs.run(until, move || handlers::verify_request(&entry, &req, until)).await?;
            Ok((codec.encode(&reply), Some(rev)))
        }
        "risk" => {
            let req: RiskRequest = codec.decode(&bytes).map_err(malformed)?;
            let entry = state.registry.get(scene)?;
            let rev = entry.revision;
            let until = deadline(req.deadline_ms);
            let reply = state.jobs.run(until, move || handlers::risk(&entry, &req, until)).await?;
            Ok((codec.encode(&reply), Some(rev)))
        }
        _ => Err(ServiceError::InvalidRequest { message: "unknown key: use riskplan/status, riskplan/scenes/<scene> or riskplan/scenes/<scene>/{apply,plan,verify,risk}".into(), field: None }),
    }
}
