"""The contour cache: E[P] and E[P²] are built when an obstacle arrives and never rebuilt
by plan or verify (README, "Certify, plan, serve")."""
from __future__ import annotations

import json


def test_plan_and_verify_build_no_contour(client, scene3, unique):
    name = unique()
    s = json.loads(json.dumps(scene3))
    # a parameter no other test uses, so this scene's contour is a fresh cache entry
    s["params"]["w"] = {"dist": "uniform", "low": 0.3, "high": 0.40625}
    client.apply(name, scene=s)
    before = client.status()["cache"]
    plan = client.plan(name, time_limit=10, seed=3)
    assert plan.certified
    for method in ("exact", "sos", "both"):
        assert client.verify(name, trajectory=plan, method=method)["safe"]
    client.verify(name, segment=([-1, -1], [1, 1]))
    client.plan(name, time_limit=10, seed=4)
    after = client.status()["cache"]
    assert after["misses"] == before["misses"], (before, after)
    assert after["entries"] == before["entries"], (before, after)
