//! The server's Prometheus metrics (`serve --metrics ADDR`; every name, type and label is
//! listed in proto/README.md, "Metrics"), in one struct made once at start and shared
//! (`Arc`) by the parts that record: queries and puts count each request under its kind
//! and outcome and time it. Recording is lock-free: an atomic add on a counter resolved
//! once per (kind, outcome) and an atomic add on a bucket of the kind's histogram. What
//! the server holds — its queue, its scenes, its caches — is read when Prometheus
//! scrapes (a [`Collector`] over a [`Snapshot`] of the server's state), never kept in
//! step on the hot path.
//!
//! The HTTP side is `metrics_http.rs`; this module knows nothing of the server's state
//! but the [`Snapshot`] its sampler returns (set by `server.rs`).

use super::routes::RouteKind;
use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeLabelSet, EncodeMetric, MetricEncoder, NoLabelSet};
use prometheus_client::metrics::counter::{ConstCounter, Counter};
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::metrics::info::Info;
use prometheus_client::metrics::{MetricType, TypedMetric};
use prometheus_client::registry::{Registry, Unit};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

/// The prefix of every metric.
pub(crate) const PREFIX: &str = "riskplan";

/// The kind of a put or delete (scenes, obstacles; a replica's installed commits).
pub(crate) const PUT: &str = "put";

/// A query on a key that is no route of the service (`queries::handle_query`).
pub(crate) const UNKNOWN: &str = "unknown";

/// The outcome of a request answered (or a put applied) without error; an error is
/// counted under its wire code (proto/README.md, "Error codes").
pub(crate) const OK: &str = "ok";

/// The outcome of a put dropped because `PUT_QUEUE` puts already waited.
pub(crate) const DROPPED: &str = "dropped";

/// The request kinds: every query kind (`RouteKind::label` of `RouteKind::ALL`), a query
/// on an unknown key, and puts. Their series are made at start (a histogram per kind, zero
/// until used); another kind is still counted, through the family's lock.
const KINDS: [&str; RouteKind::ALL.len() + 2] = {
    let mut k = [""; RouteKind::ALL.len() + 2];
    let mut i = 0;
    while i < RouteKind::ALL.len() {
        k[i] = RouteKind::ALL[i].label();
        i += 1;
    }
    k[i] = UNKNOWN;
    k[i + 1] = PUT;
    k
};

/// The outcomes: `ok`, a dropped put, and every error code of `ServiceError::code`.
/// Their (kind, outcome) counters are made on first use and then reached without a
/// lock; an outcome not listed here is still counted, through the family's lock.
const OUTCOMES: [&str; 19] = [
    OK,
    DROPPED,
    "malformed_payload",
    "unsupported_encoding",
    "payload_too_large",
    "limit_exceeded",
    "invalid_scene_name",
    "unknown_scene",
    "invalid_scene",
    "invalid_request",
    "invalid_trajectory",
    "outside_workspace",
    "unsafe_endpoint",
    "no_plan",
    "busy",
    "deadline_exceeded",
    "unavailable",
    "stale_revision",
    "internal",
];

/// Upper bounds of the latency buckets, seconds: 100 µs (an echo, a status) to 30 s
/// (a long plan; the server's caps default to 60 s and land in `+Inf`), about ×2.5 apart.
pub(crate) const LATENCY_BUCKETS: [f64; 17] =
    [0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0];

/// The labels of `riskplan_requests_total`.
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct RequestLabels {
    kind: &'static str,
    outcome: &'static str,
}

/// The labels of `riskplan_request_duration_seconds`.
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct KindLabels {
    kind: &'static str,
}

/// A latency histogram whose observation is lock-free: one atomic add on its bucket
/// and one on the sum (in nanoseconds, exact). prometheus-client's own `Histogram`
/// takes a mutex per observation; this one is encoded by its `encode_histogram`. The
/// count is the sum of the buckets, read at a scrape, so `_count` always equals the
/// `+Inf` bucket.
#[derive(Clone, Debug, Default)]
pub(crate) struct LatencyHistogram(Arc<HistogramCells>);

#[derive(Debug, Default)]
struct HistogramCells {
    /// Observations per bucket (not cumulative); the last is `+Inf`.
    buckets: [AtomicU64; LATENCY_BUCKETS.len() + 1],
    /// Sum of the observations, nanoseconds.
    sum_ns: AtomicU64,
}

impl LatencyHistogram {
    /// Records one duration.
    pub(crate) fn observe(&self, d: Duration) {
        let s = d.as_secs_f64();
        let i = LATENCY_BUCKETS.iter().position(|&b| s <= b).unwrap_or(LATENCY_BUCKETS.len());
        self.0.buckets[i].fetch_add(1, Ordering::Relaxed);
        self.0.sum_ns.fetch_add(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX), Ordering::Relaxed);
    }
}

impl TypedMetric for LatencyHistogram {
    const TYPE: MetricType = MetricType::Histogram;
}

impl EncodeMetric for LatencyHistogram {
    fn encode(&self, mut encoder: MetricEncoder) -> Result<(), std::fmt::Error> {
        let buckets: Vec<(f64, u64)> = LATENCY_BUCKETS
            .iter()
            .copied()
            .chain(std::iter::once(f64::INFINITY))
            .zip(self.0.buckets.iter().map(|b| b.load(Ordering::Relaxed)))
            .collect();
        let count = buckets.iter().map(|b| b.1).sum();
        let sum = self.0.sum_ns.load(Ordering::Relaxed) as f64 * 1e-9;
        encoder.encode_histogram::<NoLabelSet>(sum, count, &buckets, None)
    }

    fn metric_type(&self) -> MetricType {
        Self::TYPE
    }
}

/// What the server holds, read at each scrape (`server.rs` builds it from its state).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Snapshot {
    /// The stored scenes are in (queries are taken).
    pub(crate) ready: bool,
    /// Jobs admitted and waiting for a worker.
    pub(crate) queue_depth: u64,
    /// Jobs running on a worker or a write lane.
    pub(crate) jobs_running: u64,
    /// Worker threads (`--workers`).
    pub(crate) workers: u64,
    /// Jobs that may wait (`--queue`).
    pub(crate) queue_capacity: u64,
    /// Every live scene: (name, revision).
    pub(crate) scenes: Vec<(String, u64)>,
    /// The contour cache: (entries, hits, misses).
    pub(crate) contours: (u64, u64, u64),
    /// The kernels' covers and grown bodies.
    pub(crate) kernels: super::registry::KernelCounts,
}

/// Returns the server's [`Snapshot`], `None` once the server is gone.
type Sampler = Box<dyn Fn() -> Option<Snapshot> + Send + Sync>;

/// Encodes the [`Snapshot`] of each scrape (registered in the registry).
struct StateCollector {
    sampler: OnceLock<Sampler>,
}

impl std::fmt::Debug for StateCollector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StateCollector").field("sampler", &self.sampler.get().is_some()).finish()
    }
}

/// One unlabelled value of a collector's metric.
fn write_one(
    encoder: &mut DescriptorEncoder,
    name: &str,
    help: &str,
    metric: &impl EncodeMetric,
) -> Result<(), std::fmt::Error> {
    let e = encoder.encode_descriptor(name, help, None, metric.metric_type())?;
    metric.encode(e)
}

/// A collector's metric with one label: a value per label value.
fn write_labelled<M: EncodeMetric>(
    encoder: &mut DescriptorEncoder,
    name: &str,
    help: &str,
    label: &str,
    series: &[(&str, M)],
) -> Result<(), std::fmt::Error> {
    let Some(first) = series.first() else { return Ok(()) };
    let mut e = encoder.encode_descriptor(name, help, None, first.1.metric_type())?;
    for (value, metric) in series {
        let labels = [(label, *value)];
        metric.encode(e.encode_family(&labels)?)?;
    }
    Ok(())
}

impl Collector for StateCollector {
    fn encode(&self, mut encoder: DescriptorEncoder) -> Result<(), std::fmt::Error> {
        let Some(s) = self.sampler.get().and_then(|f| f()) else { return Ok(()) };
        let e = &mut encoder;
        let gauge = |v: u64| ConstGauge::new(i64::try_from(v).unwrap_or(i64::MAX));
        write_one(
            e,
            "ready",
            "1 once the stored scenes are loaded and queries are taken, else 0.",
            &gauge(s.ready.into()),
        )?;
        write_one(e, "queue_depth", "Jobs admitted and waiting for a worker.", &gauge(s.queue_depth))?;
        write_one(e, "jobs_running", "Jobs running on a worker or a write lane.", &gauge(s.jobs_running))?;
        write_one(e, "workers", "Worker threads for certification and planning (--workers).", &gauge(s.workers))?;
        write_one(
            e,
            "queue_capacity",
            "Jobs that may wait for a worker before requests are answered busy (--queue).",
            &gauge(s.queue_capacity),
        )?;
        write_one(e, "scenes", "Live scenes held.", &gauge(s.scenes.len() as u64))?;
        let revisions: Vec<(&str, ConstGauge)> = s.scenes.iter().map(|(n, r)| (n.as_str(), gauge(*r))).collect();
        write_labelled(e, "scene_revision", "The revision of each live scene.", "scene", &revisions)?;
        let k = &s.kernels;
        let (entries, contour_hits, contour_misses) = s.contours;
        write_labelled(
            e,
            "scene_cache_hits",
            "Scene cache hits: contours reused when a scene is built (contours), plan and verify jobs whose \
             scene kernel held the covers at their risk levels (covers), grown-body kernels reused (body).",
            "cache",
            &[
                ("contours", ConstCounter::new(contour_hits)),
                ("covers", ConstCounter::new(k.covers_hits)),
                ("body", ConstCounter::new(k.body_hits)),
            ],
        )?;
        write_labelled(
            e,
            "scene_cache_misses",
            "Scene cache misses: contours built (contours), plan and verify jobs whose scene kernel did not \
             hold the covers (covers), grown-body kernels built (body).",
            "cache",
            &[
                ("contours", ConstCounter::new(contour_misses)),
                ("covers", ConstCounter::new(k.covers_misses)),
                ("body", ConstCounter::new(k.body_misses)),
            ],
        )?;
        write_one(e, "contour_cache_entries", "Contours held by the contour cache.", &gauge(entries))?;
        write_one(
            e,
            "covers_built",
            "Obstacles' proven covers (the scene index's, at a job's risk levels) built and kept by the \
             process.",
            &ConstCounter::new(k.covers_built),
        )?;
        write_labelled(
            e,
            "scene_warm_ups",
            "Background warm-ups of committed scenes (serve --no-warm-up turns them off): everything built \
             (done), stopped by the job deadline or shutdown (stopped), not started because no worker was \
             idle, or abandoned for a newer revision of the scene (skipped).",
            "outcome",
            &[
                ("done", ConstCounter::new(k.warm_ups_done)),
                ("stopped", ConstCounter::new(k.warm_ups_stopped)),
                ("skipped", ConstCounter::new(k.warm_ups_skipped)),
            ],
        )
    }
}

/// The server's metrics: made once (`Metrics::new`), shared by every part that records.
#[derive(Debug)]
pub(crate) struct Metrics {
    registry: Registry,
    requests: Family<RequestLabels, Counter>,
    /// The counter of (KINDS[k], OUTCOMES[o]) at `k * OUTCOMES.len() + o`, made on first use.
    request_slots: Vec<OnceLock<Counter>>,
    durations: Family<KindLabels, LatencyHistogram>,
    /// The histogram of KINDS[k] at `k`.
    duration_slots: Vec<LatencyHistogram>,
    state: Arc<StateCollector>,
}

impl Metrics {
    /// The metrics of a server in `role` (`primary` or `replica`) with id `server_id`.
    pub(crate) fn new(role: &str, server_id: &str) -> Metrics {
        let mut registry = Registry::with_prefix(PREFIX);
        registry.register(
            "build",
            "The riskplan build and this server: version, git commit (unknown when built without git), role \
             (primary or replica) and server id",
            Info::new(vec![
                ("version", env!("CARGO_PKG_VERSION").to_string()),
                ("commit", env!("RISKPLAN_GIT_COMMIT").to_string()),
                ("role", role.to_string()),
                ("server_id", server_id.to_string()),
            ]),
        );
        let requests = Family::<RequestLabels, Counter>::default();
        registry.register(
            "requests",
            "Requests by kind (a query kind, unknown, or put for puts and deletes) and outcome (ok, an error \
             code, or dropped for a put the full put queue dropped)",
            requests.clone(),
        );
        let durations = Family::<KindLabels, LatencyHistogram>::default();
        registry.register_with_unit(
            "request_duration",
            "Time from a request's arrival to its reply (a put: to its being applied), by kind",
            Unit::Seconds,
            durations.clone(),
        );
        let duration_slots = KINDS.iter().map(|&kind| durations.get_or_create_owned(&KindLabels { kind })).collect();
        let state = Arc::new(StateCollector { sampler: OnceLock::new() });
        registry.register_collector(Box::new(state.clone()));
        Metrics {
            registry,
            requests,
            request_slots: (0..KINDS.len() * OUTCOMES.len()).map(|_| OnceLock::new()).collect(),
            durations,
            duration_slots,
            state,
        }
    }

    /// Sets where each scrape reads the server's state (once; later calls are ignored).
    pub(crate) fn set_sampler(&self, f: impl Fn() -> Option<Snapshot> + Send + Sync + 'static) {
        let _ = self.state.sampler.set(Box::new(f));
    }

    /// Records a request of `kind` with `outcome` (`OK`, an error code, `DROPPED`) that
    /// took `took`.
    pub(crate) fn record(&self, kind: &'static str, outcome: &'static str, took: Duration) {
        let k = KINDS.iter().position(|&x| x == kind);
        let o = OUTCOMES.iter().position(|&x| x == outcome);
        match (k, o) {
            (Some(k), Some(o)) => {
                self.request_slots[k * OUTCOMES.len() + o]
                    .get_or_init(|| self.requests.get_or_create_owned(&RequestLabels { kind, outcome }))
                    .inc();
            }
            _ => {
                self.requests.get_or_create(&RequestLabels { kind, outcome }).inc();
            }
        }
        match k {
            Some(k) => self.duration_slots[k].observe(took),
            None => self.durations.get_or_create(&KindLabels { kind }).observe(took),
        };
    }

    /// The OpenMetrics text exposition of every metric, ending with `# EOF`.
    pub(crate) fn encode(&self) -> Result<String, std::fmt::Error> {
        let mut out = String::with_capacity(8 << 10);
        prometheus_client::encoding::text::encode(&mut out, &self.registry)?;
        Ok(out)
    }

    /// Requests of `kind` with `outcome` so far (tests).
    #[cfg(test)]
    fn requests_of(&self, kind: &'static str, outcome: &'static str) -> u64 {
        self.requests.get(&RequestLabels { kind, outcome }).map_or(0, |c| c.get())
    }
}

/// The kinds a query is counted under: [`RouteKind::label`] of the kinds a server
/// answers (the list above must hold them all; checked by a test).
#[cfg(test)]
fn query_kinds() -> impl Iterator<Item = &'static str> {
    use super::routes::RouteKind;
    RouteKind::ALL.into_iter().filter(|k| k.is_query()).map(RouteKind::label)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(text: &str, series: &str) -> Option<f64> {
        text.lines().find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.trim().parse().ok())
    }

    #[test]
    fn every_query_kind_and_error_code_has_its_place() {
        for k in query_kinds() {
            assert!(KINDS.contains(&k), "{k} is not among the pre-made kinds");
        }
        use super::super::error::ServiceError as E;
        let errors = [
            E::Malformed { message: String::new(), field: None },
            E::UnsupportedEncoding(String::new()),
            E::PayloadTooLarge(0, 0),
            E::LimitExceeded { message: String::new(), field: None },
            E::InvalidSceneName(String::new()),
            E::UnknownScene(String::new()),
            E::InvalidRequest { message: String::new(), field: None },
            E::InvalidTrajectory { message: String::new(), field: None },
            E::NoPlan(String::new()),
            E::Busy(0),
            E::DeadlineExceeded(String::new()),
            E::Unavailable(String::new()),
            E::StaleRevision { scene: String::new(), have: 0, want: 0 },
            E::Internal(String::new()),
        ];
        for e in errors {
            assert!(OUTCOMES.contains(&e.code()), "{} is not among the pre-made outcomes", e.code());
        }
    }

    #[test]
    fn counts_and_histograms_per_kind_and_outcome() {
        let m = Metrics::new("primary", "t1");
        m.record("plan", OK, Duration::from_millis(3));
        m.record("plan", OK, Duration::from_millis(40));
        m.record("plan", "no_plan", Duration::from_secs(2));
        m.record("verify", "busy", Duration::from_micros(50));
        m.record(PUT, DROPPED, Duration::ZERO);
        // neither a known kind nor a known outcome: still counted
        m.record("future_kind", "future_code", Duration::from_secs(100));
        assert_eq!(m.requests_of("plan", OK), 2);
        let text = m.encode().unwrap();
        let v = |s: &str| value(&text, s).unwrap_or_else(|| panic!("no {s} in\n{text}"));
        assert_eq!(v(r#"riskplan_requests_total{kind="plan",outcome="ok"}"#), 2.0);
        assert_eq!(v(r#"riskplan_requests_total{kind="plan",outcome="no_plan"}"#), 1.0);
        assert_eq!(v(r#"riskplan_requests_total{kind="verify",outcome="busy"}"#), 1.0);
        assert_eq!(v(r#"riskplan_requests_total{kind="put",outcome="dropped"}"#), 1.0);
        assert_eq!(v(r#"riskplan_requests_total{kind="future_kind",outcome="future_code"}"#), 1.0);
        assert_eq!(v(r#"riskplan_request_duration_seconds_count{kind="plan"}"#), 3.0);
        assert!((v(r#"riskplan_request_duration_seconds_sum{kind="plan"}"#) - 2.043).abs() < 1e-9);
        // cumulative buckets, inclusive upper bounds
        assert_eq!(v(r#"riskplan_request_duration_seconds_bucket{le="0.0025",kind="plan"}"#), 0.0);
        assert_eq!(v(r#"riskplan_request_duration_seconds_bucket{le="0.005",kind="plan"}"#), 1.0);
        assert_eq!(v(r#"riskplan_request_duration_seconds_bucket{le="0.05",kind="plan"}"#), 2.0);
        assert_eq!(v(r#"riskplan_request_duration_seconds_bucket{le="2.5",kind="plan"}"#), 3.0);
        assert_eq!(v(r#"riskplan_request_duration_seconds_bucket{le="0.0001",kind="verify"}"#), 1.0);
        assert_eq!(v(r#"riskplan_request_duration_seconds_bucket{le="30.0",kind="future_kind"}"#), 0.0);
        assert_eq!(v(r#"riskplan_request_duration_seconds_bucket{le="+Inf",kind="future_kind"}"#), 1.0);
        // every kind's histogram exists from the start
        assert_eq!(v(r#"riskplan_request_duration_seconds_count{kind="risk"}"#), 0.0);
        assert!(text.contains("# TYPE riskplan_request_duration_seconds histogram"), "{text}");
        assert!(text.contains("# UNIT riskplan_request_duration_seconds seconds"), "{text}");
        assert!(text.contains(r#"riskplan_build_info{version=""#), "{text}");
        assert!(text.contains(r#"role="primary",server_id="t1"} 1"#), "{text}");
        assert!(text.ends_with("# EOF\n"), "{text}");
        // no sampler: no state metrics (and no error)
        assert!(!text.contains("riskplan_queue_depth"), "{text}");
    }

    #[test]
    fn the_state_is_read_at_each_scrape() {
        let m = Metrics::new("replica", "r-1");
        let snap = Snapshot {
            ready: true,
            queue_depth: 3,
            jobs_running: 2,
            workers: 2,
            queue_capacity: 64,
            scenes: vec![("a".into(), 7), ("b.c".into(), 1)],
            contours: (5, 9, 4),
            kernels: super::super::registry::KernelCounts {
                covers_hits: 10,
                covers_misses: 2,
                covers_built: 1,
                body_hits: 3,
                body_misses: 1,
                warm_ups_done: 4,
                warm_ups_stopped: 5,
                warm_ups_skipped: 6,
            },
        };
        let shared = Arc::new(std::sync::Mutex::new(snap));
        let s = shared.clone();
        m.set_sampler(move || s.lock().ok().map(|s| s.clone()));
        let text = m.encode().unwrap();
        let v = |t: &str, s: &str| value(t, s).unwrap_or_else(|| panic!("no {s} in\n{t}"));
        assert_eq!(v(&text, "riskplan_ready"), 1.0);
        assert_eq!(v(&text, "riskplan_queue_depth"), 3.0);
        assert_eq!(v(&text, "riskplan_jobs_running"), 2.0);
        assert_eq!(v(&text, "riskplan_workers"), 2.0);
        assert_eq!(v(&text, "riskplan_queue_capacity"), 64.0);
        assert_eq!(v(&text, "riskplan_scenes"), 2.0);
        assert_eq!(v(&text, r#"riskplan_scene_revision{scene="a"}"#), 7.0);
        assert_eq!(v(&text, r#"riskplan_scene_revision{scene="b.c"}"#), 1.0);
        assert_eq!(v(&text, r#"riskplan_scene_cache_hits_total{cache="contours"}"#), 9.0);
        assert_eq!(v(&text, r#"riskplan_scene_cache_misses_total{cache="contours"}"#), 4.0);
        assert_eq!(v(&text, r#"riskplan_scene_cache_hits_total{cache="covers"}"#), 10.0);
        assert_eq!(v(&text, r#"riskplan_scene_cache_misses_total{cache="covers"}"#), 2.0);
        assert_eq!(v(&text, r#"riskplan_scene_cache_hits_total{cache="body"}"#), 3.0);
        assert_eq!(v(&text, r#"riskplan_scene_cache_misses_total{cache="body"}"#), 1.0);
        assert_eq!(v(&text, "riskplan_contour_cache_entries"), 5.0);
        assert_eq!(v(&text, "riskplan_covers_built_total"), 1.0);
        assert_eq!(v(&text, r#"riskplan_scene_warm_ups_total{outcome="done"}"#), 4.0);
        assert_eq!(v(&text, r#"riskplan_scene_warm_ups_total{outcome="stopped"}"#), 5.0);
        assert_eq!(v(&text, r#"riskplan_scene_warm_ups_total{outcome="skipped"}"#), 6.0);
        assert!(text.contains(r#"role="replica",server_id="r-1"} 1"#), "{text}");
        // a scene deleted is gone at the next scrape
        if let Ok(mut s) = shared.lock() {
            s.scenes.retain(|(n, _)| n != "a");
        }
        let text = m.encode().unwrap();
        assert!(!text.contains(r#"scene="a""#), "{text}");
        assert_eq!(v(&text, "riskplan_scenes"), 1.0);
        assert!(text.ends_with("# EOF\n"), "{text}");
    }

    #[test]
    fn the_exposition_parses_as_openmetrics_lines() {
        let m = Metrics::new("primary", "x");
        m.record("status", OK, Duration::from_micros(120));
        let text = m.encode().unwrap();
        for line in text.lines() {
            if line.starts_with('#') {
                assert!(
                    ["# HELP ", "# TYPE ", "# UNIT ", "# EOF"].iter().any(|p| line.starts_with(p)),
                    "bad comment line {line:?}"
                );
                continue;
            }
            let (series, v) = line.rsplit_once(' ').unwrap_or_else(|| panic!("no value in {line:?}"));
            assert!(series.starts_with("riskplan_"), "{line:?}");
            assert!(v.parse::<f64>().is_ok(), "bad value in {line:?}");
        }
    }
}
