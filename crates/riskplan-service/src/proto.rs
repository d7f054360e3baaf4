//! Wire messages of `proto/README.md`, as serde types shared by the server and the
//! Rust client, with the JSON / bincode codec. No field uses
//! `skip_serializing_if` or untagged/internally tagged enums, so that every type
//! round-trips through bincode (which is positional and cannot `deserialize_any`).

use riskplan_app::verify::PieceReport;
use riskplan_plan::PlanStats;
use riskplan_scene::{Piece, Trajectory};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;

/// Largest request payload accepted (a `verify` request: [`MAX_VERIFY_PAYLOAD_BYTES`]).
pub const MAX_PAYLOAD_BYTES: usize = 1 << 20;
/// Largest `verify` request payload accepted: a batch of [`MAX_VERIFY_PIECES`] straight
/// pieces is about 130 bytes each in JSON, 60 in bincode.
pub const MAX_VERIFY_PAYLOAD_BYTES: usize = 32 << 20;
pub use riskplan_app::verify::MAX_VERIFY_PIECES;
/// Largest number of points in one risk query.
pub const MAX_RISK_POINTS: usize = 100_000;
/// Largest grid side in one risk query: a side-`n` grid has `n²` points, so that the
/// point limit holds (316² = 99 856 ≤ 100 000).
pub const MAX_GRID_SIDE: usize = 316;
/// Largest encoded reply. A larger reply is the error `limit_exceeded` (with what to
/// ask for instead), never silence: Zenoh would fail to deliver it.
pub const MAX_REPLY_BYTES: usize = 8 << 20;
/// Most bytes a bincode message may make the decoder allocate. Bincode reads a length
/// before the data it announces; without a limit a 10-byte message claiming a string of
/// 2^40 bytes aborts the process on the allocation. A request is at most
/// [`MAX_PAYLOAD_BYTES`] on the wire, and its decoded form is at most a few dozen times
/// larger (every small number becomes 8 bytes, every list 24 more), so 64 MiB leaves room
/// for every genuine message, requests and the larger replies a client decodes alike.
pub const MAX_DECODE_ALLOCATION: usize = 64 << 20;
/// The bincode encoding name.
pub const BINCODE: &str = "application/bincode";

/// Free-form JSON carried inside a message: as JSON itself in JSON, as a string
/// holding JSON text in bincode (which cannot carry self-describing data).
#[derive(Clone, Debug, PartialEq)]
pub struct EmbeddedJson(pub serde_json::Value);

impl Serialize for EmbeddedJson {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            self.0.serialize(s)
        } else {
            s.serialize_str(&self.0.to_string())
        }
    }
}

impl<'de> Deserialize<'de> for EmbeddedJson {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if d.is_human_readable() {
            serde_json::Value::deserialize(d).map(EmbeddedJson)
        } else {
            let text = String::deserialize(d)?;
            serde_json::from_str(&text).map(EmbeddedJson).map_err(serde::de::Error::custom)
        }
    }
}

/// `apply_request`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ApplyRequest {
    /// A whole scene (format v1).
    #[serde(default)]
    pub scene: Option<EmbeddedJson>,
    /// Obstacle changes, applied in order.
    #[serde(default)]
    pub changes: Option<Vec<Change>>,
    /// How long the server may take, in milliseconds from the request's arrival,
    /// queue time included (default and cap: the server's `--max-job-seconds`). Past it
    /// the reply is the error `deadline_exceeded`.
    #[serde(default)]
    pub deadline_ms: Option<u64>,
}

/// One change of an `apply_request`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Change {
    /// `put` or `delete`.
    pub op: String,
    /// Obstacle id.
    pub id: String,
    /// Polynomial text (put).
    #[serde(default)]
    pub poly: Option<String>,
    /// Parameters it declares or replaces (put): `{name: distribution}`.
    #[serde(default)]
    pub params: Option<EmbeddedJson>,
    /// A pedestrian template (put), instead of `poly` (docs/formats.md §1.5.1).
    #[serde(default)]
    pub pedestrian: Option<EmbeddedJson>,
}

/// `apply_reply`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ApplyReply {
    /// Scene name.
    pub scene: String,
    /// New revision.
    pub revision: u64,
}

/// `obstacle_put`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstaclePut {
    /// Polynomial text.
    pub poly: String,
    /// Parameters it declares or replaces.
    #[serde(default)]
    pub params: Option<EmbeddedJson>,
}

/// `plan_request`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    /// Start (default: the scene's).
    #[serde(default)]
    pub start: Option<Vec<f64>>,
    /// Goal (default: the scene's).
    #[serde(default)]
    pub goal: Option<Vec<f64>>,
    /// A planner by its `PlannerKind` name: `rrt-sos` (the default) or any other that `riskplan plan --help` lists.
    #[serde(default)]
    pub planner: Option<String>,
    /// Seconds (capped by the server).
    #[serde(default)]
    pub time_limit: Option<f64>,
    /// RNG seed.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Pieces of the layered planner.
    #[serde(default)]
    pub pieces: Option<u64>,
    /// Improve step (static scenes).
    #[serde(default)]
    pub improve: Option<bool>,
    /// Δ (default: the scene's).
    #[serde(default)]
    pub delta: Option<f64>,
    /// `exact`, `sos` or `both`.
    #[serde(default)]
    pub certifier: Option<String>,
    /// Speed limit (default: the scene's `planner.max_speed`, else none).
    #[serde(default)]
    pub max_speed: Option<f64>,
    /// Acceleration limit for smoothing (default: the scene's, else none).
    #[serde(default)]
    pub max_accel: Option<f64>,
    /// Shortcut and blend the plan (default true).
    #[serde(default)]
    pub smooth: Option<bool>,
    /// `per-obstacle` (default), `joint`, `joint-weighted` or `trajectory` (the probability
    /// of meeting any obstacle at any time along the plan, docs/design.md §5.14).
    #[serde(default)]
    pub risk_mode: Option<String>,
    /// Which risk bounds may prove safety: `auto` (the tightest sound one) or `cantelli`
    /// (the paper's). Default: the scene's `planner.bound`, else `auto`.
    #[serde(default)]
    pub bound: Option<String>,
    /// A receding-horizon request (docs/design.md §6.9): the current time. With it:
    /// `position`, `horizon` and `goal` are required, `start` is not allowed.
    #[serde(default)]
    pub t_now: Option<f64>,
    /// The robot's position at `t_now`.
    #[serde(default)]
    pub position: Option<Vec<f64>>,
    /// The robot's velocity at `t_now` (default: at rest).
    #[serde(default)]
    pub velocity: Option<Vec<f64>>,
    /// The window's length H: the plan covers `[t_now, t_now + H]` (cut at the scene's
    /// horizon).
    #[serde(default)]
    pub horizon: Option<f64>,
    /// The robot's id: the server keeps its last plan and continues from it (warm start).
    #[serde(default)]
    pub robot_id: Option<String>,
    /// The previous plan's pieces, to continue from (instead of the one kept per robot).
    #[serde(default)]
    pub warm_start: Option<Vec<Piece>>,
    /// The robot's body radius (default: the scene's `robot_radius`, else 0): every
    /// obstacle is grown by it (docs/design.md §3.12).
    #[serde(default)]
    pub robot_radius: Option<f64>,
}

/// `plan_reply`: a trajectory in format v1 with its provenance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanReply {
    /// `riskplan-trajectory/1`.
    pub format: String,
    /// The pieces.
    pub pieces: Vec<Piece>,
    /// Planner.
    pub planner: String,
    /// Every piece proven safe.
    pub certified: bool,
    /// Statistics.
    pub stats: PlanStats,
    /// Scene revision used.
    pub revision: u64,
    /// Scene name.
    pub scene: String,
    /// Δ used.
    pub risk: f64,
}

/// A straight segment to verify.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Segment {
    /// From.
    pub from: Vec<f64>,
    /// To.
    pub to: Vec<f64>,
    /// Start time (default: horizon start).
    #[serde(default)]
    pub t0: Option<f64>,
    /// End time (default: horizon end).
    #[serde(default)]
    pub t1: Option<f64>,
}

/// `verify_request`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct VerifyRequest {
    /// A trajectory (format v1).
    #[serde(default)]
    pub trajectory: Option<Trajectory>,
    /// Or one segment.
    #[serde(default)]
    pub segment: Option<Segment>,
    /// Or a batch of segments, each verified on its own (at most [`MAX_VERIFY_PIECES`]).
    #[serde(default)]
    pub segments: Option<Vec<Segment>>,
    /// `exact`, `sos` or `both`.
    #[serde(default)]
    pub method: Option<String>,
    /// Δ (default: the scene's).
    #[serde(default)]
    pub delta: Option<f64>,
    /// `auto` (default) or `cantelli`: which bounds may prove a piece.
    #[serde(default)]
    pub bound: Option<String>,
    /// `true`: the reply's `pieces` holds only the first piece (or segment) that is not
    /// safe (none when all are safe), not a report of every piece; the pieces proven
    /// safe get no report built at all.
    #[serde(default)]
    pub summary: Option<bool>,
    /// `true`: also the whole-path bound (`whole_path_risk` in the reply, docs/design.md
    /// §5.14) of a trajectory or segment of at most
    /// [`riskplan_app::verify::MAX_WHOLE_PATH_PIECES`] pieces (not of a `segments` batch).
    #[serde(default)]
    pub whole_path: Option<bool>,
    /// How long the server may take, in milliseconds from the request's arrival,
    /// queue time included (default and cap: the server's `--max-job-seconds`). Past it
    /// the reply is the error `deadline_exceeded`.
    #[serde(default)]
    pub deadline_ms: Option<u64>,
}

/// `verify_reply`: the `riskplan verify` report and the revision.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VerifyReply {
    /// Every piece certified safe.
    pub safe: bool,
    /// Method.
    pub method: String,
    /// Δ.
    pub risk: f64,
    /// The bounds allowed (`auto` or `cantelli`).
    #[serde(default)]
    pub bound: String,
    /// Per piece (or segment), or only the first not safe (`summary`).
    pub pieces: Vec<PieceReport>,
    /// Scene revision used.
    pub revision: u64,
    /// Pieces (or segments) decided.
    #[serde(default)]
    pub checked: u64,
    /// How many of them are not proven safe.
    #[serde(default)]
    pub not_safe: u64,
    /// Index of the first piece (or segment) not proven safe.
    #[serde(default)]
    pub first_not_safe: Option<u64>,
    /// For a `segments` batch: the index of every segment not proven safe (empty
    /// otherwise).
    #[serde(default)]
    pub not_safe_segments: Vec<u64>,
    /// With `whole_path`: the certified bound on the probability of meeting any obstacle
    /// at any time of the trajectory, per obstacle and piece.
    #[serde(default)]
    pub whole_path_risk: Option<riskplan_app::verify::WholePathRisk>,
}

/// A grid of a risk query.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// Lower corner.
    pub lower: Vec<f64>,
    /// Upper corner.
    pub upper: Vec<f64>,
    /// Points per side.
    pub n: u64,
}

/// `risk_request`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RiskRequest {
    /// Points.
    #[serde(default)]
    pub points: Option<Vec<Vec<f64>>>,
    /// Or a grid.
    #[serde(default)]
    pub grid: Option<Grid>,
    /// Time (default: horizon start).
    #[serde(default)]
    pub time: Option<f64>,
    /// `auto`: `bounds` and `obstacles` hold the best bound of each point;
    /// `cantelli`: Cantelli's. Default `auto`.
    #[serde(default)]
    pub bound: Option<String>,
    /// `true`: the reply's `by_bound` lists every bound per obstacle (six numbers per point
    /// and obstacle: a large grid's reply then may exceed the size limit). Default false.
    #[serde(default)]
    pub every_bound: Option<bool>,
    /// How long the server may take, in milliseconds from the request's arrival,
    /// queue time included (default and cap: the server's `--max-job-seconds`). Past it
    /// the reply is the error `deadline_exceeded`.
    #[serde(default)]
    pub deadline_ms: Option<u64>,
}

/// `risk_reply`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RiskReply {
    /// Scene revision.
    pub revision: u64,
    /// Time.
    pub time: f64,
    /// The points.
    pub points: Vec<Vec<f64>>,
    /// Max over obstacles of the best bound allowed (`bound`).
    pub bounds: Vec<f64>,
    /// Per obstacle, the best bound allowed.
    pub obstacles: BTreeMap<String, Vec<f64>>,
    /// Per obstacle, every bound (`cantelli`, `support`, `moment4`, `moment6`, `moment8`;
    /// `support` is 0 where zero risk is proven, 1 elsewhere; a bound an obstacle does not
    /// have is absent), when the request asked for it (`every_bound`); else empty.
    #[serde(default)]
    pub by_bound: BTreeMap<String, BTreeMap<String, Vec<f64>>>,
    /// The bounds allowed.
    #[serde(default)]
    pub bound: String,
}

/// `scene_reply`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneReply {
    /// Name.
    pub name: String,
    /// Revision.
    pub revision: u64,
    /// The scene, format v1.
    pub scene: EmbeddedJson,
}

/// A scene in `status_reply`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneStatus {
    /// Name.
    pub name: String,
    /// Revision.
    pub revision: u64,
    /// Obstacles.
    pub obstacles: u64,
}

/// Contour cache counters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CacheStatus {
    /// Cached contours.
    pub entries: u64,
    /// Lookups that found one.
    pub hits: u64,
    /// Lookups that built one.
    pub misses: u64,
}

/// Job queue state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QueueStatus {
    /// Jobs waiting.
    pub depth: u64,
    /// Jobs running.
    pub running: u64,
    /// Worker threads.
    pub workers: u64,
    /// Waiting jobs accepted before `busy`.
    pub capacity: u64,
}

/// Served and failed requests of one kind.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
pub struct Counter {
    /// Successful replies.
    pub served: u64,
    /// Error replies (or failed puts).
    pub failed: u64,
}

/// `status_reply`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StatusReply {
    /// `loading` until the stored scenes and `--preload` files are in (every request
    /// but `status` and `echo` is then answered `unavailable`), `ready` after.
    #[serde(default = "ready_state")]
    pub state: String,
    /// `primary` (takes writes; the only role of a single server) or `replica`
    /// (follows a primary's revisions and answers reads: deploy/cluster).
    #[serde(default = "primary_role")]
    pub role: String,
    /// The server's id (its liveliness token `riskplan/_servers/<id>/<role>` and own keys
    /// `riskplan/@<id>/...`: proto/README.md, "Discovery").
    #[serde(default)]
    pub server_id: String,
    /// Seconds since start.
    pub uptime_s: f64,
    /// Scenes.
    pub scenes: Vec<SceneStatus>,
    /// Contour cache.
    pub cache: CacheStatus,
    /// Job queue.
    pub queue: QueueStatus,
    /// Per request kind.
    pub requests: BTreeMap<String, Counter>,
    /// Problems met loading the stored scenes (quarantined files), for operators.
    #[serde(default)]
    pub problems: Vec<String>,
}

/// `riskplan/_replication/scenes/<scene>`: a primary's commit, as published to
/// replicas (put) and as answered to a replica's catch-up query (get). Internal to
/// a cluster (deploy/cluster); JSON only.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplicationEntry {
    /// Scene name.
    pub name: String,
    /// The revision, or the last live revision of a deleted scene.
    pub revision: u64,
    /// Whether the scene was deleted.
    pub deleted: bool,
    /// The scene file (absent when deleted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<EmbeddedJson>,
}

/// `riskplan/_replication/index` (get): the version of every scene of the primary.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplicationIndex {
    /// The primary's data-directory identity: a replica that sees it change drops
    /// what the primary no longer has and installs the primary's state in full.
    pub primary: u64,
    /// `(name, revision, deleted)` of every live or deleted scene.
    pub scenes: Vec<(String, u64, bool)>,
}

fn primary_role() -> String {
    "primary".into()
}

fn ready_state() -> String {
    "ready".into()
}

/// `error`: the payload of every `reply_err`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorReply {
    /// Stable snake_case code (see proto/README.md).
    pub code: String,
    /// Human-readable message.
    pub message: String,
    /// Field path at fault, if any.
    pub field: Option<String>,
}

/// A wire encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Codec {
    /// `application/json`.
    Json,
    /// `application/bincode`.
    Bincode,
}

impl Codec {
    /// The codec for an encoding name, `None` when unsupported. No encoding, Zenoh's
    /// default `zenoh/bytes` and `text/plain` are read as JSON.
    pub fn from_encoding(enc: &str) -> Option<Codec> {
        let base = enc.split(';').next().unwrap_or("");
        match base {
            "application/json" | "zenoh/bytes" | "text/plain" | "" => Some(Codec::Json),
            BINCODE => Some(Codec::Bincode),
            _ => None,
        }
    }

    /// Encoding name.
    pub fn name(&self) -> &'static str {
        match self {
            Codec::Json => "application/json",
            Codec::Bincode => BINCODE,
        }
    }

    /// Serialises a message.
    pub fn encode<T: Serialize>(&self, v: &T) -> Vec<u8> {
        match self {
            Codec::Json => serde_json::to_vec(v).unwrap_or_else(|e| {
                format!("{{\"code\":\"internal\",\"message\":\"{e}\",\"field\":null}}").into_bytes()
            }),
            Codec::Bincode => bincode::serde::encode_to_vec(v, bincode::config::standard()).unwrap_or_default(),
        }
    }

    /// Parses a message; the error names the field at fault where the format can.
    pub fn decode<T: serde::de::DeserializeOwned>(&self, bytes: &[u8]) -> Result<T, (String, Option<String>)> {
        match self {
            Codec::Json => {
                let de = &mut serde_json::Deserializer::from_slice(bytes);
                serde_path_to_error::deserialize(de).map_err(|e| {
                    let p = e.path().to_string();
                    (e.into_inner().to_string(), (p != ".").then_some(p))
                })
            }
            Codec::Bincode => match bincode::serde::decode_from_slice(
                bytes,
                bincode::config::standard().with_limit::<MAX_DECODE_ALLOCATION>(),
            ) {
                Ok((v, n)) if n == bytes.len() => Ok(v),
                Ok((_, n)) => Err((format!("{} trailing bytes after the message", bytes.len() - n), None)),
                Err(e) => Err((e.to_string(), None)),
            },
        }
    }
}
