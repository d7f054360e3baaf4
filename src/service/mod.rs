//! The Zenoh planning service (layer L4, feature `service`): key expressions and
//! messages of `proto/README.md`, a registry of scenes with their cached contours,
//! durable updates, and a bounded blocking pool for certification and planning —
//! never computing on the async runtime.
//!
//! Feature `proto` builds the messages, errors, registry and handlers alone (no
//! transport, no async); `service` adds the Zenoh server and client, and the opt-in
//! Prometheus metrics with their HTTP endpoint (`serve --metrics`).

// Internal parts (the `internal!` macro of lib.rs): the fuzz targets and the tests
// use the handlers, the registry and the store directly, with `test-support`.
internal! {
    #[cfg(feature = "service")]
    client;
    error;
    handlers;
    registry;
    #[cfg(feature = "service")]
    routes;
    #[cfg(feature = "service")]
    server;
    store;
}
#[cfg(feature = "service")]
mod jobs;
#[cfg(feature = "service")]
mod metrics;
#[cfg(feature = "service")]
mod metrics_http;
pub mod proto;
#[cfg(feature = "service")]
mod puts;
#[cfg(feature = "service")]
mod queries;
#[cfg(feature = "service")]
mod replication;
#[cfg(feature = "service")]
mod startup;
#[cfg(feature = "service")]
mod state;
#[cfg(feature = "service")]
mod warm;

#[cfg(feature = "service")]
pub use client::{Client, ClientError};
pub use error::{MetricsError, ServiceError};
#[cfg(feature = "service")]
/// Threads for writes besides the workers (see `jobs`).
pub use jobs::WRITE_LANES;
#[cfg(feature = "service")]
pub use routes::{Route, RouteError, RouteKind};
#[cfg(feature = "service")]
pub use server::{serve, ServerConfig};
