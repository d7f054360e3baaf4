//! The Zenoh planning service (layer L4, feature `service`): key expressions and
//! messages of `proto/README.md`, a registry of scenes with their cached contours,
//! durable updates, and a bounded blocking pool for certification and planning —
//! never computing on the async runtime.
//!
//! Feature `proto` builds the messages, errors, registry and handlers alone (no
//! transport, no async); `service` adds the Zenoh server and client, and the opt-in
//! Prometheus metrics with their HTTP endpoint (`serve --metrics`).
//!
//! A crate sees only the layers below it: an upward `use` (here of `riskplan`,
//! a layer above this one) does not compile.
//!
//! ```compile_fail,E0432
//! use riskplan::cli::run;
//! ```

#[cfg(feature = "transport")]
pub mod client;
pub mod error;
pub mod handlers;
#[cfg(feature = "transport")]
mod jobs;
#[cfg(feature = "transport")]
mod metrics;
#[cfg(feature = "transport")]
mod metrics_http;
pub mod proto;
#[cfg(feature = "transport")]
mod puts;
#[cfg(feature = "transport")]
mod queries;
pub mod registry;
#[cfg(feature = "transport")]
mod replication;
#[cfg(feature = "transport")]
pub mod routes;
pub mod schema;
#[cfg(feature = "transport")]
pub mod server;
#[cfg(feature = "transport")]
mod startup;
#[cfg(feature = "transport")]
mod state;
pub mod store;
#[cfg(feature = "transport")]
mod warm;

#[cfg(feature = "transport")]
pub use client::{Client, ClientError};
pub use error::{MetricsError, ServiceError};
#[cfg(feature = "transport")]
/// Threads for writes besides the workers (see `jobs`).
pub use jobs::WRITE_LANES;
#[cfg(feature = "transport")]
pub use routes::{Route, RouteError, RouteKind};
#[cfg(feature = "transport")]
pub use server::{serve, ServerConfig};
