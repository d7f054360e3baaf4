"""Mixed load (no message may crash or freeze the server): 64 concurrent clients of plan,
verify, risk and apply for a while; every query gets exactly one reply from the server (ok,
busy or a typed error, never a timeout), and status stays quick throughout. The 60 s run with
memory sampling is scripts/load_test.py (numbers in docs/benchmarks.md, "Mixed load, 64
clients, 60 s")."""
from __future__ import annotations

import json
import subprocess
import threading
import time

from conftest import load_scene

LOAD_SECONDS = 10
CLIENTS = 64


def test_mixed_load_gets_one_reply_per_query(binary, server, client, unique):
    name = unique()
    client.apply(name, scene=load_scene("illustrative-3"))
    status_times = []
    done = threading.Event()

    def watch():
        while not done.is_set():
            t = time.monotonic()
            client.status(timeout=5)
            status_times.append(time.monotonic() - t)
            time.sleep(0.1)

    w = threading.Thread(target=watch, daemon=True)
    w.start()
    r = subprocess.run([str(binary), "client", "--endpoint", server.endpoint, "--json", "load", "--mix",
                        "--scene", name, "--clients", str(CLIENTS), "--seconds", str(LOAD_SECONDS)],
                       capture_output=True, text=True, timeout=LOAD_SECONDS + 120)
    done.set()
    w.join(timeout=10)
    out = json.loads(r.stdout)
    assert r.returncode == 0, (out["outcomes"], out["replies_per_query"], r.stderr[-2000:])
    assert set(out["replies_per_query"]) == {"1"}
    assert set(out["kinds"]) == {"plan", "verify", "risk", "apply"}
    for kind, k in out["kinds"].items():
        assert k["queries"] > 0, kind
    assert out["kinds"]["apply"]["outcomes"].get("ok", 0) > 0
    # status is answered off the job pool: quick while every worker is busy
    assert status_times and max(status_times) < 0.5, max(status_times)
    assert client.status()["state"] == "ready"
