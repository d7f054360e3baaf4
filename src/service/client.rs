//! A Rust client of the service (bincode by default, JSON on request).

use super::proto::*;
use super::routes::Route;
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::time::Duration;
use thiserror::Error;
use zenoh::bytes::Encoding;
use zenoh::query::{ConsolidationMode, QueryTarget};

/// What can go wrong with a request.
#[derive(Debug, Error)]
pub enum ClientError {
    /// Zenoh could not connect or send.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// The server answered with a typed error.
    #[error("{}: {}{}", .0.code, .0.message, .0.field.as_ref().map(|f| format!(" (field {f})")).unwrap_or_default())]
    Server(ErrorReply),
    /// No reply at all: no server, it died during the query, or access control denied
    /// the query (Zenoh drops denied messages silently).
    #[error("no reply: is `riskplan serve` running and reachable, and may this client's role send this query?")]
    NoReply,
    /// The query timed out.
    #[error("the query timed out")]
    Timeout,
    /// A reply that does not decode.
    #[error("cannot decode the reply: {0}")]
    Decode(String),
}

/// Pause before a read that got no reply at all is sent again.
const RETRY_PAUSE: Duration = Duration::from_millis(50);

/// A connection to a riskplan server (cheap to clone: the Zenoh session is shared).
#[derive(Clone)]
pub struct Client {
    session: zenoh::Session,
    codec: Codec,
    timeout: Duration,
}

impl Client {
    /// Connects in client mode to `endpoint` (e.g. `tcp/127.0.0.1:7447`), multicast off.
    pub async fn connect(endpoint: &str, timeout: Duration, codec: Codec) -> Result<Client, ClientError> {
        let z = |e: zenoh::Error| ClientError::Zenoh(e.to_string());
        let mut c = zenoh::Config::default();
        c.insert_json5("mode", r#""client""#).map_err(z)?;
        c.insert_json5("connect/endpoints", &serde_json::to_string(&[endpoint]).unwrap_or_default()).map_err(z)?;
        c.insert_json5("scouting/multicast/enabled", "false").map_err(z)?;
        Client::connect_with(c, timeout, codec).await
    }

    /// Connects with a full Zenoh configuration (e.g. a role's configuration of the
    /// secure deployment in `deploy/secure`: TLS, user and password).
    pub async fn connect_with(config: zenoh::Config, timeout: Duration, codec: Codec) -> Result<Client, ClientError> {
        let session = zenoh::open(config).await.map_err(|e| ClientError::Zenoh(e.to_string()))?;
        Ok(Client { session, codec, timeout })
    }

    /// One query on `route`; a read ([`Route::is_read`]) that got no reply at all is
    /// sent again while the timeout allows.
    async fn query<Req: Serialize, Rep: DeserializeOwned>(
        &self,
        route: &Route,
        req: Option<&Req>,
        timeout: Duration,
    ) -> Result<Rep, ClientError> {
        let enc = match self.codec {
            Codec::Json => Encoding::APPLICATION_JSON,
            Codec::Bincode => Encoding::from(BINCODE),
        };
        let mut get = self
            .session
            .get(route.key())
            .consolidation(ConsolidationMode::None)
            .target(QueryTarget::BestMatching)
            .timeout(timeout);
        if let Some(r) = req {
            get = get.payload(self.codec.encode(r)).encoding(enc);
        }
        let started = std::time::Instant::now();
        let replies = get.await.map_err(|e| ClientError::Zenoh(e.to_string()))?;
        let Ok(reply) = replies.recv_async().await else {
            // No reply to a read: the server that took it died (or none is up yet).
            // Reads are safe to repeat and another server of a cluster takes the next
            // query (deploy/cluster); writes (apply) are never repeated.
            let left = timeout.saturating_sub(started.elapsed() + RETRY_PAUSE);
            if route.is_read() && !left.is_zero() {
                tokio::time::sleep(RETRY_PAUSE).await;
                return Box::pin(self.query(route, req, left)).await;
            }
            return Err(ClientError::NoReply);
        };
        match reply.result() {
            Ok(sample) => {
                let codec = Codec::from_encoding(&sample.encoding().to_string()).unwrap_or(self.codec);
                codec.decode(&sample.payload().to_bytes()).map_err(|(m, _)| ClientError::Decode(m))
            }
            Err(err) => {
                let codec = Codec::from_encoding(&err.encoding().to_string()).unwrap_or(Codec::Json);
                match codec.decode::<ErrorReply>(&err.payload().to_bytes()) {
                    Ok(e) => Err(ClientError::Server(e)),
                    Err(_) => {
                        let text = err.payload().try_to_string().map(|s| s.to_string()).unwrap_or_default();
                        if text.contains("Timeout") {
                            Err(ClientError::Timeout)
                        } else {
                            Err(ClientError::Decode(text))
                        }
                    }
                }
            }
        }
    }

    /// Puts a whole scene (fire and forget).
    pub async fn put_scene(&self, name: &str, scene: &serde_json::Value) -> Result<(), ClientError> {
        self.session
            .put(Route::Scene { name: name.to_string() }.key(), scene.to_string())
            .encoding(Encoding::APPLICATION_JSON)
            .await
            .map_err(|e| ClientError::Zenoh(e.to_string()))
    }

    /// Puts one obstacle (fire and forget).
    pub async fn update_obstacle(&self, name: &str, id: &str, put: &ObstaclePut) -> Result<(), ClientError> {
        self.session
            .put(Route::Obstacle { scene: name.to_string(), id: id.to_string() }.key(), Codec::Json.encode(put))
            .encoding(Encoding::APPLICATION_JSON)
            .await
            .map_err(|e| ClientError::Zenoh(e.to_string()))
    }

    /// Deletes one obstacle (fire and forget).
    pub async fn remove_obstacle(&self, name: &str, id: &str) -> Result<(), ClientError> {
        self.session
            .delete(Route::Obstacle { scene: name.to_string(), id: id.to_string() }.key())
            .await
            .map_err(|e| ClientError::Zenoh(e.to_string()))
    }

    /// Acknowledged update; returns the new revision once persisted.
    pub async fn apply(&self, name: &str, req: &ApplyRequest) -> Result<ApplyReply, ClientError> {
        let mut req = req.clone();
        req.deadline_ms = req.deadline_ms.or(Some(self.deadline_ms()));
        self.query(&Route::Apply { scene: name.to_string() }, Some(&req), self.timeout).await
    }

    /// The deadline sent with apply, verify and risk requests that name none: the
    /// query's timeout. Zenoh does not tell a server that a client gave up, so the
    /// server drops the job when the client stops waiting, not later.
    fn deadline_ms(&self) -> u64 {
        u64::try_from(self.timeout.as_millis()).unwrap_or(u64::MAX).max(1)
    }

    /// Plans (the query's timeout covers the time limit).
    pub async fn plan(&self, name: &str, req: &PlanRequest) -> Result<PlanReply, ClientError> {
        let t = self.timeout + Duration::from_secs_f64(req.time_limit.unwrap_or(10.0).clamp(0.0, 3600.0));
        self.query(&Route::Plan { scene: name.to_string() }, Some(req), t).await
    }

    /// Verifies a trajectory or a segment.
    pub async fn verify(&self, name: &str, req: &VerifyRequest) -> Result<VerifyReply, ClientError> {
        let mut req = req.clone();
        req.deadline_ms = req.deadline_ms.or(Some(self.deadline_ms()));
        self.query(&Route::Verify { scene: name.to_string() }, Some(&req), self.timeout).await
    }

    /// Risk bounds.
    pub async fn risk(&self, name: &str, req: &RiskRequest) -> Result<RiskReply, ClientError> {
        let mut req = req.clone();
        req.deadline_ms = req.deadline_ms.or(Some(self.deadline_ms()));
        self.query(&Route::Risk { scene: name.to_string() }, Some(&req), self.timeout).await
    }

    /// The scene and its revision.
    pub async fn get_scene(&self, name: &str) -> Result<SceneReply, ClientError> {
        self.query::<(), _>(&Route::Scene { name: name.to_string() }, None, self.timeout).await
    }

    /// Server status.
    pub async fn status(&self) -> Result<StatusReply, ClientError> {
        self.query::<(), _>(&Route::Status, None, self.timeout).await
    }

    /// One raw query on `route` for load tests: sends `payload` (in this client's
    /// encoding) and returns (number of replies, the first error code if any). Counts
    /// every reply until the query completes, so "exactly one reply" can be checked.
    pub async fn raw_query(&self, route: &Route, payload: Vec<u8>) -> Result<(usize, Option<String>), ClientError> {
        let enc = match self.codec {
            Codec::Json => Encoding::APPLICATION_JSON,
            Codec::Bincode => Encoding::from(BINCODE),
        };
        let replies = self
            .session
            .get(route.key())
            .payload(payload)
            .encoding(enc)
            .consolidation(ConsolidationMode::None)
            .timeout(self.timeout)
            .await
            .map_err(|e| ClientError::Zenoh(e.to_string()))?;
        let (mut n, mut code) = (0, None);
        while let Ok(r) = replies.recv_async().await {
            n += 1;
            if let Err(e) = r.result() {
                let c = Codec::from_encoding(&e.encoding().to_string()).unwrap_or(Codec::Json);
                code = Some(match c.decode::<ErrorReply>(&e.payload().to_bytes()) {
                    Ok(er) => er.code,
                    Err(_) => "timeout".to_string(),
                });
            }
        }
        Ok((n, code))
    }

    /// Encodes a message in this client's encoding.
    pub fn encode<T: Serialize>(&self, v: &T) -> Vec<u8> {
        self.codec.encode(v)
    }

    /// Closes the session.
    pub async fn close(self) {
        let _ = self.session.close().await;
    }
}
