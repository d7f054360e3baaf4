"""Durability: every acknowledged update survives `kill -9` and a restart on the same
data directory, with its revision: after the last acknowledgement, and in the middle of
a stream of applies."""
from __future__ import annotations

import json
import threading
import time
from typing import List, Optional, Tuple

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


# -- kill -9 while applies are in flight ------------------------------------------------------

STREAM_ROUNDS = 5       # kill, restart, stream again: five kills at different points
STREAM_ACKS = 25        # acknowledged applies per round before the kill


def disk_at(step: int) -> str:
    """illustrative-3's disk moved right by step × 1e-4: one polynomial per step."""
    return f"w^2 - (x1 - {step * 1e-4:.4f})^2 - x2^2"


def disk_of(reply: dict) -> str:
    (disk,) = [o for o in reply["scene"]["obstacles"] if o["id"] == "disk"]
    return disk["poly"]


class ApplyStream(threading.Thread):
    """Applies one update after another to scene ``name``, without pause, until an apply
    fails (the server was killed). Step ``i`` moves the disk to ``disk_at(i)``: an
    obstacle change for even ``i``, the whole scene for odd ``i``. ``sent`` holds the
    polynomial of every apply sent, in order (appended before it is sent), ``acked``
    (revision, polynomial) of every apply acknowledged (appended when the reply came)."""

    def __init__(self, endpoint: str, name: str, scene: dict, first: int):
        super().__init__(daemon=True)
        self.endpoint, self.name, self.scene, self.first = endpoint, name, scene, first
        self.sent: List[str] = []
        self.acked: List[Tuple[int, str]] = []
        self.error: Optional[Exception] = None

    def run(self) -> None:
        try:
            with riskplan.Client(self.endpoint, timeout=10) as c:
                step = self.first
                while True:
                    poly = disk_at(step)
                    if step % 2:
                        whole = json.loads(json.dumps(self.scene))
                        whole["obstacles"] = [dict(o, poly=poly) if o["id"] == "disk" else o
                                              for o in whole["obstacles"]]
                        request = dict(scene=whole)
                    else:
                        request = dict(changes=[{"op": "put", "id": "disk", "poly": poly}])
                    self.sent.append(poly)
                    rev = c.apply(self.name, **request)
                    self.acked.append((rev, poly))
                    step += 1
        except Exception as e:  # the test looks at it
            self.error = e


def test_kill_9_during_a_stream_of_applies(binary, tmp_path):
    """SIGKILL while an apply stream is still sending, then a restart on the same data
    directory: the scene is at the last acknowledged revision with its content, or at
    the next one (the apply in flight, persisted but not acknowledged) with that
    content; never older, never a revision with another revision's content."""
    data = tmp_path / "data"
    data.mkdir()
    scene = load_scene("illustrative-3")
    srv = Server(binary, data).start()
    streams: List[ApplyStream] = []
    try:
        with srv.client() as c:
            rev = c.apply("stream", scene=scene)
            poly = disk_of(c.get_scene("stream"))
        assert poly == scene["obstacles"][0]["poly"]
        step = 1
        for round_ in range(STREAM_ROUNDS):
            stream = ApplyStream(srv.endpoint, "stream", scene, first=step)
            streams.append(stream)
            stream.start()
            wait_for(lambda: len(stream.acked) >= STREAM_ACKS + round_ or not stream.is_alive(), limit=120,
                     what=f"{STREAM_ACKS + round_} acknowledged applies")
            # then the moment an apply is on its way (sent, not acknowledged yet); its
            # reply may still win the race with the signal: both outcomes are checked below
            deadline = time.monotonic() + 10
            while len(stream.sent) == len(stream.acked) and stream.is_alive() and time.monotonic() < deadline:
                time.sleep(0)
            assert stream.is_alive(), f"the stream stopped before the kill: {stream.error!r}"
            assert len(stream.sent) > len(stream.acked), "no apply on its way to kill"
            srv.kill()  # SIGKILL, with the stream still sending
            stream.join(timeout=60)
            assert not stream.is_alive(), "the stream did not notice the server's death"
            assert isinstance(stream.error, riskplan.RiskplanError), repr(stream.error)
            sent, acked = list(stream.sent), list(stream.acked)
            # the stream is sequential: one revision per apply, in order, and exactly one
            # apply sent and not acknowledged (the one that met the kill)
            assert [r for r, _ in acked] == list(range(rev + 1, rev + 1 + len(acked))), (rev, acked)
            assert [p for _, p in acked] == sent[:len(acked)]
            assert len(sent) == len(acked) + 1, (len(sent), len(acked))
            last_rev, last_poly = acked[-1]
            pending_poly = sent[-1]

            srv.port = free_port()  # a fresh port (the stream's session is gone with it); same data dir
            srv.endpoint = f"tcp/127.0.0.1:{srv.port}"
            srv.start()
            with srv.client() as c:
                got = c.get_scene("stream")
                rev, poly = got["revision"], disk_of(got)
                assert rev >= last_rev, f"acknowledged revision {last_rev} lost: the scene is at {rev}"
                if rev == last_rev:
                    assert poly == last_poly, (rev, poly, last_poly)
                else:
                    assert rev == last_rev + 1, (rev, last_rev)
                    assert poly == pending_poly, (rev, poly, pending_poly)
                assert poly in sent[len(acked) - 1:], (poly, sent[len(acked) - 1:])  # not older than the last ack
                for k in ("params", "workspace", "start", "goal", "dim", "risk"):
                    assert got["scene"][k] == scene[k], k
                assert [o["id"] for o in got["scene"]["obstacles"]] == ["disk"]
                st = {s["name"]: s["revision"] for s in c.status()["scenes"]}
                assert st["stream"] == rev
            step += len(sent)
        with srv.client() as c:
            # revisions go on from the restored one, and the scene still serves
            assert c.apply("stream", changes=[{"op": "put", "id": "disk", "poly": disk_at(step)}]) == rev + 1
            assert c.verify("stream", segment=([-1, -1], [1, 1]))["revision"] == rev + 1
    finally:
        srv.kill()
        for s in streams:
            s.join(timeout=15)


# -- restores: revisions never go back or repeat ----------------------------------------------

def test_a_deleted_scene_stays_deleted_and_its_revisions_go_on(binary, tmp_path):
    """A delete is an acknowledged update: it survives a restart even when --preload
    lists the scene, and the name created again continues after its last revision."""
    data, pre = tmp_path / "data", tmp_path / "preload"
    pre.mkdir()
    scene = load_scene("illustrative-3")
    (pre / "s.json").write_text(json.dumps(scene))
    srv = Server(binary, data, extra=["--preload", str(pre)]).start()
    try:
        with srv.client() as c:
            assert c.get_scene("s")["revision"] == 1          # preloaded
            last = c.apply("s", changes=[{"op": "put", "id": "disk", "poly": disk_at(1)}])
            c.delete_scene("s")
            wait_for(lambda: "s" not in {x["name"] for x in c.status()["scenes"]}, what="the delete")
        srv.kill()
        srv.start()
        with srv.client() as c:
            with pytest.raises(riskplan.UnknownSceneError):
                c.get_scene("s")
            again = c.apply("s", scene=scene)
            assert again == last + 1, (again, last)
    finally:
        srv.kill()


def test_a_corrupt_file_is_quarantined_reported_and_its_name_restarts_above(binary, tmp_path):
    data, pre = tmp_path / "data", tmp_path / "preload"
    pre.mkdir()
    scene = load_scene("illustrative-3")
    srv = Server(binary, data).start()
    try:
        with srv.client() as c:
            rev = 0
            for step in range(3):
                rev = c.apply("c", scene=scene) if step == 0 else c.apply(
                    "c", changes=[{"op": "put", "id": "disk", "poly": disk_at(step)}])
        srv.kill()
        stored = data / "scenes" / "c.json"
        stored.write_bytes(stored.read_bytes()[:40])       # torn by something other than us
        (pre / "c.json").write_text(json.dumps(scene))
        srv.extra = srv.extra + ["--preload", str(pre)]
        srv.start()
        with srv.client() as c:
            st = c.status()
            assert any("'c'" in p and "quarantine" in p for p in st["problems"]), st["problems"]
            assert not stored.exists() or json.loads(stored.read_text())["revision"] > rev
            assert list((data / "quarantine").iterdir()), "the bad file was not kept for inspection"
            back = c.get_scene("c")                          # preloaded again, at a new revision
            assert back["revision"] > rev, (back["revision"], rev)
            assert c.apply("c", changes=[{"op": "put", "id": "disk", "poly": disk_at(9)}]) == back["revision"] + 1
    finally:
        srv.kill()


# Stored scenes whose contours are slow to build, for a restart that stays `loading` for
# seconds (test_status_says_loading_until_the_stored_scenes_are_in).
SLOW_SCENES = 48


def test_status_says_loading_until_the_stored_scenes_are_in(binary, tmp_path, scene3):
    """Readiness is visible: between `listening` and `ready` the server answers status
    ("state": "loading") and echo at once, and takes no other query (in a cluster
    another server does); clients repeat such reads within their timeout, so a read
    sent while loading is answered once the scenes are in."""
    from conftest import LISTENING_LINE
    from test_hostile import slow_scene

    data = tmp_path / "data"
    srv = Server(binary, data).start()
    try:
        with srv.client(timeout=60) as c:
            # tens of milliseconds of contour building each at start: loading them takes
            # seconds, the window this test looks into
            for k in range(SLOW_SCENES):
                c.apply(f"slow{k}", scene=slow_scene(scene3, shift=k))
            c.apply("s3", scene=scene3)
    finally:
        srv.kill()
    srv.start(ready_line=LISTENING_LINE)
    try:
        with srv.client() as c:
            t = time.monotonic()
            st = c.status(timeout=5)
            assert time.monotonic() - t < 0.5
            assert st["state"] == "loading", st
            assert c.query("riskplan/echo", {"ping": 2}) == {"ping": 2}
            with pytest.raises(riskplan.NoReplyError):
                c.query("riskplan/scenes/s3", None, encoding=None, timeout=0.3)
            assert c.status()["state"] == "loading"
            # a read with time to wait is answered once the server is ready
            assert c.get_scene("s3")["revision"] >= 1
            assert c.status()["state"] == "ready"
            assert any(f"riskplan: ready ({SLOW_SCENES + 1} scenes)" in line for line in srv.lines), srv.log()
            assert {s["name"] for s in c.status()["scenes"]} >= {"s3", "slow0", "slow5"}
    finally:
        srv.kill()
