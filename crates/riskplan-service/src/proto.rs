//! Wire messages of `proto/README.md`, as serde types shared by the server and the
//! Rust client, with the JSON / bincode codec. No field uses
//! `skip_serializing_if` or untagged/internally tagged enums, so that every type
//! round-trips through bincode (which is positional and cannot `deserialize_any`).
//!
//! The JSON Schemas of `proto/schemas/` are generated from these types (their
//! `JsonSchema` derives, `schemars` attributes and doc comments; `schema::MESSAGES` names
//! the messages). A doc comment here is what a schema's reader sees: it speaks of the
//! wire, not of Rust.
//!
//! Closed sets of names are enums (a planner, a certifier, a risk mode, a bound choice, an
//! operation, a state, a role, an error code), named on the wire by their `as_str`. In a
//! request they arrive as [`Named`]: decoding keeps a name outside the set, and the
//! handler that reads the field turns it into `invalid_request` naming the field (see
//! [`Named`] for why).

use riskplan_app::verify::{PieceReport, WholePathRisk};
use riskplan_app::{PlannerKind, RiskMode};
use riskplan_certify::checker::Method;
use riskplan_math::contour::BoundChoice;
use riskplan_plan::PlanStats;
use riskplan_scene::{ParamFile, PedestrianFile, Piece, SceneFile, Trajectory, WireName};
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::str::FromStr;

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
/// Most changes in one `apply` (a scene holds at most `scene::MAX_OBSTACLES` = 512
/// obstacles; 28 000 changes took 10 s to refuse).
pub const MAX_CHANGES: usize = 512;
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
/// A scene name: 1 to 128 characters from `A-Z a-z 0-9 _ - .`.
pub const SCENE_NAME_PATTERN: &str = r"^[A-Za-z0-9_.\-]{1,128}$";
/// A robot id of a receding-horizon request: 1 to 128 characters from `A-Z a-z 0-9 . _ -`.
pub const ROBOT_ID_PATTERN: &str = r"^[A-Za-z0-9._-]{1,128}$";
/// A server id (empty from a server older than ids).
pub const SERVER_ID_PATTERN: &str = r"^[0-9A-Za-z_-]{0,64}$";

/// Free-form JSON carried inside a message: as JSON itself in JSON, as a string
/// holding JSON text in bincode (which cannot carry self-describing data). It has no
/// JSON Schema of its own: each field that holds one says what it holds
/// (`#[schemars(with = ...)]`: a scene v1, a pedestrian, parameters).
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

/// A name of a closed set (a planner, a certifier, a risk mode, a bound, an operation) as
/// a request sends it: one of the set's values, or the name that is none of them with the
/// set's own message ("unknown planner 'astar' (rrt-sos, …)").
///
/// Why a request holds this rather than the enum itself: an unknown name is a request
/// whose *value* is out of range, which the service answers `invalid_request` naming the
/// field, with the set's message — not `malformed_payload`, which is for payloads that do
/// not have the message's shape. Were the enum decoded directly, its `FromStr` error
/// would end the decoding as a serde error, one string among all the others (a typo in a
/// field name, a wrong type), and it would be found before every other check of the
/// request: a verify request with a bad trajectory *and* an unknown method would say
/// `method` instead of `invalid_trajectory` as it does. So decoding only reads the string
/// (a non-string is still `malformed_payload`), and the handler that reads the field — at
/// the point where the name was always checked — calls [`Named::get`] and answers
/// `invalid_request` with the field and the message: the request is first decoded, then
/// converted. The same holds in bincode, where a name is a string too. The JSON Schema
/// of a `Named<T>` is `T`'s: a schema validator refuses the unknown name outright.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Named<T> {
    /// One of the set's values.
    Known(T),
    /// A name outside the set.
    Unknown {
        /// The name as sent.
        name: String,
        /// The set's message for it (its `FromStr` error).
        message: String,
    },
}

impl<T: FromStr> Named<T>
where
    T::Err: std::fmt::Display,
{
    /// The value `name` names, or the name kept with the set's message.
    pub fn parse(name: &str) -> Named<T> {
        match name.parse() {
            Ok(v) => Named::Known(v),
            Err(e) => Named::Unknown { name: name.to_string(), message: e.to_string() },
        }
    }
}

impl<T: Copy> Named<T> {
    /// The value, or the set's message for a name outside it (the handler turns it into
    /// `invalid_request` naming the field).
    pub fn get(&self) -> Result<T, &str> {
        match self {
            Named::Known(v) => Ok(*v),
            Named::Unknown { message, .. } => Err(message),
        }
    }
}

impl<T> From<T> for Named<T> {
    fn from(v: T) -> Self {
        Named::Known(v)
    }
}

/// A name, in every encoding: the value's name, or the name as sent.
impl<T: WireName> Serialize for Named<T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Named::Known(v) => s.serialize_str(v.wire_name()),
            Named::Unknown { name, .. } => s.serialize_str(name),
        }
    }
}

impl<'de, T: FromStr> Deserialize<'de> for Named<T>
where
    T::Err: std::fmt::Display,
{
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d).map(|name| Named::parse(&name))
    }
}

impl<T: JsonSchema> JsonSchema for Named<T> {
    fn inline_schema() -> bool {
        T::inline_schema()
    }

    fn schema_name() -> Cow<'static, str> {
        T::schema_name()
    }

    fn schema_id() -> Cow<'static, str> {
        T::schema_id()
    }

    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        T::json_schema(generator)
    }
}

/// Declares a closed set of wire names: the enum with `ALL`, `as_str`, `FromStr` (the
/// message of a name outside it) and `Display`, and its serde and JSON Schema
/// ([`riskplan_scene::closed_set!`]).
macro_rules! wire_enum {
    (
        $(#[$meta:meta])*
        $vis:vis enum $ty:ident { $($(#[$vmeta:meta])* $variant:ident = $name:literal,)+ }
        unknown = |$s:ident| $message:expr;
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        $vis enum $ty { $($(#[$vmeta])* $variant,)+ }

        impl $ty {
            /// Every value, in the order the schemas list them.
            pub const ALL: [$ty; [$($name),+].len()] = [$($ty::$variant),+];

            /// The name on the wire.
            pub const fn as_str(self) -> &'static str {
                match self {
                    $($ty::$variant => $name,)+
                }
            }
        }

        impl FromStr for $ty {
            type Err = String;
            fn from_str($s: &str) -> Result<Self, String> {
                $ty::ALL.into_iter().find(|v| v.as_str() == $s).ok_or_else(|| $message)
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.as_str())
            }
        }

        riskplan_scene::closed_set!($ty, stringify!($ty));
    };
}

wire_enum! {
    /// The stable snake_case code of an error reply (proto/README.md, "Error codes"): the
    /// one list of them, which `ServiceError::code` returns, the metrics count outcomes by
    /// and the `error` schema enumerates.
    pub enum ErrorCode {
        /// The payload does not parse as the message (bad JSON or bincode, wrong types,
        /// unknown fields).
        MalformedPayload = "malformed_payload",
        /// An encoding other than JSON or bincode.
        UnsupportedEncoding = "unsupported_encoding",
        /// Over the payload limit.
        PayloadTooLarge = "payload_too_large",
        /// A documented limit.
        LimitExceeded = "limit_exceeded",
        /// A scene name outside the allowed characters.
        InvalidSceneName = "invalid_scene_name",
        /// No scene by that name.
        UnknownScene = "unknown_scene",
        /// The scene, or the scene a change produces, fails validation.
        InvalidScene = "invalid_scene",
        /// A field out of range, or a malformed change.
        InvalidRequest = "invalid_request",
        /// The trajectory fails validation.
        InvalidTrajectory = "invalid_trajectory",
        /// Start or goal outside the workspace.
        OutsideWorkspace = "outside_workspace",
        /// Start or goal not strictly inside every Δ-contour.
        UnsafeEndpoint = "unsafe_endpoint",
        /// No plan within the time limit or the planner's limits.
        NoPlan = "no_plan",
        /// The job queue is full.
        Busy = "busy",
        /// The request's deadline passed on the server.
        DeadlineExceeded = "deadline_exceeded",
        /// The server is still loading its stored scenes.
        Unavailable = "unavailable",
        /// A read asked for a revision this server does not have.
        StaleRevision = "stale_revision",
        /// A bug on our side.
        Internal = "internal",
    }
    unknown = |s| format!("unknown error code '{s}'");
}

wire_enum! {
    /// What one change of an `apply_request` does.
    pub enum ChangeOp {
        /// Adds or replaces an obstacle (with `poly`, or with `pedestrian`).
        Put = "put",
        /// Removes an obstacle.
        Delete = "delete",
    }
    unknown = |s| format!("'{s}' is not an operation (put or delete)");
}

wire_enum! {
    /// Whether a server takes queries yet (a status without it is from a server that was
    /// ready).
    #[derive(Default)]
    pub enum ServerState {
        /// Loading its stored scenes and `--preload` files: every request but `status` and
        /// `echo` is answered `unavailable`.
        Loading = "loading",
        /// Loaded: every query is taken.
        #[default]
        Ready = "ready",
    }
    unknown = |s| format!("unknown state '{s}' (loading or ready)");
}

wire_enum! {
    /// A server's role in a cluster (deploy/cluster; a status without it is from a primary).
    #[derive(Default)]
    pub enum Role {
        /// Takes writes (a single server is one).
        #[default]
        Primary = "primary",
        /// Answers reads only and follows a primary's revisions.
        Replica = "replica",
    }
    unknown = |s| format!("unknown role '{s}' (primary or replica)");
}

/// A get on `riskplan/scenes/<scene>/apply`. Either a whole scene (replace it, creating it
/// if needed) or a list of obstacle changes applied atomically, in order, to an existing
/// scene. The reply (apply_reply) is sent after the update is persisted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(extend("oneOf" = [{ "required": ["scene"] }, { "required": ["changes"] }]))]
pub struct ApplyRequest {
    /// A whole scene (format v1).
    #[serde(default)]
    #[schemars(with = "Option<SceneFile>")]
    pub scene: Option<EmbeddedJson>,
    /// Obstacle changes, applied in order (at most 512).
    #[serde(default)]
    #[schemars(length(max = MAX_CHANGES))]
    pub changes: Option<Vec<Change>>,
    /// Milliseconds from the request's arrival (queue time included) within which the
    /// server must answer, else the error deadline_exceeded; default and cap: the server's
    /// --max-job-seconds.
    #[serde(default)]
    pub deadline_ms: Option<u64>,
}

/// One change of an `apply_request`: `{"op": "put", "id", "poly", "params"?}`, `{"op":
/// "put", "id", "pedestrian"}` or `{"op": "delete", "id"}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(extend("oneOf" = [
    { "properties": { "op": { "const": "put" } }, "required": ["poly"], "not": { "required": ["pedestrian"] } },
    {
        "properties": { "op": { "const": "put" } },
        "required": ["pedestrian"],
        "not": { "anyOf": [{ "required": ["poly"] }, { "required": ["params"] }] }
    },
    {
        "properties": { "op": { "const": "delete" } },
        "not": { "anyOf": [{ "required": ["poly"] }, { "required": ["params"] }, { "required": ["pedestrian"] }] }
    }
]))]
pub struct Change {
    /// `put` or `delete`.
    pub op: Named<ChangeOp>,
    /// The obstacle's id, unique in its scene (it is also a key-expression chunk in
    /// `riskplan/scenes/<scene>/obstacles/<id>`, so it should avoid / * $ ? #).
    #[schemars(length(min = 1))]
    pub id: String,
    /// Polynomial text (put): the obstacle is the set where poly >= 0.
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub poly: Option<String>,
    /// The parameters the obstacle declares or replaces (put), in the scene format's
    /// parameter syntax: `{name: distribution}`.
    #[serde(default)]
    #[schemars(with = "Option<BTreeMap<String, ParamFile>>")]
    #[schemars(extend("propertyNames" = { "pattern": riskplan_scene::PARAM_NAME_PATTERN }))]
    pub params: Option<EmbeddedJson>,
    /// A pedestrian template (put), instead of `poly` (docs/formats.md §1.5.1).
    #[serde(default)]
    #[schemars(with = "Option<PedestrianFile>")]
    pub pedestrian: Option<EmbeddedJson>,
}

/// Reply to apply_request, sent after the update is persisted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ApplyReply {
    /// Scene name.
    #[schemars(regex(pattern = SCENE_NAME_PATTERN))]
    pub scene: String,
    /// New revision.
    pub revision: u64,
}

/// A put on `riskplan/scenes/<scene>/obstacles/<id>`: add or replace one obstacle (no reply;
/// a put that fails validation is counted in status requests.put.failed).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObstaclePut {
    /// Polynomial text: the obstacle is the set where poly >= 0.
    #[schemars(length(min = 1))]
    pub poly: String,
    /// The parameters it declares or replaces: `{name: distribution}`.
    #[serde(default)]
    #[schemars(with = "Option<BTreeMap<String, ParamFile>>")]
    #[schemars(extend("propertyNames" = { "pattern": riskplan_scene::PARAM_NAME_PATTERN }))]
    pub params: Option<EmbeddedJson>,
}

/// A get on `riskplan/scenes/<scene>/plan`. Every field is optional. Defaults: the scene's
/// start and goal, rrt-sos, 10 s (capped by the server's --max-plan-seconds), seed 1, the
/// scene's planner block (max_speed, max_accel; rrt_sos for rrt-sos-paper), the piece
/// ladder, no improve, the scene's Δ, exact, smoothing on, per-obstacle risk. With `t_now`
/// it is a receding-horizon request (docs/design.md §6.9): `position`, `horizon` and
/// `goal` are required, `start` is not allowed, and `position`, `velocity`, `horizon`,
/// `robot_id` and `warm_start` belong to it alone.
///
/// On the wire the two kinds share one flat object (as clients send it); the server
/// converts it once into the one kind or the other, and answers a field that does not
/// belong to its kind `invalid_request` naming it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    /// Start (default: the scene's): one coordinate per dimension of the scene.
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub start: Option<Vec<f64>>,
    /// Goal (default: the scene's): one coordinate per dimension of the scene.
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub goal: Option<Vec<f64>>,
    /// The planner (default rrt-sos); a receding-horizon request runs `receding`.
    #[serde(default)]
    pub planner: Option<Named<PlannerKind>>,
    /// Seconds (> 0); the server caps it at --max-plan-seconds.
    #[serde(default)]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub time_limit: Option<f64>,
    /// RNG seed (default 1).
    #[serde(default)]
    pub seed: Option<u64>,
    /// Pieces of the time-layered planner (forces it; default: the ladder 1, 2, 4, … 32);
    /// for tv-sos the first rung's pieces (1 to 16; default: the scene's
    /// planner.time_varying_sos.pieces, else 2); for moment the first rung's pieces (1 to
    /// 8; default: the scene's planner.standard_sos.piecewise_linear_pieces, else 2).
    #[serde(default)]
    #[schemars(range(min = 1, max = 1000))]
    pub pieces: Option<u64>,
    /// The improve step (rrt-sos-paper on static scenes only).
    #[serde(default)]
    pub improve: Option<bool>,
    /// Risk level Δ in (0, 1); default: the scene's.
    #[serde(default)]
    #[schemars(extend("exclusiveMinimum" = 0, "exclusiveMaximum" = 1))]
    pub delta: Option<f64>,
    /// How edges are certified (default exact).
    #[serde(default)]
    pub certifier: Option<Named<Method>>,
    /// Speed limit, workspace units per time unit (> 0; default: the scene's
    /// planner.max_speed, else none).
    #[serde(default)]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub max_speed: Option<f64>,
    /// Acceleration limit of the corner blends (> 0; default: the scene's
    /// planner.max_accel, else none).
    #[serde(default)]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub max_accel: Option<f64>,
    /// Shortcut and blend the path into C¹ pieces of degree ≤ 2, each certified (default
    /// true; rrt-sos and mc-rrt).
    #[serde(default)]
    pub smooth: Option<bool>,
    /// per-obstacle (the paper's: each obstacle ≤ Δ at each instant; the default); joint:
    /// any obstacle ≤ Δ at each instant, Δ split evenly (Boole); joint-weighted: split by
    /// need at start and goal, then by closeness to the start–goal line (the Δᵢ used are in
    /// stats.risk_allocation); trajectory: the probability of meeting any obstacle at any
    /// time along the plan ≤ Δ (docs/design.md §5.14; rrt-sos budgets its search;
    /// stats.whole_path_risk).
    #[serde(default)]
    pub risk_mode: Option<Named<RiskMode>>,
    /// Which risk bounds may prove safety: auto (Cantelli, then zero risk from bounded
    /// support and shifted moment bounds of orders 4, 6, 8 on sub-intervals; docs/design.md
    /// §3.7–§3.10, §5.13) or cantelli (the paper's eq. (10), (12)). Default: the scene's
    /// planner.bound, else auto.
    #[serde(default)]
    pub bound: Option<Named<BoundChoice>>,
    /// A receding-horizon request (docs/design.md §6.9): the current time, inside the
    /// scene's horizon. With it `position`, `horizon` and `goal` are required and `start`
    /// is not allowed.
    #[serde(default)]
    pub t_now: Option<f64>,
    /// The robot's position at `t_now` (strictly inside every Δ-contour).
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub position: Option<Vec<f64>>,
    /// The robot's velocity at `t_now` (default: at rest); its speed at most max_speed.
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub velocity: Option<Vec<f64>>,
    /// The window H (> 0): the plan covers `[t_now, t_now + H]`, cut at the scene's
    /// horizon.
    #[serde(default)]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub horizon: Option<f64>,
    /// The robot's id: the server keeps this robot's last plan and continues from it (warm
    /// start).
    #[serde(default)]
    #[schemars(regex(pattern = ROBOT_ID_PATTERN))]
    pub robot_id: Option<String>,
    /// The previous plan's pieces to continue from (instead of the one kept per robot_id;
    /// 1 to 10 000).
    #[serde(default)]
    #[schemars(length(min = 1, max = riskplan_scene::MAX_PIECES))]
    pub warm_start: Option<Vec<Piece>>,
    /// The robot's body radius (≥ 0; default: the scene's robot_radius, else 0): every
    /// obstacle is grown by it (docs/design.md §3.12).
    #[serde(default)]
    #[schemars(range(min = 0))]
    pub robot_radius: Option<f64>,
}

impl PlanRequest {
    /// The planner's name as sent (`rrt-sos` when none is), for logs.
    pub fn planner_name(&self) -> &str {
        match &self.planner {
            None => PlannerKind::RrtSos.as_str(),
            Some(Named::Known(p)) => p.as_str(),
            Some(Named::Unknown { name, .. }) => name,
        }
    }
}

/// Reply to plan_request: a trajectory (format v1) with its provenance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PlanReply {
    /// `riskplan-trajectory/1`.
    #[schemars(extend("const" = riskplan_scene::TRAJECTORY_FORMAT))]
    pub format: String,
    /// The pieces.
    #[schemars(length(min = 1))]
    pub pieces: Vec<Piece>,
    /// The planner that ran.
    pub planner: PlannerKind,
    /// Every piece proven safe (always false for mc-rrt).
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Segment {
    /// From: one coordinate per dimension of the scene.
    #[schemars(length(min = 1))]
    pub from: Vec<f64>,
    /// To: one coordinate per dimension of the scene.
    #[schemars(length(min = 1))]
    pub to: Vec<f64>,
    /// Start time (default: the horizon's start).
    #[serde(default)]
    pub t0: Option<f64>,
    /// End time (default: the horizon's end).
    #[serde(default)]
    pub t1: Option<f64>,
}

/// A get on `riskplan/scenes/<scene>/verify`: a trajectory (format v1, up to 200 000
/// pieces), one straight segment (default over the scene's horizon), or a batch of up to
/// 200 000 segments, each verified on its own. Payload up to 32 MiB (other requests: 1
/// MiB).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(extend("oneOf" = [{ "required": ["trajectory"] }, { "required": ["segment"] }, { "required": ["segments"] }]))]
pub struct VerifyRequest {
    /// A trajectory (format v1).
    #[serde(default)]
    pub trajectory: Option<Trajectory>,
    /// Or one segment.
    #[serde(default)]
    pub segment: Option<Segment>,
    /// Or a batch of segments, each verified on its own (1 to 200 000); the reply lists
    /// the indices of those not proven safe in `not_safe_segments`.
    #[serde(default)]
    #[schemars(length(min = 1, max = MAX_VERIFY_PIECES))]
    pub segments: Option<Vec<Segment>>,
    /// The method (default exact).
    #[serde(default)]
    pub method: Option<Named<Method>>,
    /// Risk level Δ in (0, 1); default: the scene's.
    #[serde(default)]
    #[schemars(extend("exclusiveMinimum" = 0, "exclusiveMaximum" = 1))]
    pub delta: Option<f64>,
    /// Which bounds may prove a piece (default auto); with auto each obstacle report lists
    /// under `bounds` which bound proved which part of the piece.
    #[serde(default)]
    pub bound: Option<Named<BoundChoice>>,
    /// `true`: the reply's `pieces` holds only the first piece (or segment) that is not
    /// safe (none when all are safe), not a report of every piece; the pieces proven
    /// safe get no report built at all.
    #[serde(default)]
    pub summary: Option<bool>,
    /// `true`: the reply's `whole_path_risk` bounds the probability of meeting any obstacle
    /// at any time of the trajectory (the parameters drawn once; docs/design.md §5.14),
    /// beyond the per-instant risk: a trajectory of at most 2 000 pieces or one segment,
    /// not a `segments` batch.
    #[serde(default)]
    pub whole_path: Option<bool>,
    /// Milliseconds from the request's arrival (queue time included) within which the
    /// server must answer, else the error deadline_exceeded; default and cap: the server's
    /// --max-job-seconds.
    #[serde(default)]
    pub deadline_ms: Option<u64>,
}

/// Reply to verify_request: the report of `riskplan verify`, plus the scene revision.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct VerifyReply {
    /// Every piece certified safe (undecided counts as not safe).
    pub safe: bool,
    /// The method used.
    pub method: Method,
    /// Δ used.
    pub risk: f64,
    /// The bounds allowed.
    #[serde(default)]
    pub bound: BoundChoice,
    /// One report per piece (or segment), or with `summary` only the first not safe.
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
    /// With `whole_path`: P(the trajectory meets some obstacle at some time) ≤ bound, the
    /// parameters drawn once (docs/design.md §5.14), per obstacle and piece; the sum over
    /// the obstacles of their bounds.
    #[serde(default)]
    pub whole_path_risk: Option<WholePathRisk>,
}

/// A grid of a risk query: N×N points over the first two axes (other coordinates at
/// `lower`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// Lower corner.
    #[schemars(length(min = 1))]
    pub lower: Vec<f64>,
    /// Upper corner.
    #[schemars(length(min = 1))]
    pub upper: Vec<f64>,
    /// Points per side (2 to 316, so that n² ≤ 100 000 points).
    #[schemars(range(min = 2, max = MAX_GRID_SIDE))]
    pub n: u64,
}

/// A get on `riskplan/scenes/<scene>/risk`: risk bounds at points, or on an N×N grid over the
/// first two axes (other coordinates at `lower`), at one time (default: the horizon's
/// start).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(extend("oneOf" = [{ "required": ["points"] }, { "required": ["grid"] }]))]
pub struct RiskRequest {
    /// Points (at most 100 000), one coordinate per dimension of the scene each.
    #[serde(default)]
    #[schemars(length(max = MAX_RISK_POINTS), inner(length(min = 1)))]
    pub points: Option<Vec<Vec<f64>>>,
    /// Or a grid.
    #[serde(default)]
    pub grid: Option<Grid>,
    /// Time (default: the horizon's start).
    #[serde(default)]
    pub time: Option<f64>,
    /// auto (default): `bounds` and `obstacles` hold the best bound at each point;
    /// cantelli: Cantelli's.
    #[serde(default)]
    pub bound: Option<Named<BoundChoice>>,
    /// `true`: the reply's `by_bound` lists every bound per obstacle (six numbers per point
    /// and obstacle: a large grid's reply then may exceed the size limit). Default false.
    #[serde(default)]
    pub every_bound: Option<bool>,
    /// Milliseconds from the request's arrival (queue time included) within which the
    /// server must answer, else the error deadline_exceeded; default and cap: the server's
    /// --max-job-seconds.
    #[serde(default)]
    pub deadline_ms: Option<u64>,
}

/// Reply to risk_request. Bounds (floating point, for displays) one per point: the best
/// bound allowed by `bound` per obstacle (`obstacles`), its max over obstacles (`bounds`),
/// and every bound per obstacle (`by_bound`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
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
    pub bound: BoundChoice,
}

/// Reply to a get on `riskplan/scenes/<scene>`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SceneReply {
    /// Name.
    #[schemars(regex(pattern = SCENE_NAME_PATTERN))]
    pub name: String,
    /// Revision.
    pub revision: u64,
    /// The scene, format v1.
    #[schemars(with = "SceneFile")]
    pub scene: EmbeddedJson,
}

/// A scene in `status_reply`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SceneStatus {
    /// Name.
    #[schemars(regex(pattern = SCENE_NAME_PATTERN))]
    pub name: String,
    /// Revision.
    pub revision: u64,
    /// Number of obstacles.
    pub obstacles: u64,
}

/// Contour cache counters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CacheStatus {
    /// Cached contours.
    pub entries: u64,
    /// Lookups that found one.
    pub hits: u64,
    /// Lookups that built one.
    pub misses: u64,
}

/// Job queue state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default, JsonSchema)]
pub struct Counter {
    /// Successful replies.
    pub served: u64,
    /// Error replies (or failed puts).
    pub failed: u64,
}

/// Reply to a get on riskplan/status.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StatusReply {
    /// loading until the stored scenes and --preload files are in (every request but
    /// status and echo is then answered unavailable), ready after.
    #[serde(default)]
    pub state: ServerState,
    /// primary: takes writes (a single server is one); replica: answers reads only and
    /// follows a primary (deploy/cluster).
    #[serde(default)]
    pub role: Role,
    /// The server's id: its liveliness token `riskplan/_servers/<id>/<role>` and its own
    /// keys `riskplan/@<id>/...` (proto/README.md, "Discovery").
    #[serde(default)]
    #[schemars(regex(pattern = SERVER_ID_PATTERN))]
    pub server_id: String,
    /// Seconds since start.
    #[schemars(range(min = 0))]
    pub uptime_s: f64,
    /// Scenes.
    pub scenes: Vec<SceneStatus>,
    /// Contour cache.
    pub cache: CacheStatus,
    /// Job queue.
    pub queue: QueueStatus,
    /// Per request kind (e.g. put).
    pub requests: BTreeMap<String, Counter>,
    /// Problems met loading the stored scenes: files moved to `<data>/quarantine/` and why.
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

/// The payload of every reply_err. Every field is always sent (`field` may be null).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[schemars(extend("required" = ["code", "message", "field"]))]
pub struct ErrorReply {
    /// Stable snake_case code (proto/README.md, "Error codes").
    pub code: ErrorCode,
    /// Human-readable message.
    pub message: String,
    /// A JSON path of the field at fault, or null.
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
