"""Every error code of proto/README.md that a client can provoke, from Python.

Reachable here: malformed_payload, unsupported_encoding, payload_too_large,
limit_exceeded, invalid_scene_name, unknown_scene, invalid_scene, invalid_request,
invalid_trajectory, outside_workspace, unsafe_endpoint, no_plan (this file) and busy
(test_busy.py, on a server with --workers 1 --queue 0). Client-side: timeout and
no_reply.

Not reachable: `internal` (a caught panic, i.e. a server bug: no request is supposed to
provoke it).
"""
from __future__ import annotations

import json
import time

import pytest
import zenoh

import riskplan

from conftest import validate

PLAN_LIMIT = 20.0


def expect(cls, fn, *args, field=None, **kwargs):
    """Calls fn, expects `cls`; checks the error payload against the error schema."""
    with pytest.raises(riskplan.RiskplanError) as ei:
        fn(*args, **kwargs)
    e = ei.value
    assert type(e) is cls, f"expected {cls.__name__}, got {e!r}"
    validate("error", {"code": e.code, "message": e.message, "field": e.field})
    assert e.message
    if field is not None:
        assert e.field is not None and field in e.field, f"field {e.field!r} should name {field!r}"
    return e


@pytest.fixture
def name3(client, scene3, unique):
    name = unique()
    client.apply(name, scene=scene3)
    return name


def key(name, op):
    return f"riskplan/scenes/{name}/{op}"


# -- malformed_payload --------------------------------------------------------------------

@pytest.mark.parametrize("payload", [
    b"{not json",
    b"[1, 2, 3]",
    json.dumps({"time_limt": 3}).encode(),          # unknown field (a typo)
    json.dumps({"seed": "one"}).encode(),           # wrong type
    json.dumps({"start": "origin", "goal": [1, 1]}).encode(),
], ids=["bad-json", "array", "unknown-field", "wrong-type", "wrong-type-start"])
def test_malformed_payload_plan(client, name3, payload):
    expect(riskplan.MalformedPayloadError, client.query, key(name3, "plan"), payload)


def test_malformed_payload_unknown_field_via_plan_options(client, name3):
    e = expect(riskplan.MalformedPayloadError, client.plan, name3, time_limit=1, colour="red")
    assert "colour" in e.message or (e.field and "colour" in e.field)


@pytest.mark.parametrize("op,payload", [
    ("apply", {"scene": {}, "changes": [], "extra": 1}),
    ("apply", {"changes": [{"op": "put", "id": "a", "poly": "x1", "colour": "red"}]}),
    ("verify", {"segment": {"from": [0, 0], "to": [1, 1], "speed": 2}}),
    ("risk", {"points": [[0, 0]], "when": 0}),
    ("risk", {"points": "everywhere"}),
])
def test_malformed_payload_other_queries(client, name3, op, payload):
    expect(riskplan.MalformedPayloadError, client.query, key(name3, op), payload)


def test_malformed_payload_with_text_plain_or_no_encoding_is_read_as_json(client, name3):
    # text/plain and no encoding are read as JSON: good JSON works, bad JSON is malformed
    assert client.query(key(name3, "risk"), {"points": [[1, 1]]}, encoding="text/plain")["bounds"]
    assert client.query(key(name3, "risk"), {"points": [[1, 1]]}, encoding=None)["bounds"]
    expect(riskplan.MalformedPayloadError, client.query, key(name3, "risk"), b"{oops", encoding="text/plain")
    expect(riskplan.MalformedPayloadError, client.query, key(name3, "risk"), b"{oops", encoding=None)


# -- unsupported_encoding --------------------------------------------------------------

@pytest.mark.parametrize("enc", ["application/xml", "application/cbor", "image/png"])
def test_unsupported_encoding(client, name3, enc):
    expect(riskplan.UnsupportedEncodingError, client.query, key(name3, "plan"), {"time_limit": 1}, encoding=enc)


# -- payload_too_large ----------------------------------------------------------------

def test_payload_too_large(client, name3):
    body = b'{"points": [[0, 0]]}' + b" " * (1 << 20)   # valid JSON, just over 1 MiB
    expect(riskplan.PayloadTooLargeError, client.query, key(name3, "risk"), body)


def test_payload_just_under_the_limit_is_fine(client, name3):
    head = b'{"points": [[0, 0]]}'
    body = head + b" " * ((1 << 20) - len(head) - 16)
    assert client.query(key(name3, "risk"), body)["bounds"]


# -- limit_exceeded ---------------------------------------------------------------------

def test_limit_exceeded_points(client, name3):
    e = expect(riskplan.LimitExceededError, client.risk, name3, [[0.0, 0.0]] * 100_001)
    assert e.field is None or "points" in e.field


def test_limit_points_at_the_limit_is_fine(client, name3):
    assert client.risk(name3, [[0.0, 0.0]] * 100_000).shape == (100_000,)


def test_limit_exceeded_grid_side(client, name3):
    expect(riskplan.LimitExceededError, client.risk_grid, name3, [-1, -1], [1, 1], 317)


def test_limit_exceeded_scene_dimension(client, scene3, unique):
    s = dict(scene3, dim=9, workspace={"lower": [-1] * 9, "upper": [1] * 9}, start=[-1] * 9, goal=[1] * 9)
    with pytest.raises((riskplan.LimitExceededError, riskplan.InvalidSceneError)) as ei:
        client.apply(unique(), scene=s)
    validate("error", {"code": ei.value.code, "message": ei.value.message, "field": ei.value.field})


# -- invalid_scene_name -------------------------------------------------------------------

@pytest.mark.parametrize("bad", ["bad name", "x" * 129, "caf\u00e9", "a@b", "semi;colon"],
                         ids=["space", "129-chars", "non-ascii", "at", "semicolon"])
def test_invalid_scene_name(client, scene3, bad):
    expect(riskplan.InvalidSceneNameError, client.plan, bad, time_limit=1)
    expect(riskplan.InvalidSceneNameError, client.apply, bad, scene=scene3)
    expect(riskplan.InvalidSceneNameError, client.get_scene, bad)


def test_invalid_scene_name_wildcard_key(client):
    # a wildcard chunk where a name should be (the client refuses it; the raw query reaches
    # the server, which must answer invalid_scene_name rather than plan on every scene)
    with pytest.raises(riskplan.InvalidSceneNameError):
        client.plan("*")
    expect(riskplan.InvalidSceneNameError, client.query, "riskplan/scenes/*/plan", {"time_limit": 1})


def test_longest_valid_name_is_fine(client, scene3):
    name = "n" * 128
    assert client.apply(name, scene=scene3) >= 1


# -- unknown_scene -----------------------------------------------------------------------

def test_unknown_scene(client, unique):
    missing = unique("missing")
    expect(riskplan.UnknownSceneError, client.get_scene, missing)
    expect(riskplan.UnknownSceneError, client.plan, missing, time_limit=1)
    expect(riskplan.UnknownSceneError, client.verify, missing, segment=([0, 0], [1, 1]))
    expect(riskplan.UnknownSceneError, client.risk, missing, [[0, 0]])
    expect(riskplan.UnknownSceneError, client.apply, missing,
           changes=[{"op": "put", "id": "a", "poly": "0.01 - x1^2 - x2^2"}])


# -- invalid_scene ------------------------------------------------------------------------

def test_invalid_scene_bad_param(client, scene3, unique):
    s = json.loads(json.dumps(scene3))
    s["params"]["w"] = {"dist": "normal", "mean": 0.3, "std": -0.1}
    expect(riskplan.InvalidSceneError, client.apply, unique(), scene=s, field="params")


def test_invalid_scene_undeclared_parameter(client, scene3, unique):
    s = json.loads(json.dumps(scene3))
    s["obstacles"].append({"id": "ghost", "poly": "q^2 - x1^2"})
    expect(riskplan.InvalidSceneError, client.apply, unique(), scene=s, field="obstacles")


def test_invalid_scene_unknown_top_level_field(client, scene3, unique):
    s = dict(scene3, colour="blue")
    e = expect(riskplan.InvalidSceneError, client.apply, unique(), scene=s)
    assert "colour" in e.message or (e.field and "colour" in e.field)


def test_invalid_scene_bad_change(client, name3):
    expect(riskplan.InvalidSceneError, client.apply, name3,
           changes=[{"op": "put", "id": "bad", "poly": "x1 +* x2"}])
    expect(riskplan.InvalidSceneError, client.apply, name3,
           changes=[{"op": "put", "id": "bad", "poly": "x1 - 1", "params": {"z": {"dist": "uniform", "low": 2, "high": 1}}}])


# -- invalid_request -----------------------------------------------------------------------

@pytest.mark.parametrize("options,field", [
    (dict(delta=1.5), "delta"),
    (dict(delta=0.0), "delta"),
    (dict(time_limit=0.0), "time_limit"),
    (dict(time_limit=-3.0), "time_limit"),
    (dict(pieces=0), "pieces"),
    (dict(certifier="bogus"), "certifier"),
    (dict(planner="astar"), "planner"),
    (dict(start=[-1, -1, 0], goal=[1, 1, 0]), "start"),
    (dict(max_speed=-1.0), "max_speed"),
    (dict(max_speed=0.0), "max_speed"),
    (dict(max_accel=-2.0), "max_accel"),
    (dict(risk_mode="everything"), "risk_mode"),
    (dict(improve=True), "improve"),
])
def test_invalid_request_plan(client, name3, options, field):
    kwargs = dict(time_limit=1.0)
    kwargs.update(options)
    expect(riskplan.InvalidRequestError, client.plan, name3, **kwargs, field=field)


@pytest.mark.parametrize("kwargs,field", [
    (dict(segment=([-1, -1], [1, 1]), method="bogus"), "method"),
    (dict(segment=([-1, -1], [1, 1]), delta=1.0), "delta"),
    (dict(segment=([-1, -1, 0], [1, 1, 0])), "segment"),
])
def test_invalid_request_verify(client, name3, kwargs, field):
    expect(riskplan.InvalidRequestError, client.verify, name3, **kwargs, field=field)


def test_invalid_request_risk_wrong_dimension(client, name3):
    expect(riskplan.InvalidRequestError, client.risk, name3, [[0.0, 0.0, 0.0]], field="points")


def test_invalid_request_neither_or_both(client, name3):
    expect(riskplan.InvalidRequestError, client.query, key(name3, "verify"), {})
    expect(riskplan.InvalidRequestError, client.query, key(name3, "risk"), {})
    expect(riskplan.InvalidRequestError, client.query, key(name3, "risk"),
           {"points": [[0, 0]], "grid": {"lower": [-1, -1], "upper": [1, 1], "n": 3}})


def test_apply_with_neither_or_both(client, name3, scene3):
    for body in ({}, {"scene": scene3, "changes": []}):
        with pytest.raises((riskplan.InvalidRequestError, riskplan.MalformedPayloadError)) as ei:
            client.query(key(name3, "apply"), body)
        validate("error", {"code": ei.value.code, "message": ei.value.message, "field": ei.value.field})


# -- invalid_trajectory --------------------------------------------------------------------

def _traj(*pieces):
    return {"format": "riskplan-trajectory/1", "pieces": list(pieces)}


@pytest.mark.parametrize("traj", [
    _traj(),
    _traj({"t0": 0.5, "t1": 0.5, "coeffs": [[-1, 0], [-1, 0]]}),
    _traj({"t0": 0.0, "t1": 0.5, "coeffs": [[-1, 0], [-1, 4]]}, {"t0": 0.6, "t1": 1.0, "coeffs": [[-1, 0], [1, 0]]}),
    _traj({"t0": 0.0, "t1": 0.5, "coeffs": [[-1, 0], [-1, 4]]}, {"t0": 0.5, "t1": 1.0, "coeffs": [[0, 0], [0, 0]]}),
    _traj({"t0": 0.0, "t1": 1.0, "coeffs": [[-1, 2]]}),
    _traj({"t0": 0.0, "t1": 2.0, "coeffs": [[-1, 1], [-1, 1]]}),
    _traj({"t0": 0.0, "t1": 1.0, "coeffs": [[-1, 2, 0, 0, 0, 0, 0, 0, 0, 0], [-1, 2]]}),
    {"format": "riskplan-trajectory/2", "pieces": [{"t0": 0, "t1": 1, "coeffs": [[-1, 2], [-1, 2]]}]},
], ids=["no-pieces", "empty-interval", "gap", "jump", "wrong-dim", "outside-horizon", "degree-9", "format"])
def test_invalid_trajectory(client, name3, traj):
    expect(riskplan.InvalidTrajectoryError, client.query, key(name3, "verify"), {"trajectory": traj})


# -- outside_workspace / unsafe_endpoint ----------------------------------------------------

def test_outside_workspace(client, name3):
    expect(riskplan.OutsideWorkspaceError, client.plan, name3, start=[5, 5], goal=[1, 1], time_limit=1, field="start")
    expect(riskplan.OutsideWorkspaceError, client.plan, name3, start=[-1, -1], goal=[1, 1.5], time_limit=1, field="goal")


def test_unsafe_endpoint(client, name3):
    expect(riskplan.UnsafeEndpointError, client.plan, name3, start=[0, 0], goal=[1, 1], time_limit=1, field="start")
    # where the true risk exceeds Δ = 0.1 (radius w ~ U[0.3, 0.4]: Prob(w ≥ 0.38) = 0.2) no
    # bound can prove it safe (at 0.42 the default bound, auto, proves zero risk)
    expect(riskplan.UnsafeEndpointError, client.plan, name3, start=[-1, -1], goal=[0.38, 0], time_limit=1, field="goal")
    # ... and at 0.42, inside the Cantelli contour (radius ≈ 0.4289), with the paper's bound
    expect(riskplan.UnsafeEndpointError, client.plan, name3, start=[-1, -1], goal=[0.42, 0], time_limit=1,
           field="goal", bound="cantelli")


# -- no_plan -----------------------------------------------------------------------------------

def test_no_plan_enclosed_goal(client, ring_scene, unique):
    name = unique()
    client.apply(name, scene=ring_scene)
    t = time.monotonic()
    e = expect(riskplan.NoPlanError, client.plan, name, time_limit=0.5)
    assert time.monotonic() - t < 15
    assert e.field is None


def test_no_plan_endpoints_are_fine(client, ring_scene, unique):
    """The ring scene's start and goal are valid (so no_plan above is about the path)."""
    name = unique()
    client.apply(name, scene=ring_scene)
    assert client.verify(name, segment=([-1, -1], [-0.9, -0.9]))["safe"] is True
    assert client.risk(name, [[0.5, 0.5]])[0] < 0.1


# -- client-side: timeout and no_reply ------------------------------------------------------

@pytest.mark.slow  # waits 3 s for the abandoned plan to finish
def test_timeout_is_a_riskplan_error(client, ring_scene, unique):
    name = unique()
    client.apply(name, scene=ring_scene)
    t = time.monotonic()
    with pytest.raises(riskplan.QueryTimeoutError) as ei:
        client.plan(name, time_limit=3.0, timeout=0.5)
    assert ei.value.code == "timeout" and isinstance(ei.value, TimeoutError)
    assert time.monotonic() - t < 2.5
    time.sleep(3.0)  # let the abandoned plan finish before other tests


def test_no_reply_when_nothing_serves_the_key(client):
    with pytest.raises(riskplan.NoReplyError) as ei:
        client.query("nobody/serves/this", {})
    assert ei.value.code == "no_reply"


def test_unknown_key_under_riskplan_is_answered(client):
    """Not in the README: the server answers keys under riskplan/** that it does not
    serve with an error (rather than leaving the query without a reply)."""
    with pytest.raises(riskplan.RiskplanError) as ei:
        client.query("riskplan/nothing/serves/this", {})
    validate("error", {"code": ei.value.code, "message": ei.value.message, "field": ei.value.field})


def test_time_limit_above_the_server_cap(client, name3):
    """README: the time limit is capped by --max-plan-seconds (default 60); reading: a
    larger request is capped (success), or refused as limit_exceeded / invalid_request."""
    try:
        plan = client.plan(name3, time_limit=1e6, timeout=120)
        assert plan.certified
    except (riskplan.LimitExceededError, riskplan.InvalidRequestError) as e:
        assert e.field is None or "time_limit" in e.field


def test_wildcard_queries_get_one_reply(client):
    """A wildcard key reaches several of the server's queryables (status, echo and
    riskplan/**); it is still answered once."""
    for key in ["riskplan/*", "riskplan/**", "riskplan/scenes/*/plan"]:
        with pytest.raises(riskplan.RiskplanError):
            client.query(key, {})
        assert client.last_replies == 1, key
