"""Statements of proto/README.md checked one by one against the server (beyond the
happy paths of test_service.py and the error codes of test_errors.py)."""
from __future__ import annotations

import json
import time

import pytest

import riskplan

from conftest import Server, load_scene, validate, wait_for


def _put_counter(client):
    return client.status()["requests"].get("put", {"served": 0, "failed": 0})


@pytest.fixture
def name3(client, scene3, unique):
    name = unique()
    client.apply(name, scene=scene3)
    return name


def test_exactly_one_reply_and_json_replies(client, name3):
    """"Every query gets exactly one reply"; "A request's encoding selects the reply's"."""
    for enc in ("application/json", "text/plain", None):
        client.query(f"riskplan/scenes/{name3}/risk", {"points": [[1, 1]]}, encoding=enc)
        assert client.last_replies == 1
        assert client.last_encoding == "application/json", (enc, client.last_encoding)
        with pytest.raises(riskplan.InvalidRequestError):
            client.query(f"riskplan/scenes/{name3}/risk", {"points": [[1, 1, 1]]}, encoding=enc)
        assert client.last_replies == 1
        assert client.last_encoding == "application/json", (enc, client.last_encoding)
    client.status()
    assert client.last_replies == 1 and client.last_encoding == "application/json"
    client.plan(name3, time_limit=20)
    assert client.last_replies == 1


def test_every_query_gets_exactly_one_reply_from_one_server(client, scene3, ring_scene, unique):
    """"Every query gets exactly one reply": each kind of query the client sends
    (apply, get, plan, verify, risk, status, echo), answered with a success or with an
    error, gets one reply, from the one server the client is connected to. (Puts and
    deletes are fire and forget: no reply at all.) More than one reply raises
    DuplicateReplyError in the client, so the calls below fail on a duplicate too."""
    info = client._session.info
    servers = [str(z) for z in [*info.peers_zid(), *info.routers_zid()]]
    assert len(servers) == 1, servers
    name, ring, missing = unique(), unique("ring"), unique("missing")
    seen = []

    def once(what, fn, *args, error=None, **kwargs):
        if error is None:
            out = fn(*args, **kwargs)
        else:
            with pytest.raises(error):
                fn(*args, **kwargs)
            out = None
        assert client.last_replies == 1, (what, client.last_replies)
        assert client.last_repliers == servers, (what, client.last_repliers, servers)
        seen.append(what)
        return out

    rev = once("apply scene", client.apply, name, scene=scene3)
    once("apply changes", client.apply, name, changes=[
        {"op": "put", "id": "pole", "poly": "r^2 - (x1 - 0.5)^2 - (x2 + 0.5)^2",
         "params": {"r": {"dist": "uniform", "low": 0.05, "high": 0.1}}}])
    assert once("get", client.get_scene, name)["revision"] == rev + 1
    plan = once("plan", client.plan, name, time_limit=20)
    assert once("verify trajectory", client.verify, name, trajectory=plan)["safe"] is True
    once("verify segment", client.verify, name, segment=([-1, -1], [1, 1]))
    once("risk points", client.risk, name, [[0.0, 0.0], [1.0, 1.0]])
    once("risk grid", client.risk_grid, name, [-1, -1], [1, 1], 5)
    once("status", client.status)
    assert once("echo", client.query, "riskplan/echo", {"ping": [1, 2]}) == {"ping": [1, 2]}
    # error replies
    once("get unknown", client.get_scene, missing, error=riskplan.UnknownSceneError)
    once("plan unknown", client.plan, missing, time_limit=1, error=riskplan.UnknownSceneError)
    once("apply bad change", client.apply, name, changes=[{"op": "delete", "id": "nope"}],
         error=riskplan.InvalidRequestError)
    once("apply bad scene", client.apply, name, scene=dict(scene3, colour="blue"), error=riskplan.InvalidSceneError)
    once("verify bad method", client.verify, name, segment=([-1, -1], [1, 1]), method="bogus",
         error=riskplan.InvalidRequestError)
    once("risk wrong dimension", client.risk, name, [[0.0, 0.0, 0.0]], error=riskplan.InvalidRequestError)
    once("plan unsupported encoding", client.query, f"riskplan/scenes/{name}/plan", {}, encoding="application/xml",
         error=riskplan.UnsupportedEncodingError)
    once("apply ring", client.apply, ring, scene=ring_scene)
    once("plan no plan", client.plan, ring, time_limit=0.5, error=riskplan.NoPlanError)
    assert len(seen) == 19


def test_two_servers_on_one_network_are_two_replies(binary, tmp_path):
    """The check above can fail: a second server meshed with the first as a *peer*
    (--connect, peer mode) also serves riskplan/**, and peer routing sends each query on
    a shared key to both (even with complete queryables), so the client refuses the two
    replies. That topology is not supported: several servers run as a cluster behind a
    router (deploy/cluster, test_cluster.py), where each query gets one reply. (Reads
    through the client go to one server's own key — proto/README.md, "Discovery" — and
    get one reply even here; a write to the shared key reaches both primaries.)"""
    a = Server(binary, tmp_path / "a").start()
    b = None
    try:
        b = Server(binary, tmp_path / "b", extra=["--connect", a.endpoint]).start()
        with a.client(timeout=5) as c:
            def both_answer():
                try:
                    c.query("riskplan/scenes/nothing/apply", {"changes": []})
                except riskplan.DuplicateReplyError:
                    return True
                except riskplan.RiskplanError:
                    return False
                return False

            wait_for(both_answer, what="the second server to answer through the first")
            assert c.last_replies == 2 and len(set(c.last_repliers)) == 2, c.last_repliers
            wait_for(lambda: len(c.servers()) == 2, what="the client to see both servers")
            c.status()
            assert c.last_replies == 1
    finally:
        if b is not None:
            b.kill()
        a.kill()


def test_unsupported_encoding_error_is_json(client, name3):
    with pytest.raises(riskplan.UnsupportedEncodingError):
        client.query(f"riskplan/scenes/{name3}/plan", {}, encoding="application/xml")
    assert client.last_encoding == "application/json"


def test_obstacle_put_rebuilds_only_that_obstacle(client, scene3, unique):
    """"each one bumps the scene's revision and rebuilds only that obstacle's contour"."""
    name = unique()
    s = json.loads(json.dumps(scene3))
    s["params"]["r"] = {"dist": "uniform", "low": 0.05, "high": 0.1}
    s["obstacles"].append({"id": "pole", "poly": "r^2 - (x1 - 0.5)^2 - (x2 + 0.5)^2"})
    rev = client.apply(name, scene=s)
    client.risk(name, [[0.9, 0.9]])
    before = client.status()["cache"]
    client.update_obstacle(name, "pole", "r^2 - (x1 - 0.55)^2 - (x2 + 0.5)^2")
    wait_for(lambda: client.get_scene(name)["revision"] == rev + 1, what="revision bump")
    client.risk(name, [[0.9, 0.9]])
    after = client.status()["cache"]
    assert after["misses"] - before["misses"] == 1, (before, after)


def test_failed_obstacle_puts_are_counted(client, name3):
    before = _put_counter(client)
    rev = client.get_scene(name3)["revision"]
    client.put(f"riskplan/scenes/{name3}/obstacles/x", {"poly": "x1 - 10", "colour": "red"})  # unknown field
    client.put(f"riskplan/scenes/{name3}/obstacles/y", {"poly": "x1 +* 2"})                    # bad polynomial
    client.put(f"riskplan/scenes/{name3}/obstacles/z", b"{nope")                              # bad JSON
    wait_for(lambda: _put_counter(client)["failed"] >= before["failed"] + 3, what="3 failed puts counted")
    assert client.get_scene(name3)["revision"] == rev
    assert _put_counter(client)["served"] == before["served"]


def test_oversized_scene_put_is_refused(client, scene3, unique):
    """MAX_PAYLOAD_BYTES (1 MiB) applies to scene puts too: an oversized put is refused
    (counted in requests.put.failed), not applied."""
    name = unique()
    before = _put_counter(client)
    body = json.dumps(scene3).encode() + b" " * (1 << 20)
    client.put(f"riskplan/scenes/{name}", body)
    wait_for(lambda: _put_counter(client) != before, what="the put to be counted")
    with pytest.raises(riskplan.UnknownSceneError):
        client.get_scene(name)
    assert _put_counter(client)["failed"] == before["failed"] + 1


def test_oversized_obstacle_put_is_refused(client, name3):
    before = _put_counter(client)
    rev = client.get_scene(name3)["revision"]
    client.put(f"riskplan/scenes/{name3}/obstacles/big", b'{"poly": "x1 - 10"}' + b" " * (1 << 20))
    wait_for(lambda: _put_counter(client)["failed"] == before["failed"] + 1, what="the put to be counted failed")
    assert client.get_scene(name3)["revision"] == rev


def test_unknown_field_in_a_verify_trajectory_is_an_error(client, name3):
    """"unknown fields are errors": also inside the trajectory of a verify_request."""
    traj = {"format": "riskplan-trajectory/1", "colour": "red",
            "pieces": [{"t0": 0, "t1": 1, "coeffs": [[-1, 0], [-1, 2]]}]}
    with pytest.raises((riskplan.MalformedPayloadError, riskplan.InvalidTrajectoryError)):
        client.query(f"riskplan/scenes/{name3}/verify", {"trajectory": traj})


def test_unknown_field_in_a_delete_change_is_an_error(client, name3):
    """A delete change is {"op": "delete", "id"}: a "poly" there is an unknown field."""
    rev = client.get_scene(name3)["revision"]
    with pytest.raises(riskplan.InvalidRequestError) as ei:
        client.apply(name3, changes=[{"op": "delete", "id": "disk", "poly": "x1"}])
    assert ei.value.field == "changes[0]"
    assert client.get_scene(name3)["revision"] == rev


@pytest.mark.parametrize("change", [
    {"op": "delete", "id": "no-such-obstacle"},
    {"op": "put", "id": "", "poly": "x1 - 10"},
    {"op": "put", "id": "nopoly"},
], ids=["delete-missing", "empty-id", "put-without-poly"])
def test_a_malformed_change_is_invalid_request(client, name3, change):
    """README: invalid_request covers a malformed change (a put without poly, an id not in the scene, ...)."""
    rev = client.get_scene(name3)["revision"]
    with pytest.raises(riskplan.RiskplanError) as ei:
        client.apply(name3, changes=[change])
    assert ei.value.code == "invalid_request", repr(ei.value)
    assert ei.value.field is not None and ei.value.field.startswith("changes[0]")
    assert client.get_scene(name3)["revision"] == rev


def test_a_change_producing_an_invalid_scene_is_invalid_scene(client, name3):
    """README: invalid_scene is "the scene, or the scene a change produces, fails validation"."""
    with pytest.raises(riskplan.InvalidSceneError):
        client.apply(name3, changes=[{"op": "put", "id": "bad", "poly": "x1 + + q"}])


def test_apply_renames_the_scene_to_its_key(client, scene3, unique):
    """Reading: the scene is served under its key name; scene_reply.name, the stored
    scene's name and plan_reply.scene all say so."""
    name = unique()
    client.apply(name, scene=scene3)
    got = client.get_scene(name)
    assert got["name"] == name
    assert got["scene"]["name"] in (name, scene3["name"])
    assert client.plan(name, time_limit=20).scene == name


@pytest.fixture(scope="module")
def capped(binary, tmp_path_factory):
    s = Server(binary, tmp_path_factory.mktemp("riskplan-capped"), extra=["--max-plan-seconds", "1"]).start()
    yield s
    s.stop()


def test_time_limit_is_capped_by_max_plan_seconds(capped, ring_scene):
    with capped.client() as c:
        c.apply("ring", scene=ring_scene)
        t = time.monotonic()
        with pytest.raises(riskplan.RiskplanError) as ei:
            c.plan("ring", time_limit=30.0)
        elapsed = time.monotonic() - t
        assert ei.value.code in ("no_plan", "limit_exceeded"), repr(ei.value)
        assert elapsed < 10, elapsed


@pytest.mark.parametrize("name", ["a", "A-Z_0.9", "-dash-first"])
def test_every_name_the_readme_allows_is_accepted(client, scene3, name):
    """README: "1–128 characters from A–Z a–z 0–9 _ - ., not starting with '.'"."""
    assert client.apply(name, scene=scene3) >= 1
    assert client.get_scene(name)["name"] == name


def test_a_name_starting_with_a_dot_is_refused(client, scene3):
    with pytest.raises(riskplan.RiskplanError) as ei:
        client.apply(".hidden", scene=scene3)
    assert ei.value.code == "invalid_scene_name"
