"""Load sharing (proto/README.md, "Discovery"): servers behind a router announce
themselves with liveliness tokens and answer on their own keys; clients spread reads
over the live servers, re-send a read that a vanished server left without reply, and
may ask for at least a revision (`min_revision`). Four servers: a primary and three
replicas, in client mode behind `riskplan router`."""
from __future__ import annotations

import json
import threading
import time
from collections import Counter

import pytest
import zenoh

import riskplan

from conftest import Server, load_scene, wait_for
from test_cluster import READ_TIMEOUT_S, Router, run_load

IDS = ["p0", "r1", "r2", "r3"]


@pytest.fixture
def four(binary, tmp_path):
    router = Router(binary)
    common = ["--mode", "client", "--connect", router.endpoint, "--workers", "1"]
    servers = [Server(binary, tmp_path / sid, extra=common + ["--server-id", sid] + (["--replica"] if sid != "p0" else []))
               for sid in IDS]
    try:
        for s in servers:
            s.start()
        yield router, dict(zip(IDS, servers))
    finally:
        for s in reversed(servers):
            s.kill()
        router.stop()


def raw(endpoint, selector):
    """One plain zenoh get (a client that knows nothing of the protocol): every reply."""
    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    with zenoh.open(cfg) as s:
        return list(s.get(selector, consolidation=zenoh.ConsolidationMode.NONE, timeout=5))


def test_discovery_spread_and_min_revision(four):
    router, servers = four
    with riskplan.Client(router.endpoint, timeout=READ_TIMEOUT_S) as c:
        wait_for(lambda: sorted(c.servers()) == IDS, what="the client sees the four servers")
        # each server answers on its own key, as itself
        for sid in IDS:
            (r,) = raw(router.endpoint, f"riskplan/@{sid}/status")
            assert json.loads(r.ok.payload.to_bytes())["server_id"] == sid
        # a write goes to the primary only; reads asking for its revision see it on
        # every server, right after the acknowledgement
        for k in range(3):
            rev = c.apply("s3", scene=load_scene("illustrative-3"))
            for sid in IDS:
                (r,) = raw(router.endpoint, f"riskplan/@{sid}/scenes/s3?min_revision={rev}")
                assert r.ok is not None, r.err.payload.to_string()
                assert json.loads(r.ok.payload.to_bytes())["revision"] >= rev, sid
            # and through the client, wherever its reads go
            c.at_least("s3", rev)
            for _ in range(8):
                assert c.get_scene("s3")["revision"] >= rev
        # revisions count per scene: another scene's reads ask nothing
        c.apply("other", scene=load_scene("illustrative-4"))
        wait_for(lambda: c.get_scene("other")["revision"] >= 1, what="another scene read without min_revision")
        c.at_least("s3", None)
        # a revision no server has: a typed error (a replica after a short wait, the
        # primary at once)
        with pytest.raises(riskplan.StaleRevisionError):
            c.at_least("s3", rev + 1000).get_scene("s3")
        t = time.monotonic()
        (r,) = raw(router.endpoint, f"riskplan/@p0/scenes/s3?min_revision={rev + 1000}")
        assert r.err is not None and "stale_revision" in r.err.payload.to_string()
        assert time.monotonic() - t < 1.0, "the primary waited for a revision only it could make"
        # a scene deleted after the asked revision is unknown, not stale
        rdel = c.apply("gone", scene=load_scene("illustrative-4"))
        c.delete_scene("gone")
        time.sleep(0.3)
        (r,) = raw(router.endpoint, f"riskplan/@p0/scenes/gone?min_revision={rdel}")
        assert r.err is not None and "unknown_scene" in r.err.payload.to_string(), r.err.payload.to_string()
        c.at_least("s3", None)
        # reads are spread over the servers (power of two choices), one reply each
        used = Counter()
        for _ in range(80):
            c.verify("s3", segment=([-1, -1], [1, 1]))
            assert c.last_replies == 1
            used[c.last_server] += 1
        assert set(used) == set(IDS), used
        # a client that knows nothing of the protocol still gets one reply on the shared key
        assert len(raw(router.endpoint, "riskplan/scenes/s3")) == 1


def test_four_servers_one_killed_under_load(four):
    router, servers = four
    name = "load"
    with riskplan.Client(router.endpoint, timeout=READ_TIMEOUT_S) as c:
        rev = c.apply(name, scene=load_scene("illustrative-3"))
        for sid in IDS:
            (r,) = raw(router.endpoint, f"riskplan/@{sid}/scenes/{name}?min_revision={rev}")
            assert r.ok is not None
    results = {"latencies": [], "replies": [], "errors": []}
    threads = [threading.Thread(target=run_load, args=(router.endpoint, 8.0, None, results, name)) for _ in range(6)]
    for t in threads:
        t.start()
    time.sleep(3.0)
    servers["r2"].kill()
    for t in threads:
        t.join(timeout=60)
    assert not results["errors"], results["errors"][:5]
    assert set(results["replies"]) == {1}, "a query got more than one reply"
    assert results["latencies"] and max(results["latencies"]) < READ_TIMEOUT_S


def test_a_read_waiting_on_a_server_whose_token_goes_is_sent_elsewhere(server):
    """A read sent to a server that then disappears (its liveliness token goes, no reply
    came) is re-sent to another live server at once, not left to the timeout: a fake
    server (a token and a queryable on its own key that never answers) beside the real
    one; its token is withdrawn after 1 s. Without the liveliness watch the read sent to
    the fake waits its whole 10 s timeout and fails."""
    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps([server.endpoint]))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    held = []
    with zenoh.open(cfg) as fake, riskplan.Client(server.endpoint, timeout=10.0) as c:
        queryable = fake.declare_queryable("riskplan/@fake-1/**", held.append)  # never answered
        token = fake.liveliness().declare_token("riskplan/_servers/fake-1/replica")
        wait_for(lambda: "fake-1" in c.servers() and len(c.servers()) == 2, what="the client sees both servers")
        timer = threading.Timer(1.0, token.undeclare)
        timer.start()
        latencies = []
        started = time.monotonic()
        while time.monotonic() - started < 1.5:
            t = time.monotonic()
            assert c.status()["server_id"] != "fake-1"
            latencies.append(time.monotonic() - t)
        timer.join()
        queryable.undeclare()
        assert held, "no read went to the fake server"
        assert max(latencies) > 0.5, latencies  # the read held by the fake
        assert max(latencies) < 2.5, f"a read waited {max(latencies):.2f} s for a server that had gone"


def test_one_shot_cli_reads_spread_over_the_servers(four, binary):
    """A one-shot `riskplan client` command waits briefly for the servers' tokens before its
    one read (DISCOVERY_WAIT), so that reads of many such commands spread over the servers
    instead of all going to the shared key, where the primary answers."""
    import subprocess
    router, servers = four
    with riskplan.Client(router.endpoint, timeout=READ_TIMEOUT_S) as c:
        wait_for(lambda: sorted(c.servers()) == IDS, what="the four servers announced")
    seen = Counter()
    for _ in range(16):
        p = subprocess.run([str(binary), "client", "--endpoint", router.endpoint, "status"],
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 0, p.stderr
        seen[json.loads(p.stdout)["server_id"]] += 1
    # 16 reads over four servers by the power of two choices: all on one server has
    # probability 4·(1/4)^16 < 10⁻⁹
    assert len(seen) >= 2, f"every one-shot read went to one server: {dict(seen)}"
