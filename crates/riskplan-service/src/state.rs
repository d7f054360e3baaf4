//! The state every part of the server shares (the scenes, the job pool, counters,
//! readiness), below the parts that use it: `server.rs` builds it, `queries.rs`,
//! `puts.rs`, `replication.rs` and `startup.rs` read it.

use super::jobs::{Cancels, Jobs};
use super::metrics::{Metrics, Snapshot};
use super::proto::*;
use super::registry::Registry;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Shared server state.
#[derive(Debug)]
pub(crate) struct State {
    /// Scenes.
    pub(crate) registry: Registry,
    /// Job pool.
    pub(crate) jobs: Jobs,
    /// The machine's cores: a large `verify` takes up to this many workers when they
    /// are idle (`Jobs::spare`).
    pub(crate) cores: usize,
    pub(crate) started: Instant,
    pub(crate) counters: Mutex<BTreeMap<String, Counter>>,
    /// Cap on a plan's time limit.
    pub(crate) max_plan_seconds: Duration,
    /// Cap (and default) of the deadline of apply, verify and risk jobs.
    pub(crate) max_job_seconds: Duration,
    /// Cancellation flags of running plans.
    pub(crate) cancels: Cancels,
    /// Set once the stored scenes and the `--preload` files are in.
    pub(crate) ready: AtomicBool,
    /// Set once the stored scenes are loaded (a replica is ready after catching up).
    pub(crate) loaded: AtomicBool,
    /// A replica's primary, by data-directory identity (`None` before the first
    /// catch-up).
    pub(crate) primary_id: Mutex<Option<u64>>,
    /// A replica (reads only, following a primary), not a primary.
    pub(crate) replica: bool,
    /// This server's id: its liveliness token and own keys (`routes::server_token`,
    /// `routes::own_keys`).
    pub(crate) server_id: String,
    /// Reads waiting for a revision (`queries::MAX_REVISION_WAITERS` at most).
    pub(crate) revision_waiters: std::sync::atomic::AtomicUsize,
    /// The Prometheus metrics, when `serve --metrics` asked for them.
    pub(crate) metrics: Option<Arc<Metrics>>,
    /// Warm committed scenes in the background (`serve --no-warm-up` turns it off).
    pub(crate) warm_up: bool,
    /// Set while the warm-up thread runs (one at a time: `warm`).
    pub(crate) warming: AtomicBool,
    /// Scenes (name, revision) waiting for the warm-up thread.
    pub(crate) warm_queue: Mutex<Vec<(String, u64)>>,
}

impl State {
    /// Counts a request of `kind` (a query's kind, or `put`) as served or failed.
    pub(crate) fn count(&self, kind: &str, ok: bool) {
        if let Ok(mut c) = self.counters.lock() {
            let e = c.entry(kind.to_string()).or_default();
            if ok {
                e.served += 1;
            } else {
                e.failed += 1;
            }
        }
    }

    /// Records a request of `kind` for the metrics (when on): its outcome (`metrics::OK`,
    /// an error code, `metrics::DROPPED`) and how long it took.
    pub(crate) fn record(&self, kind: &'static str, outcome: &'static str, took: Duration) {
        if let Some(m) = &self.metrics {
            m.record(kind, outcome, took);
        }
    }

    /// What a metrics scrape reads of the server.
    pub(crate) fn snapshot(&self) -> Snapshot {
        let (entries, hits, misses) = self.registry.cache.stats();
        let queue = self.jobs.status();
        Snapshot {
            ready: self.ready.load(Ordering::SeqCst),
            queue_depth: queue.depth,
            jobs_running: queue.running,
            workers: queue.workers,
            queue_capacity: queue.capacity,
            scenes: self.registry.list().into_iter().map(|(name, revision, _)| (name, revision)).collect(),
            contours: (entries as u64, hits, misses),
            kernels: self.registry.kernels.counts(),
        }
    }

    /// This server's role.
    pub(crate) fn role(&self) -> Role {
        if self.replica {
            Role::Replica
        } else {
            Role::Primary
        }
    }

    /// The `status` reply.
    pub(crate) fn status(&self) -> StatusReply {
        let (entries, hits, misses) = self.registry.cache.stats();
        StatusReply {
            state: if self.ready.load(Ordering::SeqCst) { ServerState::Ready } else { ServerState::Loading },
            role: self.role(),
            server_id: self.server_id.clone(),
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
