"""proto/examples/*.json through the schemas and, for requests, through the server: a
valid example must be accepted (success, or a documented error other than
malformed_payload: e.g. no_plan when a planner finds nothing in its time limit)."""
from __future__ import annotations

import json

import pytest

import riskplan

from conftest import EXAMPLES, load_scene, validate, wait_for

REQUESTS = sorted(p for p in EXAMPLES.glob("*.json")
                  if p.name.split(".")[0] in ("apply_request", "plan_request", "verify_request", "risk_request"))
PUTS = sorted(EXAMPLES.glob("obstacle_put.*.json"))
REPLY_OF = {"apply_request": "apply_reply", "plan_request": "plan_reply", "verify_request": "verify_reply",
            "risk_request": "risk_reply"}
OP_OF = {"apply_request": "apply", "plan_request": "plan", "verify_request": "verify", "risk_request": "risk"}
# documented outcomes other than success that a valid example may meet
ALLOWED_ERRORS = {
    "plan_request.improve.json": {"no_plan"},
    "plan_request.mc_rrt.json": {"no_plan"},
}


def test_there_are_request_examples():
    kinds = {p.name.split(".")[0] for p in REQUESTS}
    assert kinds == set(REPLY_OF)
    assert PUTS


@pytest.mark.parametrize("path", REQUESTS, ids=lambda p: p.name)
def test_request_example_round_trips_through_the_server(client, unique, path):
    message = path.name.split(".")[0]
    body = json.loads(path.read_text())
    validate(message, body)
    name = unique()
    client.apply(name, scene=load_scene("illustrative-3"))
    if path.name == "apply_request.delete.json":
        client.query(f"riskplan/scenes/{name}/apply", json.loads((EXAMPLES / "apply_request.changes.json").read_text()))
    # sent byte for byte as stored
    try:
        reply = client.query(f"riskplan/scenes/{name}/{OP_OF[message]}", path.read_bytes(), timeout=120)
    except riskplan.RiskplanError as e:
        assert e.code in ALLOWED_ERRORS.get(path.name, set()), f"{path.name}: {e!r}"
        validate("error", {"code": e.code, "message": e.message, "field": e.field})
        return
    validate(REPLY_OF[message], reply)


@pytest.mark.parametrize("path", PUTS, ids=lambda p: p.name)
def test_obstacle_put_example_is_applied(client, unique, path):
    body = json.loads(path.read_text())
    validate("obstacle_put", body)
    name = unique()
    rev = client.apply(name, scene=load_scene("illustrative-3"))
    client.put(f"riskplan/scenes/{name}/obstacles/example", path.read_bytes())
    got = wait_for(lambda: (r := client.get_scene(name))["revision"] > rev and r, what=f"{path.name} applied")
    (ob,) = [o for o in got["scene"]["obstacles"] if o["id"] == "example"]
    assert ob["poly"] == body["poly"]
    for p in body.get("params", {}):
        assert p in got["scene"]["params"]
