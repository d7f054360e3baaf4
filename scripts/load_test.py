#!/usr/bin/env python3
"""The service's load test (docs/benchmarks.md, "Mixed load, 64 clients, 60 s"): one
server with the repository's scenes, N concurrent clients for S seconds of mixed
plan/verify/risk/apply (`riskplan client load --mix`), the server's resident memory
sampled twice a second.

Checks: every query got exactly one reply from the server (ok, busy or a typed error;
never a local timeout), and the resident memory after the warm-up stays within 20 %
(max/min). Prints a JSON summary (the load command's, plus the memory samples) and
exits 1 when a check fails.

    python3 scripts/load_test.py [--bin target/release/riskplan] [--clients 64] [--seconds 60]
"""
from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
WARM_UP_S = 10.0       # memory samples before this are not compared
RSS_TOLERANCE = 1.20   # max/min of the resident memory after the warm-up


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=str(REPO / "target" / "release" / "riskplan"))
    ap.add_argument("--clients", type=int, default=64)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--scene", default="illustrative-3")
    a = ap.parse_args()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    with tempfile.TemporaryDirectory() as data:
        log_path = Path(data) / "server.log"
        log = open(log_path, "w")   # the server's log (a pipe left unread would fill and block it)
        server = subprocess.Popen([a.bin, "serve", "--listen", endpoint, "--data", str(Path(data) / "scenes"),
                                   "--preload", str(REPO / "scenes")],
                                  stderr=log, stdout=subprocess.DEVNULL, text=True, env=env)
        try:
            start = time.monotonic()
            while "riskplan: ready" not in log_path.read_text():
                if server.poll() is not None or time.monotonic() - start > 60:
                    print(f"the server did not start: {log_path.read_text()[-2000:]}", file=sys.stderr)
                    return 1
                time.sleep(0.1)
            load = subprocess.Popen([a.bin, "client", "--endpoint", endpoint, "--json", "load", "--mix",
                                     "--scene", a.scene, "--clients", str(a.clients), "--seconds", str(a.seconds)],
                                    stdout=subprocess.PIPE, text=True, env=env)
            t0 = time.monotonic()
            samples = []
            while load.poll() is None:
                samples.append((round(time.monotonic() - t0, 1), round(rss_mb(server.pid), 1)))
                time.sleep(0.5)
            out = json.loads(load.stdout.read())
            alive = server.poll() is None
        finally:
            server.terminate()
            server.wait(timeout=30)
    after = [m for t, m in samples if t >= WARM_UP_S] or [m for _, m in samples]
    ratio = max(after) / min(after)
    out["server_rss_mb"] = {"warm_up_s": WARM_UP_S, "min_after_warm_up": min(after), "max_after_warm_up": max(after),
                            "max_over_min": round(ratio, 3), "samples": samples}
    out["checks"] = {"one_reply_per_query": load.returncode == 0, "rss_flat": ratio <= RSS_TOLERANCE,
                     "server_alive": alive}
    print(json.dumps(out, indent=2))
    return 0 if all(out["checks"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
