//! Start-up and readiness: the stored scenes and `--preload` files loaded off the
//! runtime, the queryables declared (status and echo at once, the work keys once the
//! server is ready) and served, and the signals that stop the server.

use super::queries::handle_query;
use super::registry::Registry;
use super::routes::{own_keys, server_token, split_own, Route, RouteError, RouteKind, ALL_KEYS};
use super::state::State;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tracing::{info, warn};
use zenoh::query::Query;

/// A declared queryable.
pub(crate) type Queryable = zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<Query>>;

/// Declares a complete queryable on `key`.
pub(crate) async fn declare(session: &zenoh::Session, key: &str) -> Result<Queryable, String> {
    session.declare_queryable(key).complete(true).await.map_err(|e| format!("cannot declare the queryable {key}: {e}"))
}

/// The keys answered from the start, while the stored scenes load: status and echo.
pub(crate) fn early_keys() -> impl Iterator<Item = &'static str> {
    RouteKind::ALL.into_iter().filter(|k| k.is_early()).map(RouteKind::pattern)
}

/// Answers the queries of one queryable, each in its own task. `skip_early`: leave
/// `status` and `echo` to their own queryables (a primary's `riskplan/**` includes
/// them; a query dropped here gets no reply from this queryable).
pub(crate) async fn serve_queries(state: Arc<State>, q: Queryable, skip_early: bool) {
    // the early queryables (status, echo) take only their own route
    let own = Route::parse(q.key_expr().as_str()).ok().filter(Route::is_early);
    while let Ok(query) = q.recv_async().await {
        let route = Route::parse(query.key_expr().as_str());
        // `riskplan/**` leaves status and echo to their own queryables; those take
        // only their exact key (a wildcard query is answered once, by `riskplan/**`)
        let early = route.as_ref().is_ok_and(Route::is_early);
        if (skip_early && early) || own.as_ref().is_some_and(|o| route.as_ref() != Ok(o)) {
            continue;
        }
        let st = state.clone();
        tokio::spawn(async move { handle_query(st, query, route).await });
    }
}

/// Answers the queries on this server's own keys, `riskplan/@<id>/<rest>`: each as
/// the read `riskplan/<rest>` it stands for; anything but a read is refused (writes
/// go to the shared keys, where only the primary takes them).
pub(crate) async fn serve_own_queries(state: Arc<State>, q: Queryable) {
    while let Ok(query) = q.recv_async().await {
        let key = query.key_expr().as_str().to_string();
        let route = match split_own(&key) {
            Some((id, shared)) if id == state.server_id => Route::parse(&shared),
            _ => Err(RouteError::Unknown(key.clone())),
        };
        let route = match route {
            Ok(r) if !r.is_read() => Err(RouteError::Unknown(key)),
            other => other,
        };
        let st = state.clone();
        tokio::spawn(async move { handle_query(st, query, route).await });
    }
}

/// Declares the work queryables once the server is ready (a primary: `riskplan/**`;
/// a replica: the read keys), and serves them.
pub(crate) async fn serve_when_ready(state: Arc<State>, session: zenoh::Session) {
    while !state.ready.load(Ordering::SeqCst) {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let keys: Vec<&str> = if state.replica {
        RouteKind::ALL.into_iter().filter(|k| k.is_replica_served()).map(RouteKind::pattern).collect()
    } else {
        vec![ALL_KEYS]
    };
    let mut loops = Vec::new();
    for k in keys {
        match declare(&session, k).await {
            Ok(q) => loops.push(tokio::spawn(serve_queries(state.clone(), q, !state.replica))),
            Err(e) => warn!("{e}"),
        }
    }
    // this server's own keys (reads only), then its liveliness token: clients that
    // see the token spread their reads over the live servers (proto/README.md,
    // "Discovery"); the token goes when the session does
    match declare(&session, &own_keys(&state.server_id)).await {
        Ok(q) => loops.push(tokio::spawn(serve_own_queries(state.clone(), q))),
        Err(e) => warn!("{e}"),
    }
    let _token = match session.liveliness().declare_token(server_token(&state.server_id, state.role())).await {
        Ok(t) => Some(t),
        Err(e) => {
            warn!("cannot declare the liveliness token: {e}");
            None
        }
    };
    let n = state.registry.list().len();
    eprintln!("riskplan: ready ({n} scenes{})", if state.replica { ", replica" } else { "" });
    info!(scenes = n, "ready");
    for l in loops {
        let _ = l.await;
    }
}

/// Loads the stored scenes, then the `--preload` files whose names are neither live
/// nor deleted by a client.
pub(crate) fn load_scenes(registry: &Registry, preload: &[PathBuf]) {
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
