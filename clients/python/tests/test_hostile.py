"""Small hostile messages get a typed error or are refused, and the server keeps answering
`status` quickly: no message may crash or freeze the service. What is covered: bounded
bincode decoding, and the parser's nesting, degree, terms and work limits, the exact-number
limits and the scene's contour budget (proto/README.md, "Limits")."""
from __future__ import annotations

import json
import time

import pytest

import riskplan

import threading

from conftest import Server, load_scene, validate

BINCODE = "application/bincode"
STATUS_LIMIT_S = 0.1   # status answers within 100 ms after each hostile message


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


def test_reply_size_is_bounded_by_a_typed_error(client, unique):
    """A reply over the size limit is `limit_exceeded` naming what to ask instead, never
    silence; a grid side beyond √(point limit) is refused before any work."""
    name = unique()
    client.apply(name, scene=load_scene("example-d1-cluttered-2d"))
    with pytest.raises(riskplan.LimitExceededError):
        client.risk_grid(name, [0, 0], [5, 5], 500)       # 250 000 points: over the point limit
    t = time.monotonic()
    with pytest.raises(riskplan.LimitExceededError) as ei:
        client.risk_grid(name, [0, 0], [5, 5], 316, timeout=60)   # 99 856 points × 8 obstacles: too large a reply
    assert "summary" in ei.value.message or "fewer points" in ei.value.message
    assert client.last_replies == 1
    assert time.monotonic() - t < 30
    assert_alive(client)
    _, _, bounds = client.risk_grid(name, [0, 0], [5, 5], 100)
    assert bounds.shape == (100, 100)


def test_verify_summary_keeps_only_the_first_unsafe_piece(client, scene3, unique):
    name = unique()
    client.apply(name, scene=scene3)
    plan = client.plan(name, time_limit=10)
    full = client.verify(name, trajectory=plan)
    short = client.verify(name, trajectory=plan, summary=True)
    assert full["safe"] and short["safe"] and short["pieces"] == [] and len(full["pieces"]) >= 2
    bad = client.verify(name, segment=([-1, -1], [1, 1]), summary=True)
    assert not bad["safe"] and len(bad["pieces"]) == 1 and not bad["pieces"][0]["safe"]


def test_verify_batches_of_segments_and_large_trajectories(client, unique):
    """A batch of segments is verified segment by segment (the reply names the ones not
    safe); a trajectory of far more pieces than a plan has (and a payload far above the
    1 MiB of other requests) is one query; the summary reply stays small; the limits
    are typed errors."""
    import random
    name = unique()
    client.apply(name, scene=load_scene("example-d1-cluttered-2d"))
    rng = random.Random(3)
    pts = [[rng.uniform(0, 5), rng.uniform(0, 5)] for _ in range(20_001)]
    n = len(pts) - 1
    segs = [{"from": pts[i], "to": pts[i + 1], "t0": i / n, "t1": (i + 1) / n} for i in range(n)]
    batch = client.verify(name, segments=segs[:300])
    validate("verify_reply", batch)
    assert batch["checked"] == 300 and len(batch["pieces"]) == 300
    not_safe = [i for i, p in enumerate(batch["pieces"]) if not p["safe"]]
    assert batch["not_safe_segments"] == not_safe and batch["not_safe"] == len(not_safe) > 0
    assert batch["first_not_safe"] == not_safe[0] and not batch["safe"]
    # the same segments one by one: the same verdicts
    for i in (not_safe[0], next(i for i in range(300) if i not in not_safe)):
        one = client.verify(name, segment=segs[i])
        assert one["safe"] == (i not in not_safe) and one["not_safe_segments"] == []
    # 20 000 pieces in one trajectory (a plan has at most 10 000): about 2.6 MB of JSON
    pieces = []
    for s_ in segs:
        rows = []
        for d in range(2):
            slope = (s_["to"][d] - s_["from"][d]) / (s_["t1"] - s_["t0"])
            rows.append([s_["from"][d] - slope * s_["t0"], slope])
        pieces.append({"t0": s_["t0"], "t1": s_["t1"], "coeffs": rows})
    short = client.verify(name, trajectory={"format": "riskplan-trajectory/1", "pieces": pieces}, summary=True)
    validate("verify_reply", short)
    assert short["checked"] == n and 0 < short["not_safe"] < n and len(short["pieces"]) == 1
    assert short["not_safe_segments"] == [] and len(json.dumps(short)) < 20_000
    batch = client.verify(name, segments=segs, summary=True)
    assert batch["checked"] == n and batch["not_safe"] == len(batch["not_safe_segments"]) == short["not_safe"]
    # limits: an empty batch, and both forms at once
    with pytest.raises(riskplan.LimitExceededError):
        client.query(f"riskplan/scenes/{name}/verify", {"segments": []})
    with pytest.raises(ValueError):
        client.verify(name, segment=segs[0], segments=segs[:2])
    assert_alive(client)


def test_verify_whole_path(client, unique):
    """``whole_path=True``: the reply bounds the probability that the trajectory meets the
    obstacle at some time; on illustrative-3 (radius w ~ U[0.3, 0.4]) a segment passing
    0.35 from the centre is met when w ≥ 0.35, with probability 0.5 (closed form): the
    bound (the partition of w's range) is at least that and within 0.02 of it; it is absent unless asked for; a batch of
    segments and a trajectory beyond 2 000 pieces are typed errors."""
    name = unique()
    client.apply(name, scene=load_scene("illustrative-3"))
    seg = ([-0.9, 0.35], [0.9, 0.35])
    plain = client.verify(name, segment=seg, summary=True)
    assert plain.get("whole_path_risk") is None
    reply = client.verify(name, segment=seg, summary=True, whole_path=True)
    validate("verify_reply", reply)
    w = reply["whole_path_risk"]
    # the radius is uniform: the parameter space is partitioned, within 0.02 of the truth
    assert 0.5 <= w["bound"] <= 0.52 and [o["id"] for o in w["obstacles"]] == ["disk"]
    assert len(w["obstacles"][0]["pieces"]) == 1 and w["obstacles"][0]["how"] == "partition"
    with pytest.raises(riskplan.InvalidRequestError):
        client.verify(name, segments=[seg, seg], whole_path=True)
    n = 2_001
    pieces = [{"t0": i / n, "t1": (i + 1) / n if i + 1 < n else 1.0, "coeffs": [[0.9, 0.0], [0.9, 0.0]]} for i in range(n)]
    with pytest.raises(riskplan.LimitExceededError):
        client.verify(name, trajectory={"format": "riskplan-trajectory/1", "pieces": pieces}, whole_path=True)
    assert_alive(client)


def slow_scene(scene3: dict, obstacles: int = 1, shift: int = 0) -> dict:
    """A valid scene whose contour is slow to build (tens of milliseconds): one 462-term
    obstacle, near the scene's contour budget (a second one would exceed it). Scenes of
    different `shift` have different polynomials (the server builds a polynomial's contour
    once and shares it)."""
    s = json.loads(json.dumps(scene3))
    s["params"]["v"] = {"dist": "normal", "mean": 0, "std": 1}
    s["obstacles"] = [
        {"id": f"o{i}", "poly": f"0.00001*(x1+x2+t+w+v+{i + 1 + shift})^6 - 1"} for i in range(obstacles)
    ]
    return s


def status_times(client, seconds: float):
    """Round-trip times of `status` queries sent back to back for `seconds`."""
    times = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        t = time.monotonic()
        client.status(timeout=5)
        times.append(time.monotonic() - t)
    return times


def test_slow_puts_do_not_hold_the_receive_loop(client, scene3, unique):
    name = unique()
    client.put(f"riskplan/scenes/{name}", slow_scene(scene3))
    times = status_times(client, 1.0)
    assert max(times) < 0.1, f"status took {max(times):.3f} s while a put was being applied"
    wait_for_scene = time.monotonic() + 20
    while True:
        try:
            client.get_scene(name)
            break
        except riskplan.UnknownSceneError:
            assert time.monotonic() < wait_for_scene, "the slow scene never arrived"
            time.sleep(0.05)


def test_status_and_echo_answer_while_every_worker_is_busy(binary, tmp_path, scene3, ring_scene):
    srv = Server(binary, tmp_path / "data", extra=["--workers", "1", "--queue", "4"]).start()
    try:
        with srv.client() as c:
            c.apply("ring", scene=ring_scene)
            # an unreachable goal: the one worker plans until the time limit
            blocker = threading.Thread(
                target=lambda: pytest.raises(riskplan.RiskplanError, c.plan, "ring", time_limit=4, timeout=30),
                daemon=True)
            with srv.client() as c2:
                blocker.start()
                deadline = time.monotonic() + 10
                while c2.status()["queue"]["running"] < 1:
                    assert time.monotonic() < deadline, "the plan never started"
                    time.sleep(0.02)
                times = status_times(c2, 1.0)
                assert max(times) < 0.1, f"status took {max(times):.3f} s with every worker busy"
                t = time.monotonic()
                assert c2.query("riskplan/echo", {"ping": 1}) == {"ping": 1}
                assert time.monotonic() - t < 0.1
                blocker.join(timeout=30)
    finally:
        srv.kill()


def long_trajectory(pieces: int = 3000) -> dict:
    """`pieces` contiguous pieces of one degree-8 polynomial path (coefficients in
    absolute time, so neighbouring pieces meet exactly) inside illustrative-3's box."""
    c = [[-0.9, 1.6, 0, 0, 0, 0, 0, 0, 0.05], [-0.9, 1.6, 0, 0, 0, 0, 0, 0, -0.05]]
    return {"format": "riskplan-trajectory/1",
            "pieces": [{"t0": k / pieces, "t1": (k + 1) / pieces, "coeffs": c} for k in range(pieces)]}


def test_verify_stops_at_its_deadline(client, name3):
    t = time.monotonic()
    with pytest.raises(riskplan.DeadlineExceededError):
        client.verify(name3, trajectory=long_trajectory(), method="sos", deadline_ms=300, timeout=60)
    took = time.monotonic() - t
    assert took < 1.0, f"verify answered {took:.2f} s after a 0.3 s deadline"
    assert client.last_replies == 1
    assert_alive(client)
    # without a deadline the same request is answered (the server's cap is far away)
    short = {"format": "riskplan-trajectory/1", "pieces": long_trajectory(30)["pieces"]}
    assert "safe" in client.verify(name3, trajectory=short, summary=True, deadline_ms=30_000)


def test_a_job_waiting_past_its_deadline_is_dropped(binary, tmp_path, scene3, ring_scene):
    srv = Server(binary, tmp_path / "data", extra=["--workers", "1", "--queue", "4"]).start()
    try:
        with srv.client() as c, srv.client() as c2:
            c.apply("ring", scene=ring_scene)
            c.apply("s3", scene=scene3)
            blocker = threading.Thread(
                target=lambda: pytest.raises(riskplan.RiskplanError, c.plan, "ring", time_limit=3, timeout=30),
                daemon=True)
            blocker.start()
            deadline = time.monotonic() + 10
            while c2.status()["queue"]["running"] < 1:
                assert time.monotonic() < deadline, "the plan never started"
                time.sleep(0.02)
            t = time.monotonic()
            with pytest.raises(riskplan.DeadlineExceededError):
                c2.verify("s3", segment=([-1, -1], [1, 1]), deadline_ms=200)
            assert time.monotonic() - t < 1.0
            blocker.join(timeout=30)
    finally:
        srv.kill()


def test_an_apply_with_too_many_changes_is_refused_at_once(client, name3):
    changes = [{"op": "put", "id": f"o{i}", "poly": "x1"} for i in range(20_000)]   # ~0.7 MB, under the payload limit
    rev = client.get_scene(name3)["revision"]
    t = time.monotonic()
    with pytest.raises(riskplan.LimitExceededError) as ei:
        client.apply(name3, changes=changes)
    assert ei.value.field == "changes"
    assert time.monotonic() - t < 2.0
    assert client.get_scene(name3)["revision"] == rev


PLAN_OVERRUN_S = 0.1   # plans honour their time limit to within 100 ms


@pytest.mark.parametrize("planner", ["rrt-sos", "rrt-sos-paper", "mc-rrt", "tv-sos"])
@pytest.mark.parametrize("time_limit", [0.3, 1.0])
def test_plans_honour_their_time_limit(client, ring_scene, unique, planner, time_limit):
    """An impossible plan (the goal is enclosed) runs to its time limit and no further,
    measured by the client, round trip included."""
    name = unique()
    client.apply(name, scene=ring_scene)
    t = time.monotonic()
    with pytest.raises(riskplan.NoPlanError):
        client.plan(name, planner=planner, time_limit=time_limit, improve=True if planner == "rrt-sos-paper" else None)
    took = time.monotonic() - t
    assert took < time_limit + PLAN_OVERRUN_S, f"a {time_limit} s plan took {took:.3f} s"


def test_an_improving_plan_honours_its_time_limit(client, unique):
    name = unique()
    client.apply(name, scene=load_scene("example-d1-cluttered-2d"))
    t = time.monotonic()
    try:
        client.plan(name, planner="rrt-sos-paper", time_limit=0.5, improve=True)
    except riskplan.NoPlanError:
        pass
    took = time.monotonic() - t
    assert took < 0.5 + PLAN_OVERRUN_S, f"a 0.5 s plan took {took:.3f} s"


def test_work_stops_when_the_client_gives_up(client, name3):
    """Zenoh does not tell a server that a querier gave up; the clients send their
    timeout as the deadline, so the server stops the job when the client stops waiting
    (without it this verify would hold a worker for the server's 60 s cap)."""
    t = time.monotonic()
    with pytest.raises((riskplan.QueryTimeoutError, riskplan.DeadlineExceededError)):
        client.verify(name3, trajectory=long_trajectory(), method="sos", timeout=0.3)
    while client.status()["queue"]["running"] > 0:
        assert time.monotonic() - t < 1.0, "the verify kept running after the client gave up"
        time.sleep(0.02)
