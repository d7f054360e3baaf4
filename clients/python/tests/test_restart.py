"""Durability: every acknowledged update survives `kill -9` and a restart on the same
data directory, with its revision."""
from __future__ import annotations

import pytest

import riskplan

from conftest import Server, free_port, load_scene, wait_for


def test_acknowledged_updates_survive_kill_9(binary, tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    srv = Server(binary, data).start()
    try:
        with srv.client() as c:
            s3 = load_scene("illustrative-3")
            r_a = [c.apply("alpha", scene=s3)]
            r_a.append(c.apply("alpha", changes=[
                {"op": "put", "id": "pole", "poly": "r^2 - (x1 - 0.5)^2 - (x2 + 0.5)^2",
                 "params": {"r": {"dist": "uniform", "low": 0.05, "high": 0.1}}}]))
            r_a.append(c.apply("alpha", changes=[{"op": "put", "id": "disk", "poly": "w^2 - (x1 + 0.2)^2 - x2^2"}]))
            r_b = c.apply("beta", scene=load_scene("illustrative-4"))
            r_c = c.apply("gamma", scene=s3)
            r_c2 = c.apply("gamma", changes=[{"op": "delete", "id": "disk"}])
            assert r_a == sorted(r_a) and len(set(r_a)) == 3
            expected = {
                "alpha": (r_a[-1], {"disk": "w^2 - (x1 + 0.2)^2 - x2^2", "pole": None}),
                "beta": (r_b, None),
                "gamma": (r_c2, {}),
            }
            # the last ack is followed at once by the kill
        srv.kill()  # SIGKILL: no clean shutdown
        with pytest.raises(riskplan.RiskplanError):
            # the server is gone: no reply (or no connection at all)
            with riskplan.Client(srv.endpoint, timeout=2) as dead:
                dead.status()
        srv.port = free_port()  # a fresh port (the old one may linger in TIME_WAIT); same data dir
        srv.endpoint = f"tcp/127.0.0.1:{srv.port}"
        srv.start()
        with srv.client() as c:
            for name, (rev, obstacles) in expected.items():
                got = c.get_scene(name)
                assert got["revision"] == rev, (name, got["revision"], rev)
                if obstacles is not None:
                    have = {o["id"]: o["poly"] for o in got["scene"]["obstacles"]}
                    assert set(have) == set(obstacles), (name, have)
                    for k, poly in obstacles.items():
                        if poly is not None:
                            assert have[k] == poly
            assert "r" in c.get_scene("alpha")["scene"]["params"]
            st = c.status()
            revs = {s["name"]: s["revision"] for s in st["scenes"]}
            assert revs["alpha"] == r_a[-1] and revs["beta"] == r_b and revs["gamma"] == r_c2
            # revisions keep increasing after a restart, and planning works on restored scenes
            assert c.apply("alpha", changes=[{"op": "delete", "id": "pole"}]) > r_a[-1]
            plan = c.plan("alpha", time_limit=20)
            assert plan.certified and plan.revision == r_a[-1] + 1
    finally:
        srv.kill()


def test_obstacle_puts_followed_by_an_ack_survive(binary, tmp_path):
    """Puts are not acknowledged, but a later acknowledged apply orders after them."""
    data = tmp_path / "data"
    data.mkdir()
    srv = Server(binary, data).start()
    try:
        with srv.client() as c:
            rev = c.apply("delta", scene=load_scene("illustrative-3"))
            c.update_obstacle("delta", "extra", "0.01 - (x1 - 0.6)^2 - (x2 + 0.6)^2")
            wait_for(lambda: c.get_scene("delta")["revision"] > rev, what="put applied")
            last = c.apply("delta", changes=[{"op": "put", "id": "more", "poly": "0.01 - (x1 + 0.6)^2 - (x2 - 0.6)^2"}])
        srv.kill()
        srv.start()  # same port and data dir
        with srv.client() as c:
            got = c.get_scene("delta")
            assert got["revision"] == last
            assert {o["id"] for o in got["scene"]["obstacles"]} == {"disk", "extra", "more"}
    finally:
        srv.kill()
