"""Small hostile messages that used to crash or freeze the server (issue: "a service that
no message can crash or freeze") get a typed error or are refused, and the server keeps
answering `status` quickly. What is covered so far: bounded bincode decoding, and the
parser's nesting, degree, terms and work limits, the exact-number limits and the
scene's contour budget (proto/README.md, "Limits")."""
from __future__ import annotations

import json
import time

import pytest

import riskplan

BINCODE = "application/bincode"
STATUS_LIMIT_S = 1.0   # status must answer well within this after each hostile message


def assert_alive(client):
    t = time.monotonic()
    client.status(timeout=5)
    assert time.monotonic() - t < STATUS_LIMIT_S


@pytest.fixture
def name3(client, scene3, unique):
    name = unique()
    client.apply(name, scene=scene3)
    return name


@pytest.mark.parametrize("payload", [
    bytes([0x01, 0xFD, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00]),   # claims a 2^40-byte string
    bytes([0x01, 0xFD, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80]),   # claims 2^63 bytes
], ids=["claim-2^40", "claim-2^63"])
@pytest.mark.parametrize("op", ["verify", "apply", "plan", "risk"])
def test_bincode_length_claims_are_malformed_payloads(client, name3, payload, op):
    # the error reply comes in the request's encoding (bincode), which this client does
    # not decode: its code is still readable in the raw reply
    with pytest.raises(riskplan.RiskplanError) as ei:
        client.query(f"riskplan/scenes/{name3}/{op}", payload, encoding=BINCODE)
    assert "malformed_payload" in str(ei.value), ei.value
    assert client.last_replies == 1
    assert_alive(client)


HOSTILE_POLYS = {
    "2000-parentheses": "(" * 2000 + "x1" + ")" * 2000,
    "10000-minus-signs": "-" * 10000 + "x1",
    "nested-powers": "(((x1+1)^32)^32)^32",
    "wide-expansion": "(x1+x2+w+1)^30",
    "huge-number": "1e4000*x1 - w",
}


@pytest.mark.parametrize("poly", list(HOSTILE_POLYS.values()), ids=list(HOSTILE_POLYS))
def test_hostile_polynomials_in_apply_are_invalid_scenes(client, name3, poly):
    rev = client.get_scene(name3)["revision"]
    t = time.monotonic()
    with pytest.raises(riskplan.InvalidSceneError) as ei:
        client.apply(name3, changes=[{"op": "put", "id": "evil", "poly": poly}])
    assert time.monotonic() - t < 5.0
    assert "obstacles" in (ei.value.field or "")
    assert client.get_scene(name3)["revision"] == rev
    assert_alive(client)


@pytest.mark.parametrize("poly", list(HOSTILE_POLYS.values()), ids=list(HOSTILE_POLYS))
def test_hostile_obstacle_puts_are_refused_and_counted(client, name3, poly):
    def failed():
        return client.status()["requests"].get("put", {}).get("failed", 0)

    before, rev = failed(), client.get_scene(name3)["revision"]
    client.update_obstacle(name3, "evil", poly)
    deadline = time.monotonic() + 5.0
    while failed() == before:
        assert time.monotonic() < deadline, "the put was neither refused nor counted"
        time.sleep(0.02)
    assert client.get_scene(name3)["revision"] == rev
    assert_alive(client)


def test_costly_distributions_and_contours_are_invalid_scenes(client, scene3, unique):
    name = unique()
    cases = []
    s = json.loads(json.dumps(scene3))
    s["params"]["w"] = {"dist": "discrete", "values": [0.35] * 300, "weights": [f"1/{600 + i}" for i in range(300)]}
    cases.append(s)
    s = json.loads(json.dumps(scene3))
    s["params"]["w"] = {"dist": "beta", "alpha": "1e4000", "beta": 2, "low": 0.3, "high": 0.4}
    cases.append(s)
    s = json.loads(json.dumps(scene3))
    s["params"]["v"] = {"dist": "normal", "mean": 0, "std": 1}
    s["obstacles"] = [{"id": f"o{i}", "poly": f"0.00001*(x1+x2+w+v+{i + 1})^8 - 1"} for i in range(12)]
    cases.append(s)
    for s in cases:
        t = time.monotonic()
        with pytest.raises(riskplan.InvalidSceneError):
            client.apply(name, scene=s)
        assert time.monotonic() - t < 5.0
        assert_alive(client)
