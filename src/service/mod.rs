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
pub mod proto;
pub mod registry;
#[cfg(feature = "service")]
pub mod server;
pub mod store;

#[cfg(feature = "service")]
pub use client::{Client, ClientError};
pub use error::ServiceError;
#[cfg(feature = "service")]
pub use server::{serve, ServerConfig};
