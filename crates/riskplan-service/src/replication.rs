//! Replication (deploy/cluster): a primary publishes each commit and answers the
//! catch-up queries; a replica installs what is published and, every
//! [`SYNC_INTERVAL`], compares its versions with the primary's index and fetches what
//! it missed.

use super::error::{invalid, ServiceError};
use super::proto::{Codec, ReplicationEntry, ReplicationIndex};
use super::registry::{Commit, CommitListener};
use super::routes::Route;
use super::state::State;
use super::store::embedded;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tracing::{info, warn};
use zenoh::bytes::Encoding;

/// How often a replica compares its versions with the primary's index and fetches
/// what it missed (a lost publication is caught up within this).
pub(crate) const SYNC_INTERVAL: Duration = Duration::from_secs(1);
/// Timeout of a replica's catch-up queries to the primary.
const SYNC_TIMEOUT: Duration = Duration::from_secs(5);

/// A primary publishes each commit on `riskplan/_replication/scenes/<scene>`, in
/// commit order (the registry calls the listener under the scene's write lock).
pub(crate) fn spawn_publisher(state: &Arc<State>, session: zenoh::Session) {
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Commit>();
    state.registry.set_listener(CommitListener::new(move |c| {
        let _ = tx.send(c.clone());
    }));
    tokio::spawn(async move {
        while let Some(c) = rx.recv().await {
            let key = Route::ReplicationScene { name: c.name.clone() }.key();
            let entry = replication_entry(&c);
            if let Err(e) = session.put(&key, Codec::Json.encode(&entry)).encoding(Encoding::APPLICATION_JSON).await {
                warn!(scene = %c.name, "cannot publish the commit: {e}");
            }
        }
    });
}

/// The primary's answer to `riskplan/_replication/index` (JSON).
pub(crate) fn index_reply(state: &State) -> Vec<u8> {
    let index = ReplicationIndex { primary: state.registry.store_id(), scenes: state.registry.index() };
    Codec::Json.encode(&index)
}

/// The primary's answer to `riskplan/_replication/scenes/<name>` (JSON) and the
/// revision it carries.
pub(crate) fn scene_reply(state: &State, name: &str) -> Result<(Vec<u8>, Option<u64>), ServiceError> {
    let c = state.registry.commit(name)?.ok_or_else(|| ServiceError::UnknownScene(name.to_string()))?;
    Ok((Codec::Json.encode(&replication_entry(&c)), Some(c.revision)))
}

/// A replica installs a commit its primary published on `key`, the key of the scene
/// `name`; the revision installed, `None` when it had it already.
pub(crate) fn install_published(
    state: &State,
    key: &str,
    name: &str,
    bytes: &[u8],
) -> Result<Option<u64>, ServiceError> {
    let entry: ReplicationEntry =
        Codec::Json.decode(bytes).map_err(|(m, f)| ServiceError::Malformed { message: m, field: f })?;
    if entry.name != name {
        return Err(invalid("name", format!("a commit for '{}' published on '{key}'", entry.name)));
    }
    let c = commit_of(entry)?;
    state.registry.install(&c, false).map(|done| done.then_some(c.revision))
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
pub(crate) fn spawn_sync(state: Arc<State>, session: zenoh::Session) {
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

async fn get_json<T: serde::de::DeserializeOwned>(session: &zenoh::Session, route: &Route) -> Result<T, String> {
    let key = route.key();
    let replies = session
        .get(&key)
        .consolidation(zenoh::query::ConsolidationMode::None)
        .timeout(SYNC_TIMEOUT)
        .await
        .map_err(|e| e.to_string())?;
    let reply = replies.recv_async().await.map_err(|_| format!("no primary answered {key}"))?;
    let sample = reply.result().map_err(|e| format!("{key}: {}", e.payload().try_to_string().unwrap_or_default()))?;
    Codec::Json.decode(&sample.payload().to_bytes()).map_err(|(m, _)| format!("{key}: {m}"))
}

async fn sync_once(state: &Arc<State>, session: &zenoh::Session) -> Result<usize, String> {
    let index: ReplicationIndex = get_json(session, &Route::ReplicationIndex).await?;
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
        let entry: ReplicationEntry = match get_json(session, &Route::ReplicationScene { name: name.clone() }).await {
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
            Ok(true) => {
                installed += 1;
                if let Ok(e) = state.registry.get(&name) {
                    super::warm::after_commit(state, &name, e.revision);
                }
            }
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
