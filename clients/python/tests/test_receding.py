"""Receding-horizon plans and pedestrian updates through the service."""
import math

import numpy as np
import pytest

import riskplan


def prediction(x, v, t):
    return {"position": x, "velocity": v, "time": t,
            "radius": {"dist": "uniform", "low": 0.2, "high": 0.3},
            "position_std": 0.02, "velocity_std": 0.05}


def corridor(name):
    walkers = {"p1": ([3.0, 0.3], [-0.8, 0.0]), "p2": ([5.0, -1.0], [-1.0, 0.1])}
    scene = {"format": "riskplan-scene/1", "name": name, "dim": 2,
             "workspace": {"lower": [-8, -3], "upper": [8, 3]}, "horizon": [0, 60], "risk": 0.01,
             "robot_radius": 0.25, "planner": {"max_speed": 1.5, "max_accel": 3.0},
             "obstacles": [{"id": k, "pedestrian": prediction(x, v, 0.0)} for k, (x, v) in walkers.items()]}
    return scene, walkers


def test_consecutive_replans_are_c1_certified_and_warm_started(client, unique):
    name = unique()
    scene, walkers = corridor(name)
    client.apply(name, scene=scene)
    x, v, t = [-6.0, 0.0], [0.0, 0.0], 0.0
    for step in range(5):
        rev = client.update_pedestrians(name, {k: prediction([p[0] + u[0] * t, p[1] + u[1] * t], u, t)
                                               for k, (p, u) in walkers.items()})
        plan = client.replan(name, t, x, [6.0, 0.0], horizon=3.0, velocity=v, robot_id="py-robot",
                             time_limit=0.5)
        assert plan.certified and plan.revision == rev
        assert plan.t0 == pytest.approx(t, abs=0)
        assert np.allclose(plan.position(t), x, atol=1e-9)
        assert np.allclose(plan.velocity(t), v, atol=1e-6), "C¹ at the hand-over"
        assert plan.progress is not None and "reached_goal" in plan.progress
        assert client.verify(name, trajectory=plan)["safe"]
        t = round(t + 0.2, 10)
        x = [float(c) for c in plan.position(t)]
        v = [float(c) for c in plan.velocity(t)]
    assert x[0] > -6.0


def test_bad_receding_requests_name_the_field(client, unique):
    name = unique()
    scene, _ = corridor(name)
    client.apply(name, scene=scene)
    for kwargs, field in [
        (dict(t_now=99.0), "t_now"),
        (dict(horizon=0.0), "horizon"),
        (dict(velocity=[9.0, 0.0]), "velocity"),
    ]:
        args = dict(t_now=0.0, position=[-6.0, 0.0], goal=[6.0, 0.0], horizon=3.0)
        args.update(kwargs)
        with pytest.raises(riskplan.RiskplanError) as e:
            client.replan(name, **args)
        assert e.value.field == field, (kwargs, e.value)
    # inside a pedestrian's contour
    with pytest.raises(riskplan.RiskplanError) as e:
        client.replan(name, 0.0, [3.0, 0.3], [6.0, 0.0], horizon=3.0)
    assert e.value.code == "unsafe_endpoint"
    # a pedestrian template with a negative std
    bad = prediction([0.0, 0.0], [0.0, 0.0], 0.0)
    bad["velocity_std"] = -1.0
    with pytest.raises(riskplan.RiskplanError) as e:
        client.update_pedestrians(name, {"p9": bad})
    assert e.value.code == "invalid_scene" and "velocity_std" in str(e.value)
