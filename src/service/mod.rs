//! The Zenoh planning service (layer L4, feature `service`): key expressions and
//! messages of `proto/README.md`, a registry of scenes with their cached contours,
//! durable updates, and a bounded blocking pool for certification and planning —
//! never computing on the async runtime.
//!
//! Feature `proto` builds the messages, errors, registry and handlers alone (no
//! transport, no async); `service` adds the Zenoh server and client.

#[cfg(feature = "service")]
pub mod client;
pub mod error;
pub mod handlers;
#[cfg(feature = "service")]
pub(crate) mod jobs;
pub mod proto;
#[cfg(feature = "service")]
pub(crate) mod puts;
#[cfg(feature = "service")]
pub(crate) mod queries;
pub mod registry;
#[cfg(feature = "service")]
pub(crate) mod replication;
#[cfg(feature = "service")]
pub mod routes;
#[cfg(feature = "service")]
pub mod server;
#[cfg(feature = "service")]
pub(crate) mod startup;
#[cfg(feature = "service")]
pub(crate) mod state;
pub mod store;

#[cfg(feature = "service")]
pub use client::{Client, ClientError};
pub use error::ServiceError;
#[cfg(feature = "service")]
pub use routes::{Route, RouteError, RouteKind};
#[cfg(feature = "service")]
pub use server::{serve, ServerConfig};
