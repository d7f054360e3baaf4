"""Tests that need no riskplan server: the schemas and examples of proto/, the Plan
helpers, the error classes, and the client's reply handling against a fake Zenoh
queryable written in Python."""
from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
import zenoh

import riskplan
from riskplan import errors as E

from conftest import EXAMPLES, REPO, SCHEMAS, free_port, load_schema, validate

MESSAGES = [
    "apply_request", "apply_reply", "obstacle_put", "plan_request", "plan_reply", "verify_request",
    "verify_reply", "risk_request", "risk_reply", "scene_reply", "status_reply", "error",
]
ALL_EXAMPLES = sorted(EXAMPLES.glob("*.json"))


# -- schemas and examples ------------------------------------------------------------

@pytest.mark.parametrize("message", MESSAGES)
def test_schema_is_valid_draft_2020_12(message):
    import jsonschema

    schema = load_schema(message)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)


def test_one_schema_per_message_and_no_strays():
    assert sorted(p.name for p in SCHEMAS.glob("*.schema.json")) == sorted(f"{m}.schema.json" for m in MESSAGES)


def test_every_message_has_an_example():
    have = {p.name.split(".")[0] for p in ALL_EXAMPLES}
    assert set(MESSAGES) <= have, set(MESSAGES) - have
    assert have <= set(MESSAGES), have - set(MESSAGES)


def test_every_error_code_has_an_example():
    codes = load_schema("error")["properties"]["code"]["enum"]
    assert sorted(codes) == sorted(p.name.split(".")[1] for p in EXAMPLES.glob("error.*.json"))


@pytest.mark.parametrize("path", ALL_EXAMPLES, ids=lambda p: p.name)
def test_example_validates_against_its_schema(path):
    validate(path.name.split(".")[0], json.loads(path.read_text()))


@pytest.mark.parametrize("message,payload", [
    ("apply_request", {}),
    ("apply_request", {"scene": json.loads((EXAMPLES / "apply_request.scene.json").read_text())["scene"],
                       "changes": []}),
    ("apply_request", {"changes": [{"op": "put", "id": "a"}]}),
    ("apply_request", {"changes": [{"op": "move", "id": "a"}]}),
    ("plan_request", {"time_limt": 3}),
    ("plan_request", {"planner": "astar"}),
    ("plan_request", {"time_limit": 0}),
    ("plan_request", {"delta": 1.0}),
    ("plan_request", {"seed": -1}),
    ("verify_request", {"segment": {"from": [0, 0], "to": [1, 1]}, "trajectory": {"format": "riskplan-trajectory/1", "pieces": []}}),
    ("verify_request", {"segment": {"from": [0, 0]}}),
    ("verify_request", {"segment": {"from": [0, 0], "to": [1, 1]}, "method": "fast"}),
    ("risk_request", {"points": [[0, 0]], "grid": {"lower": [0, 0], "upper": [1, 1], "n": 3}}),
    ("risk_request", {"grid": {"lower": [0, 0], "upper": [1, 1], "n": 501}}),
    ("obstacle_put", {"poly": "x1", "color": "red"}),
    ("error", {"code": "oops", "message": "", "field": None}),
    ("error", {"code": "busy", "message": ""}),
    ("scene_reply", {"name": "a b", "revision": 1, "scene": {}}),
])
def test_schemas_reject_invalid_payloads(message, payload):
    with pytest.raises(AssertionError):
        validate(message, payload)


def test_scene_schema_accepts_every_reference_scene():
    from conftest import SCENES

    paths = sorted(SCENES.glob("*.json"))
    assert paths, f"no reference scenes in {SCENES}"
    for p in paths:
        validate("apply_request", {"scene": json.loads(p.read_text())})


def test_reference_scenes_come_from_the_repository():
    """conftest reads scenes/ of the repository (unless $RISKPLAN_SCENES says otherwise)."""
    import os

    from conftest import SCENES

    if not os.environ.get("RISKPLAN_SCENES"):
        assert SCENES == REPO / "scenes"
    assert (SCENES / "illustrative-3.json").is_file()


def test_scene_schema_rejects_unknown_top_level_fields():
    from conftest import load_scene

    s = load_scene("illustrative-3")
    s["colour"] = "blue"
    with pytest.raises(AssertionError):
        validate("apply_request", {"scene": s})


# -- Plan helpers ----------------------------------------------------------------------

def test_plan_helpers_on_the_golden_plan_reply():
    raw = json.loads((EXAMPLES / "plan_reply.rrt_sos.json").read_text())
    plan = riskplan.Plan(raw)
    assert plan.certified and plan.revision == raw["revision"] and plan.planner == "rrt-sos"
    wp = plan.waypoints()
    assert wp.shape == (len(raw["pieces"]) + 1, 2)
    np.testing.assert_allclose(wp[0], [-1, -1], atol=1e-12)
    np.testing.assert_allclose(wp[-1], [1, 1], atol=1e-9)
    xs = plan.sample(101)
    assert xs.shape == (101, 2)
    np.testing.assert_allclose(xs[0], wp[0], atol=1e-12)
    np.testing.assert_allclose(xs[-1], wp[-1], atol=1e-9)
    ts, xs2 = plan.sample(11, return_times=True)
    assert ts[0] == plan.t0 and ts[-1] == plan.t1 and xs2.shape == (11, 2)
    # continuity at the junctions
    for p, q in zip(raw["pieces"], raw["pieces"][1:]):
        np.testing.assert_allclose(plan.position(p["t1"] - 1e-12), plan.position(q["t0"]), atol=1e-9)
    assert plan.position(0.0).shape == (2,)
    assert abs(plan.length() - raw["stats"]["path_length"]) < 1e-3
    assert set(plan.trajectory()) == {"format", "pieces"}


# -- errors ------------------------------------------------------------------------------

def test_every_documented_code_has_its_class():
    codes = load_schema("error")["properties"]["code"]["enum"]
    for code in codes:
        cls = E.ERRORS_BY_CODE[code]
        assert issubclass(cls, riskplan.RiskplanError) and cls is not riskplan.RiskplanError
        e = E.error_from_reply({"code": code, "message": "m", "field": "f"})
        assert type(e) is cls and e.code == code and e.message == "m" and e.field == "f"


def test_unknown_code_gives_the_generic_error():
    e = E.error_from_reply({"code": "brand_new", "message": "m", "field": None})
    assert type(e) is riskplan.RiskplanError and e.code == "brand_new" and e.field is None


def test_timeout_and_no_reply_classes():
    assert issubclass(riskplan.QueryTimeoutError, TimeoutError)
    assert riskplan.QueryTimeoutError().code == "timeout"
    assert riskplan.NoReplyError().code == "no_reply"
    assert issubclass(riskplan.BusyError, riskplan.RiskplanError)
    assert issubclass(riskplan.DuplicateReplyError, riskplan.RiskplanError)
    assert riskplan.DuplicateReplyError(count=2).code == "duplicate_reply"
    assert riskplan.DuplicateReplyError(count=2).count == 2


# -- one reply per query: the client's selection, without Zenoh --------------------------

def _fake_ok(obj):
    data = json.dumps(obj).encode()
    return SimpleNamespace(ok=SimpleNamespace(payload=SimpleNamespace(to_bytes=lambda: data),
                                              encoding="application/json"), err=None)


def _fake_err(text, encoding="application/json"):
    data = text.encode()
    return SimpleNamespace(ok=None, err=SimpleNamespace(payload=SimpleNamespace(to_bytes=lambda: data),
                                                        encoding=encoding))


BUSY = json.dumps({"code": "busy", "message": "full", "field": None})


def test_one_reply_is_selected():
    from riskplan.client import one_reply

    r = _fake_ok({"a": 1})
    assert one_reply("k", [r]) is r
    e = _fake_err(BUSY)
    assert one_reply("k", [e]) is e
    # Zenoh's local Timeout next to a real reply is not a second reply
    assert one_reply("k", [r, _fake_err("Timeout", "zenoh/string")]) is r
    assert one_reply("k", [_fake_err("Timeout", "zenoh/string"), e]) is e


@pytest.mark.parametrize("replies", [
    [_fake_ok({"a": 1}), _fake_ok({"a": 1})],
    [_fake_ok({"a": 1}), _fake_ok({"a": 2})],
    [_fake_ok({"a": 1}), _fake_err(BUSY)],
    [_fake_err(BUSY), _fake_ok({"a": 1})],
    [_fake_err(BUSY), _fake_err(BUSY)],
    [_fake_ok({"a": 1}), _fake_err("Timeout", "zenoh/string"), _fake_ok({"a": 1})],
], ids=["ok-ok-same", "ok-ok-different", "ok-err", "err-ok", "err-err", "ok-timeout-ok"])
def test_several_replies_are_an_error(replies):
    from riskplan.client import one_reply

    with pytest.raises(riskplan.DuplicateReplyError) as ei:
        one_reply("riskplan/status", replies)
    e = ei.value
    assert isinstance(e, riskplan.RiskplanError) and e.code == "duplicate_reply"
    assert e.count == len([r for r in replies if r.ok is not None or b"Timeout" not in r.err.payload.to_bytes()])
    assert "riskplan/status" in e.message


def test_no_reply_and_only_a_timeout():
    from riskplan.client import one_reply

    with pytest.raises(riskplan.NoReplyError):
        one_reply("k", [])
    with pytest.raises(riskplan.QueryTimeoutError):
        one_reply("k", [_fake_err("Timeout", "zenoh/string")])


def test_client_refuses_key_expression_specials():
    with pytest.raises(riskplan.InvalidSceneNameError):
        riskplan.scene_key("a/b")
    with pytest.raises(riskplan.InvalidSceneNameError):
        riskplan.scene_key("*")
    with pytest.raises(riskplan.InvalidSceneNameError):
        riskplan.scene_key("")
    assert riskplan.scene_key("ok-name.1", "plan") == "riskplan/scenes/ok-name.1/plan"


def test_connect_error_when_nothing_listens():
    t = time.monotonic()
    with pytest.raises(riskplan.ConnectError):
        riskplan.Client(f"tcp/127.0.0.1:{free_port()}", timeout=2)
    assert time.monotonic() - t < 10


# -- reply handling against a fake server ---------------------------------------------

@pytest.fixture(scope="module")
def fake():
    """A Python Zenoh peer on 127.0.0.1 with queryables that answer in fixed ways."""
    port = free_port()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    held = []
    J = zenoh.Encoding.APPLICATION_JSON

    def ok(q):
        q.reply(q.key_expr, json.dumps({"echo": json.loads(q.payload.to_bytes()) if q.payload else None,
                                        "encoding": str(q.encoding)}), encoding=J)

    def busy(q):
        q.reply_err(json.dumps({"code": "busy", "message": "full", "field": None}), encoding=J)

    def weird(q):
        q.reply_err("not json", encoding=zenoh.Encoding.TEXT_PLAIN)

    def twice(q):
        ok(q)
        ok(q)

    def ok_then_busy(q):
        ok(q)
        busy(q)

    qs = [
        session.declare_queryable("fake/ok", ok),
        session.declare_queryable("fake/busy", busy),
        session.declare_queryable("fake/weird", weird),
        session.declare_queryable("fake/hang", lambda q: held.append(q)),
        session.declare_queryable("fake/twice", twice),
        session.declare_queryable("fake/ok-then-busy", ok_then_busy),
        # a second queryable on fake/ok2 next to the first: two "servers" of one key
        session.declare_queryable("fake/ok2", ok),
        session.declare_queryable("fake/ok2", ok),
    ]
    yield f"tcp/127.0.0.1:{port}"
    del held[:]
    for q in qs:
        q.undeclare()
    session.close()


def test_fake_ok_reply_is_decoded(fake):
    with riskplan.Client(fake, timeout=5) as c:
        r = c.query("fake/ok", {"a": 1})
        assert r == {"echo": {"a": 1}, "encoding": "application/json"}
        assert c.last_replies == 1


def test_fake_error_reply_raises_its_class(fake):
    with riskplan.Client(fake, timeout=5) as c:
        with pytest.raises(riskplan.BusyError) as ei:
            c.query("fake/busy", {})
        assert ei.value.code == "busy" and ei.value.message == "full" and ei.value.field is None


def test_fake_non_json_error_is_generic(fake):
    with riskplan.Client(fake, timeout=5) as c:
        with pytest.raises(riskplan.RiskplanError) as ei:
            c.query("fake/weird", {})
        assert ei.value.code == "unknown" and "not json" in ei.value.message


def test_fake_hung_server_gives_a_timeout(fake):
    with riskplan.Client(fake, timeout=5) as c:
        t = time.monotonic()
        with pytest.raises(riskplan.QueryTimeoutError) as ei:
            c.query("fake/hang", {}, timeout=0.5)
        assert ei.value.code == "timeout"
        assert 0.4 < time.monotonic() - t < 4


def test_fake_nothing_serves_gives_no_reply(fake):
    with riskplan.Client(fake, timeout=5) as c:
        t = time.monotonic()
        with pytest.raises(riskplan.NoReplyError) as ei:
            c.query("fake/absent", {})
        assert ei.value.code == "no_reply"
        assert time.monotonic() - t < 2


@pytest.mark.parametrize("key,replies", [("fake/twice", 2), ("fake/ok-then-busy", 2), ("fake/ok2", 2)])
def test_fake_several_replies_raise(fake, key, replies):
    with riskplan.Client(fake, timeout=5) as c:
        with pytest.raises(riskplan.DuplicateReplyError) as ei:
            c.query(key, {"a": 1})
        assert ei.value.count == replies and c.last_replies == replies
        # the next query on a well-behaved key is fine again
        assert c.query("fake/ok", {"a": 1})["echo"] == {"a": 1} and c.last_replies == 1
