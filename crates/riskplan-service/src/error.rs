//! Typed service errors and their stable wire codes (proto/README.md): each error's
//! [`ErrorCode`], the one list of codes that the replies, the metrics and the schemas use.

pub use super::proto::ErrorCode;
use super::proto::ErrorReply;
use riskplan_plan::PlanError;
use riskplan_scene::SceneError;
use thiserror::Error;

/// Everything a request can fail with.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ServiceError {
    /// Payload does not parse.
    #[error("malformed payload: {message}")]
    Malformed {
        /// Parser message.
        message: String,
        /// Field path.
        field: Option<String>,
    },
    /// Encoding other than JSON or bincode.
    #[error("unsupported encoding '{0}': use application/json or application/bincode")]
    UnsupportedEncoding(String),
    /// Payload over the limit.
    #[error("payload of {0} bytes exceeds the limit of {1} bytes")]
    PayloadTooLarge(usize, usize),
    /// A documented limit.
    #[error("{message}")]
    LimitExceeded {
        /// What.
        message: String,
        /// Field.
        field: Option<String>,
    },
    /// Bad scene name.
    #[error("invalid scene name '{0}': use 1 to 128 characters from A-Z a-z 0-9 _ - .")]
    InvalidSceneName(String),
    /// No such scene.
    #[error("unknown scene '{0}'")]
    UnknownScene(String),
    /// Scene validation failed.
    #[error("invalid scene: {0}")]
    InvalidScene(SceneError),
    /// Bad request field.
    #[error("{message}")]
    InvalidRequest {
        /// What.
        message: String,
        /// Field.
        field: Option<String>,
    },
    /// Bad trajectory.
    #[error("invalid trajectory: {message}")]
    InvalidTrajectory {
        /// What.
        message: String,
        /// Field.
        field: Option<String>,
    },
    /// Planner request error.
    #[error("{0}")]
    Plan(PlanError),
    /// No plan found.
    #[error("{0}")]
    NoPlan(String),
    /// Queue full.
    #[error("the job queue is full ({0} jobs): try again later")]
    Busy(usize),
    /// The request's deadline passed (in the queue or during the work).
    #[error("deadline exceeded: {0}")]
    DeadlineExceeded(String),
    /// The server cannot take the request yet (it is loading its stored scenes).
    #[error("unavailable: {0}")]
    Unavailable(String),
    /// A read asked for a revision of the scene this server does not have yet (a
    /// replica behind its primary), after waiting `MIN_REVISION_WAIT` (1.5 s, proto/README.md "Discovery and load sharing").
    #[error("scene '{scene}' is at revision {have} on this server, the read asked for at least {want}: a replica behind its primary, or a revision that does not exist yet")]
    StaleRevision {
        /// The scene.
        scene: String,
        /// The revision this server has (0: none).
        have: u64,
        /// The revision asked for.
        want: u64,
    },
    /// Our bug.
    #[error("internal error: {0}")]
    Internal(String),
}

impl ServiceError {
    /// The stable code.
    pub fn code(&self) -> ErrorCode {
        use ErrorCode as C;
        match self {
            ServiceError::Malformed { .. } => C::MalformedPayload,
            ServiceError::UnsupportedEncoding(_) => C::UnsupportedEncoding,
            ServiceError::PayloadTooLarge(..) => C::PayloadTooLarge,
            ServiceError::LimitExceeded { .. } => C::LimitExceeded,
            ServiceError::InvalidSceneName(_) => C::InvalidSceneName,
            ServiceError::UnknownScene(_) => C::UnknownScene,
            ServiceError::InvalidScene(_) => C::InvalidScene,
            ServiceError::InvalidRequest { .. } => C::InvalidRequest,
            ServiceError::InvalidTrajectory { .. } => C::InvalidTrajectory,
            ServiceError::Plan(PlanError::OutsideWorkspace { .. }) => C::OutsideWorkspace,
            ServiceError::Plan(PlanError::UnsafeEndpoint { .. }) => C::UnsafeEndpoint,
            // our own SDP model failed: a bug, not the request's fault
            ServiceError::Plan(PlanError::SdpModel { .. }) => C::Internal,
            ServiceError::Plan(_) => C::InvalidRequest,
            ServiceError::NoPlan(_) => C::NoPlan,
            ServiceError::Busy(_) => C::Busy,
            ServiceError::DeadlineExceeded(_) => C::DeadlineExceeded,
            ServiceError::Unavailable(_) => C::Unavailable,
            ServiceError::StaleRevision { .. } => C::StaleRevision,
            ServiceError::Internal(_) => C::Internal,
        }
    }

    /// The field at fault.
    pub fn field(&self) -> Option<String> {
        match self {
            ServiceError::Malformed { field, .. }
            | ServiceError::LimitExceeded { field, .. }
            | ServiceError::InvalidRequest { field, .. }
            | ServiceError::InvalidTrajectory { field, .. } => field.clone(),
            ServiceError::InvalidScene(e) => (!e.path.is_empty()).then(|| e.path.clone()),
            ServiceError::Plan(PlanError::InvalidRequest { field, .. }) => Some(field.clone()),
            ServiceError::Plan(PlanError::OutsideWorkspace { which, .. } | PlanError::UnsafeEndpoint { which, .. }) => {
                Some(which.clone())
            }
            ServiceError::Plan(PlanError::InvalidOption { option, .. }) => Some(option.clone()),
            ServiceError::StaleRevision { .. } => Some("min_revision".into()),
            _ => None,
        }
    }

    /// The wire payload.
    pub fn reply(&self) -> ErrorReply {
        ErrorReply { code: self.code(), message: self.to_string(), field: self.field() }
    }
}

impl From<PlanError> for ServiceError {
    /// A planner option out of range is a request-field error (`invalid_request` with
    /// the option as the field); every other planning error keeps its own code.
    fn from(e: PlanError) -> Self {
        match e {
            PlanError::InvalidOption { option, message } => invalid(&option, message),
            other => ServiceError::Plan(other),
        }
    }
}

/// Shorthand for a request-field error.
pub fn invalid(field: &str, message: impl Into<String>) -> ServiceError {
    ServiceError::InvalidRequest { message: message.into(), field: Some(field.to_string()) }
}

/// What can stop the metrics endpoint (`serve --metrics ADDR`) from starting: the
/// server does not start without it (the flag asked for it).
#[derive(Debug, Error)]
pub enum MetricsError {
    /// The address cannot be listened on (in use, not this host's, a privileged port).
    #[error("--metrics {addr}: cannot listen for metrics scrapes: {source}")]
    Bind {
        /// The address asked for.
        addr: std::net::SocketAddr,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The listener's own address cannot be read back (to print it).
    #[error("--metrics {addr}: the listening socket has no address: {source}")]
    LocalAddr {
        /// The address asked for.
        addr: std::net::SocketAddr,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// `text` without the ` at /path/file.rs:N.` source locations Zenoh's errors carry.
#[cfg(feature = "transport")]
pub(crate) fn strip_source_locations(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find(" at /") {
        out.push_str(&rest[..i]);
        let tail = &rest[i + 4..];
        // the location runs to ".rs:<digits>" and an optional "."
        match tail.find(".rs:") {
            Some(j) => {
                let after = &tail[j + 4..];
                let digits = after.bytes().take_while(u8::is_ascii_digit).count();
                let skip = digits + usize::from(after[digits..].starts_with('.'));
                rest = &after[skip..];
            }
            None => {
                out.push_str(" at ");
                rest = tail;
            }
        }
    }
    out.push_str(rest);
    out
}

#[cfg(all(test, feature = "transport"))]
mod source_location_tests {
    use super::strip_source_locations;

    #[test]
    fn zenoh_source_locations_are_left_out() {
        let z = "Unable to connect to any of [Single(tcp/127.0.0.1:7999)]!  at /root/.cargo/registry/src/x/zenoh-1.10.2/src/net/runtime/orchestrator.rs:447.";
        assert_eq!(strip_source_locations(z).trim_end(), "Unable to connect to any of [Single(tcp/127.0.0.1:7999)]!");
        let nested = "bound to tcp/127.0.0.1:7611: [127.0.0.1:7611: Address already in use (os error 98) at /a/tcp.rs:61.] at /b/unicast.rs:338.";
        assert_eq!(
            strip_source_locations(nested),
            "bound to tcp/127.0.0.1:7611: [127.0.0.1:7611: Address already in use (os error 98)]"
        );
        assert_eq!(strip_source_locations("look at /tmp here"), "look at /tmp here");
    }
}
