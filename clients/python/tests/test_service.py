"""The Python client against the real `riskplan serve`: scenes, plans, verification,
risk queries, updates and revisions, status counters."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

import riskplan

from conftest import load_scene, validate, wait_for

PLAN_LIMIT = 20.0  # seconds: illustrative-3 plans in well under a second


def applied(client, name, scene):
    rev = client.apply(name, scene=scene)
    assert isinstance(rev, int) and rev >= 1
    return rev


# -- scenes ----------------------------------------------------------------------------

def test_status_answers_and_validates(client):
    st = client.status()
    validate("status_reply", st)
    assert st["uptime_s"] >= 0
    assert st["queue"]["workers"] >= 1


def test_apply_reference_scene(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    reply = client.get_scene(name)
    validate("scene_reply", reply)
    assert reply["name"] == name
    assert reply["revision"] == rev
    got = reply["scene"]
    for k in ("format", "dim", "obstacles", "params", "start", "goal", "workspace"):
        assert got[k] == scene3[k], k
    assert float(got["risk"]) == pytest.approx(0.1)


def test_apply_again_bumps_the_revision(client, scene3, unique):
    name = unique()
    r1 = applied(client, name, scene3)
    r2 = applied(client, name, scene3)
    assert r2 > r1


def test_put_scene_reference_scene(client, scene3, unique):
    name = unique()
    client.put_scene(name, scene3)
    reply = wait_for(lambda: client.get_scene(name), what=f"scene {name} after put")
    validate("scene_reply", reply)
    assert reply["revision"] >= 1
    assert reply["scene"]["obstacles"] == scene3["obstacles"]
    plan = client.plan(name, time_limit=PLAN_LIMIT)
    assert plan.certified and plan.revision == reply["revision"]


def test_every_reference_scene_is_accepted(client, unique):
    from conftest import SCENES

    paths = sorted(SCENES.glob("*.json"))
    assert paths, f"no reference scenes in {SCENES}"
    for p in paths:
        name = unique(p.stem)
        rev = client.apply(name, scene=load_scene(p.stem))
        assert client.get_scene(name)["revision"] == rev


def test_delete_scene(client, scene3, unique):
    name = unique()
    applied(client, name, scene3)
    client.delete_scene(name)

    def gone():
        try:
            client.get_scene(name)
            return False
        except riskplan.UnknownSceneError:
            return True

    wait_for(gone, what="scene deleted")


# -- plan and verify -------------------------------------------------------------------

def test_plan_is_certified_with_the_revision(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    plan = client.plan(name, time_limit=PLAN_LIMIT, seed=1)
    validate("plan_reply", plan.raw)
    assert plan.certified is True
    assert plan.revision == rev
    assert plan.planner == "rrt-sos"
    assert plan.risk == pytest.approx(0.1)
    wp = plan.waypoints()
    assert wp.shape[1] == 2 and wp.shape[0] == len(plan.raw["pieces"]) + 1
    np.testing.assert_allclose(wp[0], scene3["start"], atol=1e-9)
    np.testing.assert_allclose(wp[-1], scene3["goal"], atol=1e-9)
    xs = plan.sample(200)
    assert xs.shape == (200, 2)
    # the planned path keeps out of the Δ-contour of the disk (radius ≈ 0.429)
    # outside the true Δ-contour (radius w ~ U[0.3, 0.4]: Prob(w ≥ r) ≤ 0.1 iff r ≥ 0.39); the
    # default bound (auto) proves zero risk beyond 0.4, Cantelli's only beyond 0.4289
    assert np.min(np.linalg.norm(xs, axis=1)) > 0.39
    assert plan.stats["planning_time_s"] >= 0 and plan.stats["edges_checked"] >= 1


@pytest.mark.parametrize("scene", ["illustrative-3", "illustrative-4", "example-b-lane-change", "example-c-delivery"])
def test_tv_sos_plans_over_zenoh(client, unique, scene):
    """The time-varying SOS planner from Python: a certified plan on each of the
    paper's tv-sos scenes, with its SDP stats and ladder, that the server's own
    verification (both methods) accepts."""
    name = unique()
    applied(client, name, load_scene(scene))
    plan = client.plan(name, planner="tv-sos", time_limit=PLAN_LIMIT, seed=1)
    validate("plan_reply", plan.raw)
    assert plan.planner == "tv-sos" and plan.certified is True
    assert plan.stats["sdp"]["solves"] >= 1 and plan.stats["sdp"]["psd_cones"] >= 1
    assert plan.stats["ladder"][-1]["outcome"] == "certified"
    reply = client.verify(name, plan, method="both")
    assert reply["safe"] is True


def test_plan_reports_the_served_scene_name(client, scene3, unique):
    """Reading of the README: plan_reply.scene is the scene's name as served (the key)."""
    name = unique()
    applied(client, name, scene3)
    plan = client.plan(name, time_limit=PLAN_LIMIT)
    assert plan.scene == name


def test_plan_is_reproducible_with_a_seed(client, scene3, unique):
    name = unique()
    applied(client, name, scene3)
    a = client.plan(name, time_limit=PLAN_LIMIT, seed=5)
    b = client.plan(name, time_limit=PLAN_LIMIT, seed=5)
    assert a.raw["pieces"] == b.raw["pieces"]


def test_plan_with_explicit_start_goal_and_options(client, scene3, unique):
    name = unique()
    applied(client, name, scene3)
    plan = client.plan(name, start=[-1, 0.9], goal=[0.9, -1], time_limit=PLAN_LIMIT, seed=2,
                       certifier="exact", delta=0.05)
    assert plan.certified
    assert plan.risk == pytest.approx(0.05)
    np.testing.assert_allclose(plan.waypoints()[0], [-1, 0.9], atol=1e-9)
    np.testing.assert_allclose(plan.waypoints()[-1], [0.9, -1], atol=1e-9)


def test_plan_options_of_issue_10(client, scene3, unique):
    """Smoothing (C¹ pieces, degree ≤ 2), the paper's planner, a speed limit that cannot
    be met (a typed no_plan naming it), and the joint risk mode with its allocation."""
    name = unique()
    applied(client, name, scene3)
    smooth = client.plan(name, time_limit=PLAN_LIMIT)
    assert smooth.certified and smooth.stats["smoothing"]["corners_sharp"] == 0
    assert max(len(c) for p in smooth.raw["pieces"] for c in p["coeffs"]) <= 3
    paper = client.plan(name, planner="rrt-sos-paper", time_limit=PLAN_LIMIT)
    assert paper.certified and paper.planner == "rrt-sos-paper" and paper.stats["smoothing"] is None
    with pytest.raises(riskplan.NoPlanError, match="out of reach"):
        client.plan(name, time_limit=PLAN_LIMIT, max_speed=0.5)   # 2.83 to cover in 1 time unit
    joint = client.plan(name, time_limit=PLAN_LIMIT, risk_mode="joint")
    assert joint.certified
    assert len(joint.stats["risk_allocation"]) == 1
    assert joint.stats["risk_allocation"][0][1] == pytest.approx(joint.risk)


def test_plan_in_trajectory_mode_reports_its_whole_path_bound(client, scene3, unique):
    """risk_mode "trajectory": Δ bounds the probability of meeting the obstacle at any time
    along the plan; every certified plan reports its whole-path bound, and on
    illustrative-3's disk (radius uniform on [0.3, 0.4]) that bound covers the closed form
    (0.4 − d_min)/0.1 of the plan's smallest distance from the centre, sampled densely."""
    name = unique()
    applied(client, name, scene3)
    for mode in ("per-obstacle", "trajectory"):
        plan = client.plan(name, time_limit=PLAN_LIMIT, risk_mode=mode, delta=0.05)
        validate("plan_reply", plan.raw)
        bound = plan.stats["whole_path_risk"]
        assert plan.certified and 0.0 <= bound <= 1.0
        if mode == "trajectory":
            assert bound <= 0.05
        d_min = min(
            math.hypot(*[sum(c * t ** k for k, c in enumerate(row)) for row in p["coeffs"]])
            for p in plan.raw["pieces"]
            for t in [p["t0"] + (p["t1"] - p["t0"]) * i / 2000 for i in range(2001)]
        )
        truth = min(max((0.4 - d_min) / 0.1, 0.0), 1.0)
        assert bound >= truth - 1e-9, (mode, bound, truth)


def test_verify_the_plan_is_safe(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    plan = client.plan(name, time_limit=PLAN_LIMIT)
    report = client.verify(name, trajectory=plan)
    validate("verify_reply", report)
    assert report["safe"] is True
    assert report["revision"] == rev
    assert report["method"] == "exact"
    assert len(report["pieces"]) == len(plan.raw["pieces"])
    assert all(p["safe"] for p in report["pieces"])
    # the raw plan_reply dict is accepted too
    assert client.verify(name, trajectory=plan.raw)["safe"] is True


def test_verify_straight_segment_through_the_obstacle_is_unsafe(client, scene3, unique):
    name = unique()
    applied(client, name, scene3)
    report = client.verify(name, segment=([-1, -1], [1, 1]))
    validate("verify_reply", report)
    assert report["safe"] is False
    (piece,) = report["pieces"]
    assert piece["safe"] is False
    (obst,) = piece["obstacles"]
    assert obst["id"] == "disk" and obst["status"] == "unsafe"
    witnesses = [c["witness"] for c in obst["constraints"] if c["status"] == "unsafe"]
    assert witnesses and all(w is not None for w in witnesses)
    for w in witnesses:
        assert 0.0 <= w["t"] <= 1.0 and w["value"] <= 0
    # the segment crosses the disk's centre at t = 0.5: a witness lies inside the contour
    assert any(abs(w["t"] - 0.5) < 0.22 for w in witnesses)


def test_verify_timed_segment_with_both_methods(client, scene3, unique):
    name = unique()
    applied(client, name, scene3)
    report = client.verify(name, segment={"from": [-1, -1], "to": [-1, 1], "t0": 0, "t1": 0.5},
                           method="both", delta=0.05)
    validate("verify_reply", report)
    assert report["method"] == "both"
    assert report["risk"] == pytest.approx(0.05)
    assert report["safe"] is True
    assert report["pieces"][0]["t0"] == 0 and report["pieces"][0]["t1"] == 0.5


# -- updates ---------------------------------------------------------------------------

def test_update_obstacle_then_plan_carries_the_new_revision(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    client.update_obstacle(name, "disk", "w^2 - (x1 - 0.3)^2 - (x2 + 0.3)^2")
    new = wait_for(lambda: (r := client.get_scene(name))["revision"] > rev and r, what="revision bump after put")
    assert new["revision"] == rev + 1
    (disk,) = [o for o in new["scene"]["obstacles"] if o["id"] == "disk"]
    assert "0.3" in disk["poly"]
    plan = client.plan(name, time_limit=PLAN_LIMIT)
    assert plan.revision == new["revision"] and plan.certified
    # the old plan is checked against the new scene
    assert client.verify(name, segment=([-1, -1], [1, 1]))["revision"] == new["revision"]


def test_update_obstacle_with_new_params(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    client.update_obstacle(name, "pole", "r^2 - (x1 - 0.6)^2 - (x2 + 0.6)^2",
                           params={"r": {"dist": "normal", "mean": 0.1, "std": 0.01}})
    new = wait_for(lambda: (r := client.get_scene(name))["revision"] > rev and r, what="revision bump after put")
    assert {o["id"] for o in new["scene"]["obstacles"]} == {"disk", "pole"}
    assert "r" in new["scene"]["params"]
    bounds = client.risk(name, [[0.6, -0.6]])
    assert bounds[0] > 0.5  # inside the new pole


def test_remove_obstacle(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    client.remove_obstacle(name, "disk")
    new = wait_for(lambda: (r := client.get_scene(name))["revision"] > rev and r, what="revision bump after delete")
    assert new["scene"]["obstacles"] == []
    # nothing left: the straight line is safe now
    assert client.verify(name, segment=([-1, -1], [1, 1]))["safe"] is True


def test_apply_changes_moves_an_obstacle(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    rev2 = client.apply(name, changes=[
        {"op": "put", "id": "disk", "poly": "w^2 - (x1 + 0.4)^2 - (x2 - 0.4)^2"},
        {"op": "put", "id": "pole", "poly": "r^2 - (x1 - 0.5)^2 - (x2 + 0.5)^2",
         "params": {"r": {"dist": "uniform", "low": 0.05, "high": 0.1}}},
    ])
    assert rev2 > rev
    got = client.get_scene(name)
    assert got["revision"] == rev2
    assert {o["id"] for o in got["scene"]["obstacles"]} == {"disk", "pole"}
    plan = client.plan(name, time_limit=PLAN_LIMIT)
    assert plan.revision == rev2 and plan.certified
    rev3 = client.apply(name, changes=[{"op": "delete", "id": "pole"}])
    assert rev3 > rev2
    assert [o["id"] for o in client.get_scene(name)["scene"]["obstacles"]] == ["disk"]


def test_apply_changes_are_atomic(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    with pytest.raises(riskplan.InvalidSceneError):
        client.apply(name, changes=[
            {"op": "put", "id": "good", "poly": "0.01 - (x1 - 0.5)^2 - (x2 + 0.5)^2"},
            {"op": "put", "id": "bad", "poly": "undeclared^2 - x1^2"},
        ])
    got = client.get_scene(name)
    assert got["revision"] == rev
    assert [o["id"] for o in got["scene"]["obstacles"]] == ["disk"]


# -- risk --------------------------------------------------------------------------------

def test_risk_points_match_the_reference_values(client, scene3, unique):
    name = unique()
    rev = applied(client, name, scene3)
    points = [[-1, -1], [0.45, 0], [0, 0.5], [1, 1]]
    reply = client.risk_query(name, {"points": points, "time": 0, "bound": "cantelli"})
    validate("risk_reply", reply)
    assert reply["revision"] == rev and reply["time"] == 0 and reply["by_bound"] == {}
    # derived_checks of illustrative-3.json (Cantelli's bound)
    expected = [0.0001160862041, 0.06124529322, 0.02485143166, 0.0001160862041]
    np.testing.assert_allclose(reply["bounds"], expected, rtol=1e-6)
    np.testing.assert_allclose(reply["obstacles"]["disk"], expected, rtol=1e-6)
    b = client.risk(name, np.array([[0.45, 0.0], [0.0, 0.5]]), bound="cantelli")
    assert b.shape == (2,)
    np.testing.assert_allclose(b, expected[1:3], rtol=1e-6)
    # the default (auto): every point here is beyond the largest radius 0.4, so zero risk is
    # proven; every bound is listed on request, Cantelli's among them
    every = client.risk_query(name, {"points": points, "time": 0, "every_bound": True})
    validate("risk_reply", every)
    assert every["bound"] == "auto" and every["bounds"] == [0.0] * 4
    np.testing.assert_allclose(every["by_bound"]["disk"]["cantelli"], expected, rtol=1e-6)
    assert every["by_bound"]["disk"]["support"] == [0.0] * 4
    assert all(0 <= v <= 1 for v in every["by_bound"]["disk"]["moment8"])
    assert client.risk(name, [0.45, 0.0]).shape == (1,)


def test_risk_grid_contour_radius(client, scene3, unique):
    name = unique()
    applied(client, name, scene3)
    n = 201
    X, Y, B = client.risk_grid(name, [-1, -1], [1, 1], n, bound="cantelli")
    assert X.shape == Y.shape == B.shape == (n, n)
    assert not np.isnan(B).any()
    assert X[0, 0] == -1 and X[0, -1] == 1 and Y[0, 0] == -1 and Y[-1, 0] == 1
    # symmetric disk: B(x, y) = B(y, x); the Δ = 0.1 contour has radius ≈ 0.4289 (derived_checks)
    np.testing.assert_allclose(B, B.T, rtol=1e-9, atol=1e-12)
    row = B[n // 2]  # y = 0
    xs = X[n // 2]
    outside = xs[(xs > 0) & (row <= 0.1)]
    assert outside.min() == pytest.approx(0.4289479419, abs=2 / (n - 1))
    # the default bound (auto) proves zero risk beyond the largest radius 0.4
    _, _, A = client.risk_grid(name, [-1, -1], [1, 1], n)
    outside = xs[(xs > 0) & (A[n // 2] <= 0.1)]
    assert 0.39 - 2 / (n - 1) <= outside.min() <= 0.4 + 2 / (n - 1)
    assert (A <= B + 1e-12).all()


def test_risk_grid_in_3d_fixes_other_coordinates_at_lower(client, unique):
    name = unique()
    scene = load_scene("example-d2-cluttered-3d")
    client.apply(name, scene=scene)
    lo, hi = scene["workspace"]["lower"], scene["workspace"]["upper"]
    X, Y, B = client.risk_grid(name, lo, hi, 5, time=0.5)
    assert B.shape == (5, 5)
    pts = np.column_stack([X.ravel(), Y.ravel(), np.full(25, float(lo[2]))])
    np.testing.assert_allclose(client.risk(name, pts, time=0.5), B.ravel(), rtol=1e-9, atol=1e-15)


# -- status --------------------------------------------------------------------------------

def _counter(status, kind):
    return status["requests"].get(kind, {"served": 0, "failed": 0})


def test_status_counters(client, scene3, unique):
    name = unique()
    before = client.status()
    applied(client, name, scene3)
    client.plan(name, time_limit=PLAN_LIMIT)
    with pytest.raises(riskplan.UnknownSceneError):
        client.plan(unique("missing"), time_limit=1)
    client.update_obstacle(name, "bad", "this is not a polynomial (")

    def put_failed():
        s = client.status()
        return _counter(s, "put")["failed"] > _counter(before, "put")["failed"] and s

    after = wait_for(put_failed, what="requests.put.failed to count the bad put")
    validate("status_reply", after)
    plan_kinds = [k for k in after["requests"] if "plan" in k]
    assert plan_kinds, after["requests"]
    k = plan_kinds[0]
    assert _counter(after, k)["served"] >= _counter(before, k)["served"] + 1
    assert _counter(after, k)["failed"] >= _counter(before, k)["failed"] + 1
    apply_kinds = [k for k in after["requests"] if "apply" in k]
    assert apply_kinds and _counter(after, apply_kinds[0])["served"] >= _counter(before, apply_kinds[0])["served"] + 1
    mine = [s for s in after["scenes"] if s["name"] == name]
    assert len(mine) == 1
    assert mine[0]["revision"] == client.get_scene(name)["revision"]
    assert mine[0]["obstacles"] == 1
    assert after["uptime_s"] >= before["uptime_s"]
    q = after["queue"]
    assert q["workers"] >= 1 and q["depth"] >= 0 and q["running"] >= 0 and q["capacity"] >= 0
    c = after["cache"]
    assert c["entries"] >= 1 and c["hits"] + c["misses"] >= 1


# -- plot -----------------------------------------------------------------------------------

def test_draw_scene_with_a_plan(client, scene3, unique, tmp_path):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from riskplan.plot import draw_scene

    name = unique()
    applied(client, name, scene3)
    plan = client.plan(name, time_limit=PLAN_LIMIT)
    ax = draw_scene(client, name, plan=plan, n=120)
    out = tmp_path / "scene.png"
    ax.figure.savefig(out)
    plt.close(ax.figure)
    assert out.stat().st_size > 5000
    ax = draw_scene(client, name, delta=0.05, time=0.0, n=60)
    plt.close(ax.figure)
