//! The server's Prometheus metrics (`serve --metrics ADDR`; every name, type and label is
//! listed in proto/README.md, "Metrics"), in one struct made once at start and shared
//! (`Arc`) by the parts that record: queries and puts count each request under its kind
//! and outcome and time it. Recording is lock-free: an atomic add on a counter resolved
//! once per (kind, outcome) and an atomic add on a bucket of the kind's histogram. What
//! the server holds — its queue, its scenes, its caches — is read when Prometheus
//! scrapes (a [`Collector`] over a [`Snapshot`] of the server's state), never kept in
//! step on the hot path.
//!
//! The registry is written in either of two text formats ([`Format`]): OpenMetrics 1.0.0
//! or the Prometheus text format 0.0.4, both by prometheus-client's encoders. The HTTP
//! side, which picks the format from a scrape's `Accept` header, is `metrics_http.rs`;
//! this module knows nothing of the server's state but the [`Snapshot`] its sampler
//! returns (set by `server.rs`).

use super::error::ServiceError;
use super::proto::{ErrorCode, Role};
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

/// The text exposition a scrape is answered with (`metrics_http` picks one from the
/// request's `Accept` header): both carry the same samples under the same names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Format {
    /// OpenMetrics 1.0.0, the default: a counter's family is named without `_total` (its
    /// samples carry it), `# UNIT` lines, the `info` type, and a final `# EOF`.
    OpenMetrics,
    /// The Prometheus text format 0.0.4, for the classic tools (`promtool check metrics`,
    /// agents that predate OpenMetrics): `# HELP` and `# TYPE` under the sample names
    /// (`…_total` for counters), the info family a gauge named `…_info`, no `# UNIT`, no
    /// `# EOF`.
    Text,
}

impl Format {
    /// The `Content-Type` of a reply in this format.
    pub(crate) const fn content_type(self) -> &'static str {
        match self {
            Format::OpenMetrics => OPENMETRICS_CONTENT_TYPE,
            Format::Text => TEXT_CONTENT_TYPE,
        }
    }
}

/// The media type of the OpenMetrics 1.0.0 text exposition (OpenMetrics 1.0, "Overall
/// Structure": `application/openmetrics-text; version=1.0.0; charset=utf-8`).
pub(crate) const OPENMETRICS_CONTENT_TYPE: &str = "application/openmetrics-text; version=1.0.0; charset=utf-8";

/// The media type of the Prometheus text exposition format 0.0.4 (Prometheus's
/// "Exposition formats"; what Go's `expfmt.FmtText` and prometheus-client's
/// `prometheus_text::CONTENT_TYPE` say).
pub(crate) const TEXT_CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

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

/// The outcomes: `ok`, a dropped put, and every error code ([`ErrorCode::ALL`], the list
/// `ServiceError::code` returns from, by its wire name). Their (kind, outcome) counters are
/// made on first use and then reached without a lock; an outcome not listed here is still
/// counted, through the family's lock.
const OUTCOMES: [&str; 2 + ErrorCode::ALL.len()] = {
    let mut o = [""; 2 + ErrorCode::ALL.len()];
    o[0] = OK;
    o[1] = DROPPED;
    let mut i = 0;
    while i < ErrorCode::ALL.len() {
        o[2 + i] = ErrorCode::ALL[i].as_str();
        i += 1;
    }
    o
};

/// The outcome of a request answered with `result`: `ok`, or its error's code.
pub(crate) fn outcome<T>(result: &Result<T, ServiceError>) -> &'static str {
    result.as_ref().map_or_else(|e| e.code().as_str(), |_| OK)
}

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
    pub(crate) fn new(role: Role, server_id: &str) -> Metrics {
        let mut registry = Registry::with_prefix(PREFIX);
        registry.register(
            "build",
            "The riskplan build and this server: version, git commit (unknown when built without git), role \
             (primary or replica) and server id",
            Info::new(vec![
                ("version", env!("CARGO_PKG_VERSION").to_string()),
                ("commit", riskplan_app::GIT_COMMIT.to_string()),
                ("role", role.as_str().to_string()),
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

    /// The text exposition of every metric in `format`: OpenMetrics 1.0.0 ending with
    /// `# EOF` (prometheus-client's `encoding::text`), or the Prometheus text format
    /// 0.0.4 (its `encoding::prometheus_text`, since 0.26: the same registry and the same
    /// collector, written with the 0.0.4 names and types).
    pub(crate) fn encode(&self, format: Format) -> Result<String, std::fmt::Error> {
        let mut out = String::with_capacity(8 << 10);
        match format {
            Format::OpenMetrics => prometheus_client::encoding::text::encode(&mut out, &self.registry)?,
            Format::Text => prometheus_client::encoding::prometheus_text::encode(&mut out, &self.registry)?,
        }
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
            assert!(OUTCOMES.contains(&e.code().as_str()), "{} is not among the pre-made outcomes", e.code());
            assert_eq!(outcome::<()>(&Err(e.clone())), e.code().as_str());
        }
    }

    #[test]
    fn counts_and_histograms_per_kind_and_outcome() {
        let m = Metrics::new(Role::Primary, "t1");
        m.record("plan", OK, Duration::from_millis(3));
        m.record("plan", OK, Duration::from_millis(40));
        m.record("plan", "no_plan", Duration::from_secs(2));
        m.record("verify", "busy", Duration::from_micros(50));
        m.record(PUT, DROPPED, Duration::ZERO);
        // neither a known kind nor a known outcome: still counted
        m.record("future_kind", "future_code", Duration::from_secs(100));
        assert_eq!(m.requests_of("plan", OK), 2);
        let text = m.encode(Format::OpenMetrics).unwrap();
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
        let m = Metrics::new(Role::Replica, "r-1");
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
        let text = m.encode(Format::OpenMetrics).unwrap();
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
        let text = m.encode(Format::OpenMetrics).unwrap();
        assert!(!text.contains(r#"scene="a""#), "{text}");
        assert_eq!(v(&text, "riskplan_scenes"), 1.0);
        assert!(text.ends_with("# EOF\n"), "{text}");
    }

    /// A Metrics that recorded every pre-made (kind, outcome), a kind and an outcome
    /// outside the lists, and a full state snapshot: every family the server writes.
    fn everything() -> Metrics {
        let m = Metrics::new(Role::Primary, "every-1");
        for (i, &kind) in KINDS.iter().enumerate() {
            for (j, &outcome) in OUTCOMES.iter().enumerate() {
                m.record(kind, outcome, Duration::from_micros(((i * OUTCOMES.len() + j) as u64 * 7919) % 40_000_000));
            }
        }
        m.record("future_kind", "future_code", Duration::from_secs(100));
        let snap = Snapshot {
            ready: true,
            queue_depth: 1,
            jobs_running: 1,
            workers: 2,
            queue_capacity: 64,
            scenes: vec![("a".into(), 3), ("b.c-d_e".into(), 1)],
            contours: (5, 9, 4),
            kernels: super::super::registry::KernelCounts {
                covers_hits: 1,
                covers_misses: 2,
                covers_built: 3,
                body_hits: 4,
                body_misses: 5,
                warm_ups_done: 6,
                warm_ups_stopped: 7,
                warm_ups_skipped: 8,
            },
        };
        m.set_sampler(move || Some(snap.clone()));
        m
    }

    /// The samples of an exposition as series → value, each series written one way: its
    /// labels sorted, `le` as the number it stands for (the encoders differ in both: the
    /// OpenMetrics one writes `{le="30.0",kind="plan"}`, the 0.0.4 one, as Go's clients
    /// do, `{kind="plan",le="30"}`). Label values here hold no `",`.
    fn samples(text: &str) -> std::collections::BTreeMap<String, f64> {
        text.lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| {
                let (series, v) = l.rsplit_once(' ').unwrap_or_else(|| panic!("no value in {l:?}"));
                let series = match series.split_once('{') {
                    None => series.to_string(),
                    Some((name, labels)) => {
                        let labels = labels.strip_suffix('}').unwrap_or_else(|| panic!("{l:?}"));
                        let mut labels: Vec<String> = labels
                            .split("\",")
                            .map(|p| match p.strip_prefix("le=\"") {
                                Some(le) => {
                                    let le: f64 = le.trim_end_matches('"').parse().unwrap_or_else(|_| panic!("{l:?}"));
                                    format!("le=\"{le}")
                                }
                                None => p.trim_end_matches('"').to_string(),
                            })
                            .collect();
                        labels.sort();
                        format!("{name}{{{}\"}}", labels.join("\","))
                    }
                };
                (series, v.parse().unwrap_or_else(|_| panic!("bad value in {l:?}")))
            })
            .collect()
    }

    #[test]
    fn the_text_format_names_every_sample_family_as_prometheus_0_0_4_does() {
        let m = everything();
        let text = m.encode(Format::Text).unwrap();
        // the families in order: (name, type) from each HELP line and the TYPE line after it
        let lines: Vec<&str> = text.lines().collect();
        let mut families: Vec<(&str, &str)> = Vec::new();
        for (i, line) in lines.iter().enumerate() {
            if let Some(rest) = line.strip_prefix("# HELP ") {
                let (name, help) = rest.split_once(' ').unwrap_or_else(|| panic!("no help text: {line:?}"));
                assert!(!help.trim().is_empty(), "empty help: {line:?}");
                let ty = lines
                    .get(i + 1)
                    .and_then(|t| t.strip_prefix("# TYPE "))
                    .and_then(|t| t.strip_prefix(name))
                    .and_then(|t| t.strip_prefix(' '))
                    .unwrap_or_else(|| panic!("no TYPE of {name} after its HELP"));
                assert!(["counter", "gauge", "histogram"].contains(&ty), "{name}: type {ty}");
                assert!(!families.iter().any(|f| f.0 == name), "{name} twice");
                families.push((name, ty));
            } else if line.starts_with('#') {
                assert!(line.starts_with("# TYPE "), "not a 0.0.4 comment: {line:?}");
            }
        }
        // every sample belongs to the family declared last, under that family's name (a
        // histogram's with its _bucket/_sum/_count suffix; a counter's ends in _total)
        let mut current: Option<(&str, &str)> = None;
        for line in &lines {
            if let Some(rest) = line.strip_prefix("# HELP ") {
                let name = rest.split(' ').next().unwrap_or_default();
                current = families.iter().copied().find(|f| f.0 == name);
                continue;
            }
            if line.starts_with('#') {
                continue;
            }
            let (name, ty) = current.unwrap_or_else(|| panic!("a sample before any HELP: {line:?}"));
            let sample = line.split(['{', ' ']).next().unwrap_or_default();
            let ok = match ty {
                "histogram" => ["_bucket", "_sum", "_count"].iter().any(|s| sample == format!("{name}{s}")),
                "counter" => sample == name && name.ends_with("_total"),
                _ => sample == name && !name.ends_with("_total"),
            };
            assert!(ok, "sample {sample} under the {ty} family {name}");
        }
        let of = |name: &str| families.iter().find(|f| f.0 == name).map(|f| f.1);
        assert_eq!(of("riskplan_build_info"), Some("gauge"), "{text}");
        assert_eq!(of("riskplan_requests_total"), Some("counter"), "{text}");
        assert_eq!(of("riskplan_request_duration_seconds"), Some("histogram"), "{text}");
        for c in ["scene_cache_hits", "scene_cache_misses", "covers_built", "scene_warm_ups"] {
            assert_eq!(of(&format!("riskplan_{c}_total")), Some("counter"), "{c}: {text}");
        }
        for g in ["ready", "queue_depth", "jobs_running", "workers", "queue_capacity", "scenes", "scene_revision"] {
            assert_eq!(of(&format!("riskplan_{g}")), Some("gauge"), "{g}: {text}");
        }
        assert_eq!(of("riskplan_contour_cache_entries"), Some("gauge"), "{text}");
        assert_eq!(families.len(), 15, "{families:?}");
        assert!(!text.contains(" info\n") && !text.contains("# UNIT") && !text.contains("# EOF"), "{text}");
        assert!(text.ends_with('\n'), "{text}");
        // the same samples as the OpenMetrics exposition, value for value
        let open = m.encode(Format::OpenMetrics).unwrap();
        let (a, b) = (samples(&text), samples(&open));
        let differ: Vec<_> = a.iter().filter(|(k, v)| b.get(*k) != Some(v)).take(5).collect();
        assert!(
            differ.is_empty() && a.len() == b.len(),
            "{} vs {} samples; first differing: {differ:?}",
            a.len(),
            b.len()
        );
        assert_eq!(samples(&text).len(), text.lines().filter(|l| !l.starts_with('#')).count());
        let requests = samples(&text).keys().filter(|k| k.starts_with("riskplan_requests_total{")).count();
        assert_eq!(requests, KINDS.len() * OUTCOMES.len() + 1);
    }

    #[test]
    fn the_openmetrics_exposition_keeps_its_own_names() {
        let open = everything().encode(Format::OpenMetrics).unwrap();
        assert!(open.contains("# TYPE riskplan_build info\n"), "{open}");
        assert!(open.contains("# TYPE riskplan_requests counter\n"), "{open}");
        assert!(open.contains("# UNIT riskplan_request_duration_seconds seconds\n"), "{open}");
        assert!(open.ends_with("# EOF\n"), "{open}");
    }

    #[test]
    fn each_format_names_its_media_type() {
        assert_eq!(Format::OpenMetrics.content_type(), "application/openmetrics-text; version=1.0.0; charset=utf-8");
        assert_eq!(Format::Text.content_type(), "text/plain; version=0.0.4; charset=utf-8");
        // the crate's own name for what its 0.0.4 encoder writes
        assert_eq!(Format::Text.content_type(), prometheus_client::encoding::prometheus_text::CONTENT_TYPE);
    }

    #[test]
    fn the_exposition_parses_as_openmetrics_lines() {
        let m = Metrics::new(Role::Primary, "x");
        m.record("status", OK, Duration::from_micros(120));
        let text = m.encode(Format::OpenMetrics).unwrap();
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
