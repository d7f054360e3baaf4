"""`busy`: a server with one worker and no queue refuses a second job at once."""
from __future__ import annotations

import threading
import time

import pytest

import riskplan

from conftest import Server, validate, wait_for


@pytest.fixture(scope="module")
def tiny(binary, tmp_path_factory):
    s = Server(binary, tmp_path_factory.mktemp("riskplan-tiny"), extra=["--workers", "1", "--queue", "0"]).start()
    yield s
    s.stop()


@pytest.mark.slow  # a 4 s plan occupies the only worker
def test_busy_when_the_only_worker_is_planning(tiny, ring_scene):
    with tiny.client() as c:
        st = c.status()
        assert st["queue"]["workers"] == 1 and st["queue"]["capacity"] == 0
        c.apply("ring", scene=ring_scene)
        outcome = {}

        def long_plan():
            try:
                with tiny.client() as c2:
                    c2.plan("ring", time_limit=4.0)
                outcome["result"] = "plan"
            except riskplan.RiskplanError as e:
                outcome["result"] = e

        th = threading.Thread(target=long_plan, daemon=True)
        th.start()
        wait_for(lambda: c.status()["queue"]["running"] >= 1, limit=5, what="the long plan to run")
        t = time.monotonic()
        with pytest.raises(riskplan.BusyError) as ei:
            c.plan("ring", time_limit=4.0)
        assert time.monotonic() - t < 2.0, "busy must be sent at once"
        e = ei.value
        assert e.code == "busy"
        validate("error", {"code": e.code, "message": e.message, "field": e.field})
        th.join(timeout=30)
        assert isinstance(outcome.get("result"), riskplan.NoPlanError), outcome
        # free again: the next job runs (and finds no plan, quickly)
        with pytest.raises(riskplan.NoPlanError):
            c.plan("ring", time_limit=0.3)
        st = c.status()
        validate("status_reply", st)
        assert st["queue"]["running"] == 0 and st["queue"]["depth"] == 0
        plan_kinds = [k for k in st["requests"] if "plan" in k]
        assert plan_kinds and st["requests"][plan_kinds[0]]["failed"] >= 3
