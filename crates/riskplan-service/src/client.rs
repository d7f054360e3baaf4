//! A Rust client of the service (bincode by default, JSON on request).

use super::proto::*;
use super::routes::{token_server, Route, SERVER_TOKENS};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use thiserror::Error;
use zenoh::bytes::Encoding;
use zenoh::query::{ConsolidationMode, QueryTarget};

/// What can go wrong with a request.
#[derive(Debug, Error)]
pub enum ClientError {
    /// No Zenoh session could be opened to the endpoint(s): nothing listens there.
    #[error(
        "cannot connect to {endpoint} ({detail}): is `riskplan serve` running there? Start one with \
         `riskplan serve --listen {endpoint}`, or give the endpoint of a running one with --endpoint"
    )]
    Connect {
        /// The endpoint(s) tried.
        endpoint: String,
        /// What Zenoh said, without its source location.
        detail: String,
    },
    /// Zenoh could not send.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// The server answered with a typed error: its message, then its code (and the field).
    #[error("{} ({}{})", .0.message, .0.code, .0.field.as_ref().map(|f| format!(", field {f}")).unwrap_or_default())]
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

/// The live servers a client knows of (from their liveliness tokens) and its queries
/// outstanding at each (proto/README.md, "Discovery").
#[derive(Debug, Default)]
struct Servers {
    /// The servers whose liveliness tokens are up (only the tokens change it).
    live: Vec<String>,
    /// The primary among them (writes go to it, through the shared keys).
    primary: Option<String>,
    outstanding: HashMap<String, usize>,
    /// Servers left out of the choice until the given instant: a read on their own key
    /// got no reply at all (the server went away; its token's departure may come
    /// later, and a restarted server may already have announced itself under the
    /// same id, so it is left out for a while, not forgotten).
    suspended: HashMap<String, std::time::Instant>,
}

/// How often a read waiting on a server's own key looks whether that server's liveliness
/// token is still up (proto/README.md, "Failover"): a read in flight to a server that was
/// killed is not always ended by Zenoh before the query's timeout; once the token goes the
/// read is sent elsewhere at once.
const LIVENESS_POLL: Duration = Duration::from_millis(50);

/// How long a server whose own key left a read without reply is left out of the choice.
const SUSPEND: Duration = Duration::from_secs(1);

/// How long a new client asks for the servers' tokens that are up (in the background).
const TOKENS_TIMEOUT: Duration = Duration::from_secs(2);

/// How long [`Client::connect`] waits for the servers' tokens up at its start (their
/// liveliness query's replies, a few milliseconds on a LAN) before it returns: the reads
/// of a client that asks once — a one-shot `riskplan client` command — are spread over
/// the servers too, instead of going to the shared key, where the primary answers. A
/// discovery slower than this goes on in the background.
const DISCOVERY_WAIT: Duration = Duration::from_millis(500);

impl Servers {
    /// The server for the next read: of two live servers drawn at random, the one with
    /// fewer of this client's queries outstanding (the power of two choices); `None`
    /// when none is known (the read goes to the shared key).
    fn pick(&mut self) -> Option<String> {
        let now = std::time::Instant::now();
        self.suspended.retain(|_, until| *until > now);
        let ready: Vec<&String> = self.live.iter().filter(|id| !self.suspended.contains_key(*id)).collect();
        let n = ready.len();
        match n {
            0 => None,
            1 => Some(ready[0].clone()),
            _ => {
                let a = rand::random_range(0..n);
                let b = (a + 1 + rand::random_range(0..n - 1)) % n;
                let load = |i: usize| self.outstanding.get(ready[i]).copied().unwrap_or(0);
                Some(ready[if load(b) < load(a) { b } else { a }].clone())
            }
        }
    }

    fn add(&mut self, id: &str, role: Role) {
        if !self.live.iter().any(|s| s == id) {
            self.live.push(id.to_string());
        }
        if role == Role::Primary {
            self.primary = Some(id.to_string());
        }
    }

    fn remove(&mut self, id: &str) {
        self.live.retain(|s| s != id);
        if self.primary.as_deref() == Some(id) {
            self.primary = None;
        }
    }

    fn suspend(&mut self, id: &str) {
        self.suspended.insert(id.to_string(), std::time::Instant::now() + SUSPEND);
    }
}

/// Where a query went: a server's own key, or the shared key (with the server its
/// load is counted against: the primary for a write, when known).
#[derive(Clone, Debug)]
enum Target {
    Own(String),
    Shared(Option<String>),
}

impl Target {
    fn counted(&self) -> Option<&str> {
        match self {
            Target::Own(id) | Target::Shared(Some(id)) => Some(id),
            Target::Shared(None) => None,
        }
    }
}

/// A query in flight, counted at its server until it is finished — or dropped (a
/// caller's timeout or `select!` drops the future: the count must not leak).
struct Pending {
    servers: Arc<Mutex<Servers>>,
    target: Target,
    open: bool,
}

impl Pending {
    fn finish(mut self, no_reply: bool) {
        self.open = false;
        Client::done(&self.servers, &self.target, no_reply);
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if self.open {
            Client::done(&self.servers, &self.target, false);
        }
    }
}

/// A connection to a riskplan server or cluster (cheap to clone: the Zenoh session and
/// the view of the live servers are shared). Reads are spread over the servers whose
/// liveliness tokens it sees (proto/README.md, "Discovery"); writes go to the shared
/// keys, where only the primary takes them.
#[derive(Clone)]
pub struct Client {
    session: zenoh::Session,
    codec: Codec,
    timeout: Duration,
    servers: Arc<Mutex<Servers>>,
    /// Keeps the liveliness subscriber (and its callback) alive.
    _watch: Option<Arc<zenoh::pubsub::Subscriber<()>>>,
    /// Reads of a scene ask for at least this revision of it (`min_revision`): per
    /// scene, or for every scene (`None`).
    min_revision: Option<(Option<String>, u64)>,
}

impl Client {
    /// Connects in client mode to `endpoint` (e.g. `tcp/127.0.0.1:7447`), multicast off.
    pub async fn connect(endpoint: &str, timeout: Duration, codec: Codec) -> Result<Client, ClientError> {
        let z = |e: zenoh::Error| ClientError::Zenoh(e.to_string());
        let mut c = zenoh::Config::default();
        c.insert_json5("mode", r#""client""#).map_err(z)?;
        c.insert_json5("connect/endpoints", &serde_json::to_string(&[endpoint]).unwrap_or_default()).map_err(z)?;
        c.insert_json5("scouting/multicast/enabled", "false").map_err(z)?;
        let mut client = Client::connect_with(c, timeout, codec).await.map_err(|e| match e {
            ClientError::Connect { detail, .. } => ClientError::Connect { endpoint: endpoint.to_string(), detail },
            other => other,
        })?;
        client.discover().await;
        Ok(client)
    }

    /// Connects with a full Zenoh configuration (e.g. a role's configuration of the
    /// secure deployment in `deploy/secure`: TLS, user and password).
    pub async fn connect_with(config: zenoh::Config, timeout: Duration, codec: Codec) -> Result<Client, ClientError> {
        let session = zenoh::open(config).await.map_err(|e| ClientError::Connect {
            endpoint: "the configuration's endpoints".into(),
            detail: super::error::strip_source_locations(&e.to_string()).trim_end().trim_end_matches('!').to_string(),
        })?;
        let servers = Arc::new(Mutex::new(Servers::default()));
        Ok(Client { session, codec, timeout, servers, _watch: None, min_revision: None })
    }

    /// Watches the servers' liveliness tokens (proto/README.md, "Discovery"). Not done
    /// for a configuration of one's own (`connect_with`, e.g. deploy/secure, whose access
    /// control denies the liveliness messages: a denied one could leave the next query
    /// without reply); there every read goes to the shared keys.
    async fn discover(&mut self) {
        let (session, servers) = (self.session.clone(), self.servers.clone());
        // the live servers: their tokens now (history) and as they come and go
        let view = servers.clone();
        // (not the subscriber's own history: where access control denies the liveliness
        // messages, deploy/secure, a denied history request left the next query without
        // reply; the separate get below, when denied, only times out)
        let watch = session
            .liveliness()
            .declare_subscriber(SERVER_TOKENS)
            .callback(move |sample| {
                let Some((id, role)) = token_server(sample.key_expr().as_str()) else { return };
                if let Ok(mut s) = view.lock() {
                    match sample.kind() {
                        zenoh::sample::SampleKind::Put => s.add(id, role),
                        zenoh::sample::SampleKind::Delete => s.remove(id),
                    }
                }
            })
            .await
            .ok()
            .map(Arc::new);
        // the tokens up now: waited for briefly, so that even a client's first read (a
        // one-shot CLI command's only one) can go to any server; the rest in the background
        let (now, view) = (session.clone(), servers.clone());
        let tokens = tokio::spawn(async move {
            let Ok(replies) = now.liveliness().get(SERVER_TOKENS).timeout(TOKENS_TIMEOUT).await else { return };
            while let Ok(r) = replies.recv_async().await {
                if let Ok(sample) = r.result() {
                    if let (Some((id, role)), Ok(mut s)) = (token_server(sample.key_expr().as_str()), view.lock()) {
                        s.add(id, role);
                    }
                }
            }
        });
        // (a timeout leaves the task running: dropping its handle detaches it)
        let _ = tokio::time::timeout(DISCOVERY_WAIT, tokens).await;
        self._watch = watch;
    }

    /// The same client, whose reads of scene `scene` ask for at least `revision` of it
    /// (`min_revision`: a replica that is behind waits briefly for it, else answers
    /// `stale_revision`). Use the revision an `apply` acknowledged to read your write
    /// from any server. Revisions count per scene: reads of other scenes ask nothing.
    pub fn at_least(&self, scene: &str, revision: u64) -> Client {
        Client { min_revision: Some((Some(scene.to_string()), revision)), ..self.clone() }
    }

    /// The same client, whose reads of every scene ask for at least `revision` (for a
    /// client that reads one scene, like the CLI's commands).
    pub fn at_least_everywhere(&self, revision: u64) -> Client {
        Client { min_revision: Some((None, revision)), ..self.clone() }
    }

    /// The ids of the live servers this client sees (their liveliness tokens).
    pub fn servers(&self) -> Vec<String> {
        self.servers.lock().map(|s| s.live.clone()).unwrap_or_default()
    }

    /// Whether server `id`'s liveliness token is up.
    fn is_live(&self, id: &str) -> bool {
        self.servers.lock().map(|s| s.live.iter().any(|x| x == id)).unwrap_or(true)
    }

    /// Where a query on `route` goes: a read to a live server's own key (the power of
    /// two choices, `Servers::pick`), anything else — or a read when no server is
    /// known — to the shared key; with `?min_revision=R` on reads when asked for.
    /// A write (on the shared key) counts as outstanding at the primary, so that reads
    /// lean towards the replicas while it works.
    fn target(&self, route: &Route) -> (String, Pending) {
        let pending = |target| Pending { servers: self.servers.clone(), target, open: true };
        let Ok(mut s) = self.servers.lock() else { return (route.key(), pending(Target::Shared(None))) };
        let (mut key, target) = match route.is_read().then(|| s.pick()).flatten() {
            Some(id) => (route.key_on(&id), Target::Own(id)),
            None => (route.key(), Target::Shared(if route.is_read() { None } else { s.primary.clone() })),
        };
        if let (Some((only, r)), Some(scene)) = (&self.min_revision, route.is_read().then(|| route.scene()).flatten()) {
            if only.as_deref().is_none_or(|o| o == scene) {
                key = format!("{key}?min_revision={r}");
            }
        }
        if let Some(id) = target.counted() {
            *s.outstanding.entry(id.to_string()).or_default() += 1;
        }
        (key, pending(target))
    }

    /// The query is over; `no_reply`: it ended with no reply at all — a server that
    /// took it on its own key went away: leave it out for [`SUSPEND`].
    fn done(servers: &Mutex<Servers>, target: &Target, no_reply: bool) {
        let Ok(mut s) = servers.lock() else { return };
        if let Some(n) = target.counted().and_then(|id| s.outstanding.get_mut(id)) {
            *n = n.saturating_sub(1);
        }
        if let (Target::Own(id), true) = (target, no_reply) {
            s.suspend(id);
        }
    }

    /// The status of server `id` (a query on its own key).
    pub async fn status_of(&self, id: &str) -> Result<StatusReply, ClientError> {
        let replies = self
            .session
            .get(Route::Status.key_on(id))
            .consolidation(ConsolidationMode::None)
            .timeout(self.timeout)
            .await
            .map_err(|e| ClientError::Zenoh(e.to_string()))?;
        let reply = replies.recv_async().await.map_err(|_| ClientError::NoReply)?;
        match reply.result() {
            Ok(sample) => {
                let codec = Codec::from_encoding(&sample.encoding().to_string()).unwrap_or(Codec::Json);
                codec.decode(&sample.payload().to_bytes()).map_err(|(m, _)| ClientError::Decode(m))
            }
            Err(e) => Err(ClientError::Decode(e.payload().try_to_string().map(|s| s.to_string()).unwrap_or_default())),
        }
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
        let (key, pending) = self.target(route);
        let own = matches!(pending.target, Target::Own(_));
        let mut get = self
            .session
            .get(key)
            .consolidation(ConsolidationMode::None)
            .target(QueryTarget::BestMatching)
            .timeout(timeout);
        if let Some(r) = req {
            get = get.payload(self.codec.encode(r)).encoding(enc);
        }
        let started = std::time::Instant::now();
        let replies = match get.await {
            Ok(r) => r,
            Err(e) => {
                pending.finish(false);
                return Err(ClientError::Zenoh(e.to_string()));
            }
        };
        // a read on a server's own key is waited for only while its token is up
        let first = match &pending.target {
            Target::Own(id) => {
                let gone = async {
                    while self.is_live(id) {
                        tokio::time::sleep(LIVENESS_POLL).await;
                    }
                };
                tokio::select! {
                    r = replies.recv_async() => r.ok(),
                    () = gone => None,
                }
            }
            Target::Shared(_) => replies.recv_async().await.ok(),
        };
        pending.finish(first.is_none());
        let Some(reply) = first else {
            // No reply to a read: the server that took it died (or none is up yet), or
            // its token went while it held the read. Reads are safe to repeat (a late
            // reply to the abandoned one is dropped with its receiver): the next goes to
            // another live server (or the shared key, where Zenoh routes it to one);
            // writes (apply) are never repeated.
            let left = timeout.saturating_sub(started.elapsed() + RETRY_PAUSE);
            if route.is_read() && !left.is_zero() {
                if !own {
                    tokio::time::sleep(RETRY_PAUSE).await;
                }
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
    /// encoding) and returns (number of replies, the last error code if any: an error
    /// reply's code, or `timeout` for an error that is no error reply). Counts every
    /// reply until the query completes, so "exactly one reply" can be checked.
    pub async fn raw_query(&self, route: &Route, payload: Vec<u8>) -> Result<(usize, Option<String>), ClientError> {
        let enc = match self.codec {
            Codec::Json => Encoding::APPLICATION_JSON,
            Codec::Bincode => Encoding::from(BINCODE),
        };
        let (key, pending) = self.target(route);
        let replies = match self
            .session
            .get(key)
            .payload(payload)
            .encoding(enc)
            .consolidation(ConsolidationMode::None)
            .timeout(self.timeout)
            .await
        {
            Ok(r) => r,
            Err(e) => {
                pending.finish(false);
                return Err(ClientError::Zenoh(e.to_string()));
            }
        };
        let (mut n, mut code) = (0, None);
        let mut pending = Some(pending);
        while let Ok(r) = replies.recv_async().await {
            if let Some(p) = pending.take() {
                p.finish(false);
            }
            n += 1;
            if let Err(e) = r.result() {
                let c = Codec::from_encoding(&e.encoding().to_string()).unwrap_or(Codec::Json);
                code = Some(match c.decode::<ErrorReply>(&e.payload().to_bytes()) {
                    Ok(er) => er.code.as_str().to_string(),
                    Err(_) => "timeout".to_string(),
                });
            }
        }
        if let Some(p) = pending.take() {
            p.finish(true);
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
