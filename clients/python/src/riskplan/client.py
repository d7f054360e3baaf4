"""The riskplan client: a Zenoh session in client mode talking to ``riskplan serve``
(wire protocol v1, proto/README.md)."""
from __future__ import annotations

import json
import os
import re
import time
import math
import random
import threading
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np
import zenoh

from .errors import (
    ConnectError,
    DuplicateReplyError,
    InvalidSceneNameError,
    NoReplyError,
    QueryTimeoutError,
    RiskplanError,
    error_from_reply,
)
from .plan import Plan, Trajectory

PREFIX = "riskplan"
JSON = "application/json"
# Characters that would change a key expression's meaning (chunk separator, wildcards,
# parameters, ...). The server checks the full name rules; the client only refuses
# names that would address other keys than the one meant.
_KEY_SPECIALS = set("/*$?#")

Json = Dict[str, Any]


def _check_chunk(value: str, what: str) -> str:
    if not isinstance(value, str) or not value or any(c in _KEY_SPECIALS for c in value):
        raise InvalidSceneNameError(
            f"{what} {value!r} cannot be a key-expression chunk (empty, or contains one of / * $ ? #); "
            "refused by the client",
            field="name" if what == "scene name" else "id",
        )
    return value


def scene_key(name: str, *rest: str) -> str:
    """The key expression ``riskplan/scenes/<name>[/rest...]``."""
    return "/".join([PREFIX, "scenes", _check_chunk(name, "scene name"), *rest])


def _encode(payload: Any) -> Optional[bytes]:
    if payload is None:
        return None
    if isinstance(payload, bytes):
        return payload
    if isinstance(payload, str):
        return payload.encode()
    return json.dumps(payload, allow_nan=False, separators=(",", ":")).encode()


def _encoding(enc: Union[None, str, zenoh.Encoding]) -> Optional[zenoh.Encoding]:
    if enc is None:
        return None
    if isinstance(enc, zenoh.Encoding):
        return enc
    return zenoh.Encoding(enc)


def _decode_ok(sample: zenoh.Sample) -> Any:
    data = sample.payload.to_bytes()
    enc = str(sample.encoding)
    if enc.startswith("application/bincode"):
        raise RiskplanError(f"the client cannot decode a reply in {enc}", code="unsupported_encoding")
    try:
        return json.loads(data)
    except ValueError as e:
        raise RiskplanError(f"reply is not JSON ({enc}): {e}: {data[:200]!r}", code="bad_reply") from None


def _decode_err(err: zenoh.ReplyError) -> RiskplanError:
    text = err.payload.to_bytes().decode("utf-8", errors="replace")
    if text.strip() == "Timeout":
        return QueryTimeoutError("the query timed out (the server is hung, busy with it, or slower than the timeout)")
    try:
        payload = json.loads(text)
    except ValueError:
        return RiskplanError(f"error reply ({err.encoding}): {text}", code="unknown")
    if isinstance(payload, dict) and "code" in payload:
        return error_from_reply(payload)
    return RiskplanError(f"error reply ({err.encoding}): {text}", code="unknown")


def one_reply(key: str, replies: Sequence[Any]) -> Any:
    """The one reply to a query on ``key`` among ``replies`` (``zenoh.Reply`` objects, or
    anything with ``ok`` and ``err`` the same way), in arrival order.

    Zenoh's local ``Timeout`` error reply is not a reply of a server: it is ignored next
    to a real reply, and raised as :class:`QueryTimeoutError` when nothing else came.
    Raises :class:`NoReplyError` for no reply at all and :class:`DuplicateReplyError`
    for more than one real reply (success or error): the protocol promises exactly one.
    Returns the reply (its ``ok`` is the sample, or its ``err`` the error reply)."""
    if not replies:
        raise NoReplyError(f"no reply to the query on {key}: no server serves it (absent, or it died meanwhile), or access control denied it (a reader's apply)")
    real = [r for r in replies if r.ok is not None or not isinstance(_decode_err(r.err), QueryTimeoutError)]
    if len(real) > 1:
        kinds = ", ".join("ok" if r.ok is not None else "error" for r in real)
        raise DuplicateReplyError(f"{len(real)} replies ({kinds}) to one query on {key}, where the protocol "
                                  "promises exactly one: several servers serve this key, or a server answered twice",
                                  count=len(real))
    if real:
        return real[0]
    raise _decode_err(replies[0].err)


def _replier(reply: Any) -> Optional[str]:
    """The Zenoh id of the session that sent ``reply`` (None: not known)."""
    rid = getattr(reply, "replier_id", None)
    return None if rid is None else str(getattr(rid, "zid", rid))


DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
# The read queries of proto/README.md ("Roles"): repeated when no server replied.
READ_KEY = re.compile(r"^riskplan/(status|echo|scenes/[^/]+(/(plan|verify|risk))?)$")
RETRY_PAUSE_S = 0.05
# How often a read waiting for a server checks that the server's token is still up.
LIVENESS_POLL_S = 0.05
# The ready servers' liveliness tokens (proto/README.md, "Discovery"): riskplan/_servers/<id>.
SERVER_TOKENS = "riskplan/_servers/*/*"
SERVER_ID = re.compile(r"^[0-9A-Za-z_-]{1,64}$")
SUSPEND_S = 1.0
TOKENS_TIMEOUT_S = 2.0


class _Servers:
    """The live servers this client sees (from their liveliness tokens) and its queries
    outstanding at each; thread-safe (the token callback runs on Zenoh's threads)."""

    def __init__(self):
        self._lock = threading.Lock()
        self.live: List[str] = []
        self.primary: Optional[str] = None
        self.outstanding: Dict[str, int] = {}
        # servers left out of the choice until a time (monotonic): a read on their own
        # key got no reply (gone; its token's departure may come later, and a restarted
        # server may already be back under the same id)
        self.suspended: Dict[str, float] = {}

    def on_token(self, sample) -> None:
        """A token riskplan/_servers/<id>/<role> came (PUT) or went (DELETE)."""
        parts = str(sample.key_expr).split("/")
        if len(parts) != 4 or parts[:2] != ["riskplan", "_servers"]:
            return
        sid, role = parts[2], parts[3]
        if not SERVER_ID.match(sid) or role not in ("primary", "replica"):
            return
        with self._lock:
            if sample.kind == zenoh.SampleKind.PUT:
                if sid not in self.live:
                    self.live.append(sid)
                if role == "primary":
                    self.primary = sid
            else:
                self.live = [x for x in self.live if x != sid]
                if self.primary == sid:
                    self.primary = None

    def count_write(self) -> Optional[str]:
        """A write goes to the shared key, where the primary takes it: counted against
        the primary (when known), so that reads lean towards the replicas meanwhile."""
        with self._lock:
            sid = self.primary
            if sid is not None:
                self.outstanding[sid] = self.outstanding.get(sid, 0) + 1
            return sid

    def pick(self) -> Optional[str]:
        """Of two live servers drawn at random, the one with fewer outstanding queries
        (the power of two choices); None when none is known. Counts the query."""
        with self._lock:
            now = time.monotonic()
            self.suspended = {k: v for k, v in self.suspended.items() if v > now}
            ready = [x for x in self.live if x not in self.suspended]
            if not ready:
                return None
            if len(ready) == 1:
                sid = ready[0]
            else:
                a, b = random.sample(ready, 2)
                sid = b if self.outstanding.get(b, 0) < self.outstanding.get(a, 0) else a
            self.outstanding[sid] = self.outstanding.get(sid, 0) + 1
            return sid

    def done(self, sid: Optional[str]) -> None:
        """A query to ``sid`` is over."""
        if sid is None:
            return
        with self._lock:
            self.outstanding[sid] = max(0, self.outstanding.get(sid, 0) - 1)

    def is_live(self, sid: str) -> bool:
        """Whether ``sid``'s token is up."""
        with self._lock:
            return sid in self.live

    def drop(self, sid: str) -> None:
        """``sid`` gave no reply at all (it went away): leave it out for SUSPEND_S."""
        with self._lock:
            self.suspended[sid] = time.monotonic() + SUSPEND_S



def _segment(segment: Union[Json, Sequence]) -> Json:
    """A ``{"from", "to", "t0"?, "t1"?}`` dict from a dict or ``(from, to[, t0, t1])``."""
    if isinstance(segment, dict):
        seg = dict(segment)
    else:
        seg_list = list(segment)
        if len(seg_list) not in (2, 4):
            raise ValueError("segment: (from, to) or (from, to, t0, t1)")
        seg = {"from": seg_list[0], "to": seg_list[1]}
        if len(seg_list) == 4:
            seg["t0"], seg["t1"] = seg_list[2], seg_list[3]
    for k in ("from", "to"):
        seg[k] = [float(v) for v in seg[k]]
    for k in ("t0", "t1"):
        if seg.get(k) is not None:
            seg[k] = float(seg[k])
        else:
            seg.pop(k, None)
    return seg

class Client:
    """A connection to a riskplan server.

    After each query, ``last_replies`` holds the number of replies received (the
    protocol promises exactly one: more than one real reply raises
    :class:`DuplicateReplyError`), ``last_repliers`` the Zenoh ids of their senders
    (``None`` where Zenoh gives none, e.g. a local timeout) and ``last_encoding`` the
    encoding of the reply used.

    ``endpoint``: a Zenoh locator (``tcp/127.0.0.1:7447``) or a list of them. The
    session runs in client mode with multicast scouting off, so it talks only to the
    endpoint(s) given. ``timeout``: seconds per query (plans use at least their time
    limit plus a margin). Use as a context manager, or call :meth:`close`.

    ``config_file``: a Zenoh JSON5 configuration, e.g. a role's configuration of the
    secure deployment (``deploy/secure``: TLS, user and password); ``endpoint``, when
    given too, replaces its ``connect/endpoints``. ``config``: a ready ``zenoh.Config``
    used as is.
    """

    def __init__(self, endpoint: Union[None, str, Sequence[str]] = None, timeout: float = 30.0,
                 *, config: Optional[zenoh.Config] = None, config_file: Union[None, str, "os.PathLike[str]"] = None):
        self.timeout = float(timeout)
        if config is not None and config_file is not None:
            raise ValueError("give config= or config_file=, not both")
        if config_file is not None:
            try:
                config = zenoh.Config.from_file(str(config_file))
            except zenoh.ZError as e:
                raise ConnectError(f"cannot read the Zenoh configuration {config_file}: {e}") from None
            if endpoint is not None:
                endpoints = [endpoint] if isinstance(endpoint, str) else list(endpoint)
                config.insert_json5("connect/endpoints", json.dumps(endpoints))
        configured = config is not None
        if endpoint is None:
            endpoint = DEFAULT_ENDPOINT if config is None else "(from the configuration)"
        self.endpoint = endpoint
        if config is None:
            config = zenoh.Config()
            endpoints = [endpoint] if isinstance(endpoint, str) else list(endpoint)
            config.insert_json5("mode", '"client"')
            config.insert_json5("connect/endpoints", json.dumps(endpoints))
            config.insert_json5("scouting/multicast/enabled", "false")
        try:
            self._session = zenoh.open(config)
        except zenoh.ZError as e:
            raise ConnectError(f"cannot open a Zenoh session to {endpoint}: {e}") from None
        self.last_replies = 0
        self.last_repliers: List[Optional[str]] = []
        self.last_encoding: Optional[str] = None
        # reads of a scene ask for at least this revision of it (see at_least)
        self.min_revisions: Dict[str, int] = {}
        self.last_server: Optional[str] = None
        self._servers = _Servers()
        # the servers' tokens as they come and go, and (in the background) the ones up
        # now. Not the subscriber's own history: where access control denies the
        # liveliness messages (deploy/secure), a denied history request left the next
        # query without reply; a separate get that is denied only times out.
        # Not with a configuration of one's own (deploy/secure: its access control denies
        # the liveliness messages, and a denied one could leave the next query without
        # reply): then every read goes to the shared keys.
        self._watch = None
        if not configured:
            self._watch = self._session.liveliness().declare_subscriber(SERVER_TOKENS, self._servers.on_token)
            threading.Thread(target=self._current_servers, daemon=True).start()

    # -- lifecycle -----------------------------------------------------------------

    def close(self) -> None:
        """Closes the Zenoh session (idempotent)."""
        s = getattr(self, "_session", None)
        if s is not None and not s.is_closed():
            s.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self):  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass

    # -- cluster ---------------------------------------------------------------------

    def _current_servers(self) -> None:
        """The servers' tokens that are up now (a liveliness get, in the background)."""
        try:
            for r in self._session.liveliness().get(SERVER_TOKENS, timeout=TOKENS_TIMEOUT_S):
                if r.ok is not None:
                    self._servers.on_token(r.ok)
        except zenoh.ZError:
            pass   # the session closed meanwhile

    def servers(self) -> List[str]:
        """The ids of the live servers this client sees (their liveliness tokens)."""
        with self._servers._lock:
            return list(self._servers.live)

    def at_least(self, name: str, revision: Optional[int]) -> "Client":
        """Makes this client's reads of scene ``name`` ask for at least ``revision`` of it
        (``min_revision``; ``None``: any): a replica that is behind its primary waits
        briefly for it, else answers :class:`StaleRevisionError`. Pass the revision an
        :meth:`apply` returned to read your own write from any server. Revisions count per
        scene; this changes this client (for every later read of ``name``). Returns self."""
        if revision is None:
            self.min_revisions.pop(name, None)
        else:
            self.min_revisions[name] = int(revision)
        return self

    def _target(self, key: str) -> Tuple[str, Optional[str]]:
        """Where a query on ``key`` goes: a read to a live server's own key
        ``riskplan/@<id>/...`` (the power of two choices on this client's outstanding
        queries), anything else — or a read when no server is known — to the key as
        given; reads on a scene carry ``?min_revision=R`` when asked for."""
        if not READ_KEY.match(key):
            return key, (self._servers.count_write() if key.endswith("/apply") else None)
        sid = self._servers.pick()
        selector = key if sid is None else f"{PREFIX}/@{sid}/{key[len(PREFIX) + 1:]}"
        if key.startswith(f"{PREFIX}/scenes/"):
            scene = key[len(PREFIX) + len("/scenes/"):].split("/")[0]
            if scene in self.min_revisions:
                selector += f"?min_revision={self.min_revisions[scene]}"
        return selector, sid

    # -- low level -----------------------------------------------------------------

    def query(self, key: str, request: Any = None, *, encoding: Union[None, str, zenoh.Encoding] = JSON,
              timeout: Optional[float] = None) -> Any:
        """One ``get`` on ``key`` with ``request`` as payload (a dict/list is sent as JSON;
        ``str``/``bytes`` as they are) and the given encoding (``None``: no encoding).
        Returns the decoded JSON reply; raises a :class:`RiskplanError` subclass for an
        error reply, :class:`QueryTimeoutError` on timeout, :class:`NoReplyError` when
        nothing answered, :class:`DuplicateReplyError` when more than one reply came."""
        total = float(timeout if timeout is not None else self.timeout)
        kwargs: Dict[str, Any] = dict(
            consolidation=zenoh.ConsolidationMode.NONE,
            target=zenoh.QueryTarget.BEST_MATCHING,
        )
        data = _encode(request)
        if data is not None:
            kwargs["payload"] = data
        enc = _encoding(encoding)
        if enc is not None:
            kwargs["encoding"] = enc
        end = time.monotonic() + total
        while True:
            left = end - time.monotonic()
            selector, sid = self._target(key)
            try:
                replies = self._get(selector, sid, left, bool(READ_KEY.match(key)), kwargs)
            finally:
                self._servers.done(sid)
            self.last_server = sid
            # No reply at all to a read: the server that took it died (or none is up
            # yet). Reads are safe to repeat: the next goes to another live server (or,
            # when none is known, to the shared key after a pause): try again within the
            # timeout. Writes (apply) are never repeated: the lost one may have been
            # carried out.
            if replies or not READ_KEY.match(key) or end - time.monotonic() <= RETRY_PAUSE_S:
                break
            if sid is not None and READ_KEY.match(key):
                self._servers.drop(sid)
            else:
                time.sleep(RETRY_PAUSE_S)
        self.last_replies = len(replies)
        self.last_repliers = [_replier(r) for r in replies]
        self.last_encoding = None
        r = one_reply(key, replies)
        if r.ok is not None:
            self.last_encoding = str(r.ok.encoding)
            return _decode_ok(r.ok)
        self.last_encoding = str(r.err.encoding)
        raise _decode_err(r.err)

    def _get(self, selector: str, sid: Optional[str], left: float, read: bool, kwargs: Dict[str, Any]) -> List[Any]:
        """The replies to one ``get``. A read sent to a known server is waited for only
        while that server's liveliness token is up: a server killed with the query in
        flight may leave it unanswered until the timeout (seen once in a few hundred
        runs of the cluster test), so when the token goes before the query ends the
        replies so far are returned (none: the caller re-sends the read elsewhere)."""
        timeout = max(left, 0.001)
        if not read or sid is None:
            return list(self._session.get(selector, timeout=timeout, **kwargs))
        replies: List[Any] = []
        finished = threading.Event()
        self._session.get(selector, zenoh.handlers.Callback(replies.append, finished.set), timeout=timeout, **kwargs)
        while not finished.wait(LIVENESS_POLL_S):
            if not self._servers.is_live(sid):
                break
        return list(replies)

    def put(self, key: str, payload: Any, *, encoding: Union[None, str, zenoh.Encoding] = JSON) -> None:
        """A ``put`` on ``key`` (fire and forget)."""
        kwargs = {}
        enc = _encoding(encoding)
        if enc is not None:
            kwargs["encoding"] = enc
        self._session.put(key, _encode(payload) or b"", **kwargs)

    def delete(self, key: str) -> None:
        """A ``delete`` on ``key`` (fire and forget)."""
        self._session.delete(key)

    # -- scenes --------------------------------------------------------------------

    def put_scene(self, name: str, scene: Json) -> None:
        """Replaces (or creates) scene ``name`` with a whole scene (format v1), fire and
        forget: nothing is acknowledged, use :meth:`apply` when you must know."""
        self.put(scene_key(name), scene)

    def delete_scene(self, name: str) -> None:
        """Deletes scene ``name`` (fire and forget)."""
        self.delete(scene_key(name))

    def apply(self, name: str, scene: Optional[Json] = None, changes: Optional[List[Json]] = None,
              *, timeout: Optional[float] = None) -> int:
        """Replaces the whole scene (``scene=``) or applies obstacle ``changes``
        atomically, in order (``[{"op": "put", "id", "poly", "params"?} |
        {"op": "delete", "id"}]``). Returns the new revision, acknowledged after the
        update is persisted."""
        if (scene is None) == (changes is None):
            raise ValueError("apply needs exactly one of scene= and changes=")
        request = {"scene": scene} if scene is not None else {"changes": list(changes)}
        request["deadline_ms"] = self._deadline_ms(timeout)
        reply = self.query(scene_key(name, "apply"), request, timeout=timeout)
        return int(reply["revision"])

    def update_obstacle(self, name: str, id: str, poly: str, params: Optional[Json] = None) -> None:
        """Adds or replaces obstacle ``id`` of scene ``name`` (a put on
        ``riskplan/scenes/<name>/obstacles/<id>``; fire and forget). ``params`` declares
        or replaces parameters the obstacle introduces (``{name: distribution}``)."""
        body: Json = {"poly": poly}
        if params is not None:
            body["params"] = params
        self.put(scene_key(name, "obstacles", _check_chunk(id, "obstacle id")), body)

    def remove_obstacle(self, name: str, id: str) -> None:
        """Removes obstacle ``id`` of scene ``name`` (a delete; fire and forget)."""
        self.delete(scene_key(name, "obstacles", _check_chunk(id, "obstacle id")))

    def get_scene(self, name: str) -> Json:
        """The ``scene_reply`` of scene ``name``: ``{"name", "revision", "scene"}`` (the
        scene itself, format v1, under ``"scene"``)."""
        return self.query(scene_key(name))

    def revision(self, name: str) -> int:
        """The current revision of scene ``name``."""
        return int(self.get_scene(name)["revision"])

    # -- planning ------------------------------------------------------------------

    def _deadline_ms(self, timeout: Optional[float]) -> int:
        """The deadline sent with apply, verify and risk requests that name none: the
        query's timeout. Zenoh does not tell a server that a client gave up, so the
        server drops the job when the client stops waiting for it, not later (it caps
        the deadline at its own --max-job-seconds)."""
        t = float(timeout if timeout is not None else self.timeout)
        return max(1, int(t * 1000))

    def plan_timeout(self, time_limit: Optional[float]) -> float:
        """The query timeout used for a plan with this time limit: a bit longer than it."""
        if time_limit is None or not math.isfinite(time_limit) or time_limit <= 0:
            return self.timeout
        return max(self.timeout, 1.25 * float(time_limit) + 5.0)

    def plan(self, name: str, start: Optional[Sequence[float]] = None, goal: Optional[Sequence[float]] = None,
             planner: Optional[str] = "rrt-sos", time_limit: Optional[float] = 10.0, seed: Optional[int] = 1,
             timeout: Optional[float] = None, **options: Any) -> Plan:
        """Plans on scene ``name`` (``plan_request``). ``planner``: ``rrt-sos`` (the
        default: certified, smoothed), ``rrt-sos-paper`` (the paper's RRT-SOS),
        ``mc-rrt`` (uncertified baseline) or ``tv-sos`` (the paper's time-varying SOS
        optimisation, every piece certified; SDP sizes, solver time and the retry
        ladder in ``plan.stats["sdp"]`` and ``plan.stats["ladder"]``), ``moment`` or
        ``moment-poly`` (the paper's standard SOS planner with average risk, over
        piecewise-linear or polynomial trajectories: atoms extracted from one moment
        relaxation, each certified; the average-risk values in
        ``plan.stats["average_risk"]``). ``options``: ``pieces``, ``improve``,
        ``delta``, ``certifier``, ``max_speed``, ``max_accel``, ``smooth`` (bool),
        ``risk_mode`` (``per-obstacle``, ``joint`` or ``joint-weighted``; the Δᵢ used are
        in ``plan.stats["risk_allocation"]``; or ``trajectory``: Δ bounds the probability
        of meeting any obstacle at any time along the plan). Every certified plan's
        ``plan.stats["whole_path_risk"]`` is its certified whole-path bound. Any other key is sent as is, and the server
        rejects it as ``malformed_payload``. ``None`` leaves a field out (the server's
        default). Raises :class:`NoPlanError` when no plan is found in time, with the
        typed reason in its message."""
        request: Json = {}
        if start is not None:
            request["start"] = [float(v) for v in start]
        if goal is not None:
            request["goal"] = [float(v) for v in goal]
        if planner is not None:
            request["planner"] = planner
        if time_limit is not None:
            request["time_limit"] = float(time_limit)
        if seed is not None:
            request["seed"] = int(seed)
        return self._plan(name, request, options, time_limit, timeout)

    def _plan(self, name: str, request: Json, options: Dict[str, Any], time_limit: Optional[float],
              timeout: Optional[float]) -> Plan:
        """Sends a plan request with ``options`` (``None`` values left out)."""
        for k, v in options.items():
            if v is not None:
                request[k] = v
        reply = self.query(scene_key(name, "plan"), request,
                           timeout=timeout if timeout is not None else self.plan_timeout(time_limit))
        return Plan(reply)

    def replan(self, name: str, t_now: float, position: Sequence[float], goal: Sequence[float],
               horizon: float, velocity: Optional[Sequence[float]] = None, *,
               robot_id: Optional[str] = None, warm_start: Union[None, Json, Trajectory] = None,
               time_limit: Optional[float] = 0.05, timeout: Optional[float] = None, **options: Any) -> Plan:
        """A receding-horizon plan (docs/design.md §6.9): from the robot's state at
        ``t_now`` (``position``, ``velocity``; at rest when ``None``) over
        ``[t_now, t_now + horizon]`` towards ``goal``. The trajectory leaves with the given
        velocity (C¹) and ends at the goal at rest, or short of it at the point of best
        progress: ``plan.progress`` (``{"reached_goal", "remaining_distance", ...}``).
        ``robot_id``: the server keeps the robot's last plan and continues from it;
        ``warm_start``: send the previous plan instead. ``options`` as for :meth:`plan`
        (``delta``, ``max_speed``, ``max_accel``, ``robot_radius``, ``seed``, ...)."""
        request: Json = {
            "t_now": float(t_now),
            "position": [float(v) for v in position],
            "goal": [float(v) for v in goal],
            "horizon": float(horizon),
        }
        if velocity is not None:
            request["velocity"] = [float(v) for v in velocity]
        if robot_id is not None:
            request["robot_id"] = _check_chunk(robot_id, "robot id")
        if warm_start is not None:
            pieces = warm_start.pieces if hasattr(warm_start, "pieces") else warm_start["pieces"]
            request["warm_start"] = [dict(p) if isinstance(p, dict) else p for p in pieces]
        if time_limit is not None:
            request["time_limit"] = float(time_limit)
        return self._plan(name, request, options, time_limit, timeout)

    def update_pedestrians(self, name: str, predictions: Dict[str, Json],
                           remove: Sequence[str] = (), *, timeout: Optional[float] = None) -> int:
        """Sends pedestrians' predictions as one acknowledged ``apply``: ``predictions``
        maps an obstacle id to a pedestrian template (``{"position", "velocity", "time",
        "radius", "position_std"?, "velocity_std"?}``, docs/formats.md §1.5.1); ``remove``
        lists ids to delete. Only the pedestrians that changed are rebuilt on the server.
        Returns the new revision."""
        changes: List[Json] = [{"op": "delete", "id": str(i)} for i in remove]
        changes += [{"op": "put", "id": str(i), "pedestrian": p} for i, p in predictions.items()]
        return self.apply(name, changes=changes, timeout=timeout)

    def verify(self, name: str, trajectory: Union[None, Json, Trajectory] = None,
               segment: Union[None, Json, Sequence] = None, method: Optional[str] = None,
               delta: Optional[float] = None, *, summary: Optional[bool] = None,
               deadline_ms: Optional[int] = None, timeout: Optional[float] = None,
               bound: Optional[str] = None, segments: Optional[Sequence] = None,
               whole_path: Optional[bool] = None) -> Json:
        """Verifies a trajectory (a :class:`Plan`, a plan_reply dict or a trajectory v1
        dict) or one straight segment (``{"from", "to", "t0"?, "t1"?}`` or a tuple
        ``(from, to[, t0, t1])``) against scene ``name``. Returns the ``verify_reply``
        (``{"safe", "method", "risk", "pieces", "revision"}``). ``summary=True``: ``pieces``
        holds only the first piece that is not safe (none when safe), and no report is
        built for the others. ``segments``: a batch of segments (each as for ``segment``,
        up to 200 000), each verified on its own; the reply's ``not_safe_segments`` lists
        the indices of those not proven safe. Every reply counts ``checked`` and
        ``not_safe`` and gives ``first_not_safe`` (an index). ``deadline_ms``: the
        server answers ``deadline_exceeded`` rather than work past it. ``bound``: ``"auto"``
        (Cantelli, zero risk from bounded support, shifted moment bounds on sub-intervals;
        each obstacle report's ``bounds`` says which bound proved which part) or
        ``"cantelli"`` (default: ``"auto"``). ``whole_path=True`` (a trajectory of at most
        2 000 pieces, or a segment): the reply's ``whole_path_risk`` bounds the probability
        that the trajectory meets any obstacle at any time, the parameters drawn once
        (``{"bound", "obstacles": [{"id", "bound", "how", "pieces"}]}``), beyond the
        per-instant risk the rest of the reply certifies."""
        if sum(x is not None for x in (trajectory, segment, segments)) != 1:
            raise ValueError("verify needs exactly one of trajectory=, segment= and segments=")
        request: Json = {}
        if trajectory is not None:
            if isinstance(trajectory, Trajectory):
                request["trajectory"] = trajectory.trajectory()
            else:
                request["trajectory"] = {"format": trajectory.get("format", "riskplan-trajectory/1"),
                                         "pieces": trajectory["pieces"]}
        elif segment is not None:
            request["segment"] = _segment(segment)
        else:
            request["segments"] = [_segment(s) for s in segments]
        if method is not None:
            request["method"] = method
        if bound is not None:
            request["bound"] = bound
        if delta is not None:
            request["delta"] = float(delta)
        if summary is not None:
            request["summary"] = bool(summary)
        if whole_path is not None:
            request["whole_path"] = bool(whole_path)
        request["deadline_ms"] = int(deadline_ms) if deadline_ms is not None else self._deadline_ms(timeout)
        return self.query(scene_key(name, "verify"), request, timeout=timeout)

    # -- risk ----------------------------------------------------------------------

    def risk_query(self, name: str, request: Json, *, timeout: Optional[float] = None) -> Json:
        """A raw ``risk_request``; returns the ``risk_reply`` dict. Without a
        ``deadline_ms`` in it, the query's timeout is sent as the deadline."""
        if "deadline_ms" not in request:
            request = {**request, "deadline_ms": self._deadline_ms(timeout)}
        return self.query(scene_key(name, "risk"), request, timeout=timeout)

    def risk(self, name: str, points: Union[np.ndarray, Sequence], time: Optional[float] = None,
             *, timeout: Optional[float] = None, bound: Optional[str] = None) -> np.ndarray:
        """Risk bounds (max over obstacles) at ``points`` (an ``(n, dim)`` array, or
        one point) at ``time`` (default: the horizon's start): an ``(n,)`` array.
        ``bound="auto"``: the best proven bound at each point; ``"cantelli"``: Cantelli's
        (default: ``"auto"``). ``risk_query`` with ``"every_bound": true`` returns every
        bound per obstacle (``by_bound``)."""
        pts = np.asarray(points, dtype=float)
        if pts.ndim == 1:
            pts = pts.reshape(1, -1)
        request: Json = {"points": pts.tolist()}
        if time is not None:
            request["time"] = float(time)
        if bound is not None:
            request["bound"] = bound
        reply = self.risk_query(name, request, timeout=timeout)
        return np.asarray(reply["bounds"], dtype=float)

    def risk_grid(self, name: str, lower: Sequence[float], upper: Sequence[float], n: int,
                  time: Optional[float] = None, *, timeout: Optional[float] = None,
                  bound: Optional[str] = None) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Risk bounds (``bound``: ``"auto"``, the default, or ``"cantelli"``) on an
        ``n``×``n`` grid over the first two axes (other coordinates at ``lower``). Returns ``(X, Y, B)``, each ``(n, n)``, as from
        ``numpy.meshgrid`` (``X`` varies along axis 1): ready for ``plt.contour``."""
        lower = [float(v) for v in lower]
        upper = [float(v) for v in upper]
        n = int(n)
        request: Json = {"grid": {"lower": lower, "upper": upper, "n": n}}
        if time is not None:
            request["time"] = float(time)
        if bound is not None:
            request["bound"] = bound
        reply = self.risk_query(name, request, timeout=timeout)
        xs = np.linspace(lower[0], upper[0], n)
        ys = np.linspace(lower[1], upper[1], n)
        X, Y = np.meshgrid(xs, ys)
        pts = np.asarray(reply["points"], dtype=float).reshape(-1, len(lower))
        bounds = np.asarray(reply["bounds"], dtype=float)
        if pts.shape[0] != n * n or bounds.shape[0] != n * n:
            raise RiskplanError(f"risk grid reply has {pts.shape[0]} points and {bounds.shape[0]} bounds, "
                                f"expected {n * n}", code="bad_reply")
        # Place each returned point by its coordinates (the order of the reply's points
        # is not specified by the protocol).
        def index(v, lo, hi):
            if n == 1 or hi == lo:
                return np.zeros(v.shape, dtype=int)
            return np.clip(np.rint((v - lo) / (hi - lo) * (n - 1)).astype(int), 0, n - 1)
        i = index(pts[:, 0], lower[0], upper[0])
        j = index(pts[:, 1], lower[1], upper[1])
        B = np.full((n, n), np.nan)
        B[j, i] = bounds
        return X, Y, B

    # -- server --------------------------------------------------------------------

    def status(self, *, timeout: Optional[float] = None) -> Json:
        """The ``status_reply``: uptime, scenes, cache, queue and request counters."""
        return self.query(f"{PREFIX}/status", None, encoding=None, timeout=timeout)
