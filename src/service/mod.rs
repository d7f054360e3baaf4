//! The Zenoh planning service (layer L4, feature `service`): key expressions and
//! messages of `proto/README.md`, a registry of scenes with their cached contours,
//! durable updates, and a bounded blocking pool for certification and planning —
//! never computing on the async runtime.

pub mod client;
pub mod error;
pub mod handlers;
pub mod proto;
pub mod registry;
pub mod server;
pub mod store;

pub use client::{Client, ClientError};
pub use error::ServiceError;
pub use server::{serve, ServerConfig};
