//! Puts and deletes (no reply): scenes and obstacles on a primary, the primary's
//! commits on a replica. One put worker applies them in arrival order on a blocking
//! thread, so the loop that receives messages never waits for one.

use super::error::ServiceError;
use super::metrics;
use super::proto::{Codec, ObstaclePut, MAX_PAYLOAD_BYTES};
use super::replication;
use super::routes::{Route, RouteError};
use super::state::State;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;
use tracing::{info, warn};
use zenoh::sample::SampleKind;

/// Puts and deletes waiting for the put worker before new ones are dropped.
pub(crate) const PUT_QUEUE: usize = 256;

/// A put or delete as received: key expression, kind, payload, and when it arrived.
pub(crate) type PutMsg = (String, SampleKind, Vec<u8>, Instant);

/// The put worker: applies puts and deletes one after another, in arrival order, on
/// a blocking thread, so that the loop receiving messages never waits for one. It
/// starts once `loading` (the stored scenes) is done.
pub(crate) fn spawn_put_worker(
    state: Arc<State>,
    loading: tokio::task::JoinHandle<()>,
) -> tokio::sync::mpsc::Sender<PutMsg> {
    let (tx, mut rx) = tokio::sync::mpsc::channel::<PutMsg>(PUT_QUEUE);
    tokio::spawn(async move {
        if let Err(e) = loading.await {
            warn!("loading the stored scenes failed: {e}");
            state.ready.store(true, Ordering::SeqCst);
        }
        while let Some((key, kind, bytes, arrived)) = rx.recv().await {
            let st = state.clone();
            if let Err(e) = tokio::task::spawn_blocking(move || handle_put(&st, &key, kind, &bytes, arrived)).await {
                warn!("put handler failed: {e}");
            }
        }
    });
    tx
}

/// `riskplan/scenes/<scene>` and `.../obstacles/<id>` puts and deletes (a replica:
/// `riskplan/_replication/scenes/<scene>` puts), logged and counted (the metrics: from
/// `arrived`, queue time included).
fn handle_put(state: &Arc<State>, key: &str, kind: SampleKind, bytes: &[u8], arrived: Instant) {
    let route = Route::parse(key);
    let span = tracing::info_span!("put", key = %key);
    let _g = span.enter();
    match apply_put(state, key, route, kind, bytes) {
        Ok(rev) => {
            // (a whole scene committed: warmed in the background, `warm::after_commit`; an
            // obstacle's put or delete is an update of a few obstacles, never warmed)
            let name = match Route::parse(key) {
                Ok(Route::Scene { name } | Route::ReplicationScene { name }) => Some(name),
                _ => None,
            };
            if let (Some(name), Some(rev)) = (name, rev) {
                super::warm::after_commit(state, &name, rev);
            }
            state.count("put", true);
            state.record(metrics::PUT, metrics::OK, arrived.elapsed());
            info!(revision = ?rev, "applied");
        }
        Err(e) => {
            state.count("put", false);
            state.record(metrics::PUT, e.code().as_str(), arrived.elapsed());
            warn!(code = e.code().as_str(), "put rejected: {e}");
        }
    }
}

/// Applies one put or delete; the new revision, if any. Keys that take no puts are
/// ignored.
fn apply_put(
    state: &State,
    key: &str,
    route: Result<Route, RouteError>,
    kind: SampleKind,
    bytes: &[u8],
) -> Result<Option<u64>, ServiceError> {
    let malformed = |(message, field)| ServiceError::Malformed { message, field };
    let size = || {
        if bytes.len() > MAX_PAYLOAD_BYTES {
            Err(ServiceError::PayloadTooLarge(bytes.len(), MAX_PAYLOAD_BYTES))
        } else {
            Ok(())
        }
    };
    match (route, kind) {
        (Ok(Route::ReplicationScene { name }), SampleKind::Put) if state.replica => {
            replication::install_published(state, key, &name, bytes)
        }
        (Ok(Route::Scene { name }), SampleKind::Put) => {
            size()?;
            let json: serde_json::Value = Codec::Json.decode(bytes).map_err(malformed)?;
            state.registry.put_scene(&name, json).map(Some)
        }
        (Ok(Route::Scene { name }), SampleKind::Delete) => state.registry.delete_scene(&name).map(|_| None),
        (Ok(Route::Obstacle { scene, id }), SampleKind::Put) => {
            size()?;
            let put: ObstaclePut = Codec::Json.decode(bytes).map_err(malformed)?;
            state.registry.put_obstacle(&scene, &id, &put).map(Some)
        }
        (Ok(Route::Obstacle { scene, id }), SampleKind::Delete) => {
            state.registry.delete_obstacle(&scene, &id).map(Some)
        }
        _ => Ok(None),
    }
}
