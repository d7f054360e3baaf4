//! Queries (get): each parsed once into a [`Route`], answered in its own task with
//! exactly one reply (a success or a typed error), logged and counted under its kind.
//! Computation goes to the job pool, never the async runtime.

use super::error::ServiceError;
use super::handlers;
use super::metrics;
use super::proto::*;
use super::replication;
use super::routes::{query_log_fields, Route, RouteError};
use super::state::State;
use super::store::embedded;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tracing::{info, warn, Instrument};
use zenoh::bytes::Encoding;
use zenoh::query::Query;

fn encoding_of(c: Codec) -> Encoding {
    match c {
        Codec::Json => Encoding::APPLICATION_JSON,
        Codec::Bincode => Encoding::from(BINCODE),
    }
}

/// The largest payload a query on `route` may carry: a `verify` batch may be larger.
fn payload_limit(route: Option<&Route>) -> usize {
    match route {
        Some(Route::Verify { .. }) => MAX_VERIFY_PAYLOAD_BYTES,
        _ => MAX_PAYLOAD_BYTES,
    }
}

/// Answers one query on `route` (the query's key, parsed).
pub(crate) async fn handle_query(state: Arc<State>, query: Query, route: Result<Route, RouteError>) {
    let t0 = Instant::now();
    let (kind, scene) = query_log_fields(&route);
    let span = tracing::info_span!("request", kind = %kind, scene = %scene, planner = tracing::field::Empty, revision = tracing::field::Empty, duration_ms = tracing::field::Empty);
    async move {
        let enc = query.encoding().map(|e| e.to_string()).unwrap_or_default();
        let bytes = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
        let min_revision = min_revision(query.parameters().get("min_revision"));
        let (codec, result) = match (Codec::from_encoding(&enc), min_revision) {
            (None, _) => (Codec::Json, Err(ServiceError::UnsupportedEncoding(enc.clone()))),
            (Some(c), _) if bytes.len() > payload_limit(route.as_ref().ok()) => {
                (c, Err(ServiceError::PayloadTooLarge(bytes.len(), payload_limit(route.as_ref().ok()))))
            }
            (Some(c), Err(e)) => (c, Err(e)),
            (Some(c), Ok(min)) => (
                c,
                dispatch(&state, route.as_ref().ok(), c, bytes, t0, min).await.and_then(|(payload, rev)| {
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
        state.count(kind, ok);
        // before the reply: a client that scrapes after its reply finds it counted
        state.record(kind, metrics::outcome(&result), t0.elapsed());
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
                info!(code = e.code().as_str(), "error reply: {e}");
                let mut reply = e.reply();
                if let ServiceError::UnknownScene(name) = &e {
                    // what this server holds, and the name meant (after the handler: no lock held)
                    let known = state.registry.list();
                    reply.message.push_str(&riskplan_app::names::scene_hint(name, known.iter().map(|k| k.0.as_str())));
                }
                query.reply_err(codec.encode(&reply)).encoding(encoding_of(codec)).await
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

/// How long a read that asks for a revision this server does not have yet waits for
/// it (a replica installs its primary's commits within milliseconds of the
/// acknowledgement, or at its next catch-up, every second, after a lost publication).
pub(crate) const MIN_REVISION_WAIT: Duration = Duration::from_millis(1500);

/// Reads that may wait for a revision at once; more are answered `stale_revision`
/// at once (so that a flood of reads asking for a revision that never comes holds no
/// more than this many tasks).
pub(crate) const MAX_REVISION_WAITERS: usize = 256;

/// The selector parameter `min_revision=R` of a read (proto/README.md, "Revisions").
fn min_revision(v: Option<&str>) -> Result<u64, ServiceError> {
    match v {
        None => Ok(0),
        Some(s) => s
            .trim()
            .parse::<u64>()
            .map_err(|_| crate::error::invalid("min_revision", format!("'{s}' is not a revision (an integer ≥ 0)"))),
    }
}

/// The scene's entry at revision `min` or later: at once when this server has it;
/// otherwise a replica waits for it (its primary's commit, awaited on the registry's
/// commit count: woken by each commit, no polling) until [`MIN_REVISION_WAIT`]
/// after `arrival` or `until` (the request's own deadline), whichever comes first,
/// then answers `stale_revision`. A primary answers at once (no other server makes its
/// revisions); a scene deleted at or after `min` is `unknown_scene`.
async fn entry_at_least(
    state: &State,
    scene: &str,
    min: u64,
    arrival: Instant,
    until: Instant,
) -> Result<super::registry::Entry, ServiceError> {
    let limit = until.min(arrival + MIN_REVISION_WAIT);
    let mut waiting: Option<WaiterSlot<'_>> = None;
    // (subscribed before the first look: a commit after it wakes the wait)
    let mut commits = state.registry.commits();
    loop {
        let have = match state.registry.get(scene) {
            Ok(e) if e.revision >= min => return Ok(e),
            Ok(e) => e.revision,
            Err(e @ ServiceError::UnknownScene(_)) if min == 0 => return Err(e),
            Err(e @ ServiceError::UnknownScene(_)) if state.registry.deleted_at(scene).is_some_and(|r| r >= min) => {
                return Err(e)
            }
            Err(ServiceError::UnknownScene(_)) => 0,
            Err(e) => return Err(e),
        };
        if waiting.is_none() && state.replica {
            waiting = WaiterSlot::take(state);
        }
        if waiting.is_none() || Instant::now() >= limit {
            return Err(ServiceError::StaleRevision { scene: scene.to_string(), have, want: min });
        }
        // the registry's next commit (look again) or the limit (the look above answers)
        let next = tokio::time::timeout_at(tokio::time::Instant::from_std(limit), commits.changed()).await;
        if let Ok(Err(_)) = next {
            // no commit can come any more
            return Err(ServiceError::StaleRevision { scene: scene.to_string(), have, want: min });
        }
    }
}

/// One of the [`MAX_REVISION_WAITERS`] places of a read waiting for a revision, given
/// back when dropped.
struct WaiterSlot<'a>(&'a State);

impl<'a> WaiterSlot<'a> {
    fn take(state: &'a State) -> Option<WaiterSlot<'a>> {
        let before = state.revision_waiters.fetch_add(1, Ordering::SeqCst);
        if before >= MAX_REVISION_WAITERS {
            state.revision_waiters.fetch_sub(1, Ordering::SeqCst);
            return None;
        }
        Some(WaiterSlot(state))
    }
}

impl Drop for WaiterSlot<'_> {
    fn drop(&mut self) {
        self.0.revision_waiters.fetch_sub(1, Ordering::SeqCst);
    }
}

fn malformed((message, field): (String, Option<String>)) -> ServiceError {
    ServiceError::Malformed { message, field }
}

async fn dispatch(
    state: &Arc<State>,
    route: Option<&Route>,
    codec: Codec,
    bytes: Vec<u8>,
    arrival: Instant,
    min: u64,
) -> Result<(Vec<u8>, Option<u64>), ServiceError> {
    // apply, verify and risk: the request's deadline, capped (and defaulted) by the server's
    let deadline = |ms: Option<u64>| {
        let d = ms.map_or(state.max_job_seconds, |ms| Duration::from_millis(ms).min(state.max_job_seconds));
        arrival + d
    };
    match route {
        Some(Route::Status) => return Ok((codec.encode(&state.status()), None)),
        // The bare round trip of the load benchmark: the payload back, no work, no pool.
        Some(Route::Echo) => return Ok((bytes, None)),
        // a replica's catch-up queries (only a primary declares these keys)
        Some(Route::ReplicationIndex) => return Ok((replication::index_reply(state), None)),
        Some(Route::ReplicationScene { name }) => return replication::scene_reply(state, name),
        _ if !state.ready.load(Ordering::SeqCst) => {
            return Err(ServiceError::Unavailable("the server is loading its stored scenes: try again shortly".into()))
        }
        _ => {}
    }
    match route {
        Some(Route::Scene { name: scene }) => {
            let e = entry_at_least(state, scene, min, arrival, arrival + MIN_REVISION_WAIT).await?;
            Ok((codec.encode(&SceneReply { name: scene.to_string(), revision: e.revision, scene: embedded(&e.json) }), Some(e.revision)))
        }
        Some(Route::Apply { scene }) => {
            let req: ApplyRequest = codec.decode(&bytes).map_err(malformed)?;
            let st = state.clone();
            let name = scene.to_string();
            // (a whole scene is warmed in the background; obstacle changes — a crowd's
            // stream of updates — never are: `warm::after_commit`)
            let whole = req.scene.is_some();
            let rev = state
                .jobs
                .run_write(deadline(req.deadline_ms), move || handlers::apply(&st.registry, &name, req))
                .await?;
            if whole {
                super::warm::after_commit(state, scene, rev);
            }
            Ok((codec.encode(&ApplyReply { scene: scene.to_string(), revision: rev }), Some(rev)))
        }
        Some(Route::Plan { scene }) => {
            let req: PlanRequest = codec.decode(&bytes).map_err(malformed)?;
            // waiting for a revision spends the plan's own time limit
            let limit = req.time_limit.and_then(|t| Duration::try_from_secs_f64(t).ok()).unwrap_or(state.max_plan_seconds);
            let entry = entry_at_least(state, scene, min, arrival, arrival + limit.min(state.max_plan_seconds)).await?;
            tracing::Span::current().record("planner", req.planner_name());
            let cap = state.max_plan_seconds;
            let guard = state.cancels.register();
            let cancel = guard.flag.clone();
            let rev = entry.revision;
            // the queue wait counts against the plan's time limit (handlers::plan); a plan
            // can never wait longer than the cap
            let st = state.clone();
            let reply = state
                .jobs
                .run(arrival + cap, move || handlers::plan(&st.registry, &entry, &req, cap, arrival, cancel))
                .await;
            drop(guard);
            let reply = reply?;
            Ok((codec.encode(&reply), Some(rev)))
        }
        Some(Route::Verify { scene }) => {
            let req: VerifyRequest = codec.decode(&bytes).map_err(malformed)?;
            let entry = entry_at_least(state, scene, min, arrival, deadline(req.deadline_ms)).await?;
            let rev = entry.revision;
            let until = deadline(req.deadline_ms);
            // the covers are looked at for the metrics only (a verify may take microseconds)
            let st = state.clone();
            let observe = state.metrics.is_some();
            let reply = state
                .jobs
                .run(until, move || {
                    // a large batch also runs on the workers idle right now (held until it ends)
                    let spare = (handlers::verify_size(&req) >= riskplan_app::verify::PARALLEL_MIN_PIECES)
                        .then(|| st.jobs.spare(st.cores.saturating_sub(1)))
                        .flatten();
                    let threads = 1 + spare.as_ref().map_or(0, |p| p.num_permits());
                    handlers::verify_observed(&entry, &req, until, observe.then_some(&st.registry.kernels), threads)
                })
                .await?;
            Ok((codec.encode(&reply), Some(rev)))
        }
        Some(Route::Risk { scene }) => {
            let req: RiskRequest = codec.decode(&bytes).map_err(malformed)?;
            let entry = entry_at_least(state, scene, min, arrival, deadline(req.deadline_ms)).await?;
            let rev = entry.revision;
            let until = deadline(req.deadline_ms);
            let reply = state.jobs.run(until, move || handlers::risk(&entry, &req, until)).await?;
            Ok((codec.encode(&reply), Some(rev)))
        }
        _ => Err(ServiceError::InvalidRequest { message: "unknown key: use riskplan/status, riskplan/scenes/<scene> or riskplan/scenes/<scene>/{apply,plan,verify,risk}".into(), field: None }),
    }
}
