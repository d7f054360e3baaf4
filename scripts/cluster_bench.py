#!/usr/bin/env python3
"""Throughput of a cluster behind one router (docs/benchmarks.md, "A fleet's planning service:
load sharing").

Starts, in turn and on this host only: a router and one server with 1 worker; a primary and
a replica with 1 worker each; one server with 2 workers; a primary and three replicas with
1 worker each — every server in client mode behind the router, the scene preloaded on the
primary (the replicas receive it by replication). Against each, through the router:
`riskplan client load --mix --clients N --seconds S --scene SCENE`, whose Rust client spreads
reads over the live servers (proto/README.md, "Discovery and load sharing"). Prints one JSON
object: each configuration's throughput, outcomes and replies per query, and the two ratios
the targets are stated in (the pair over one server with 1 and with 2 workers).

    python3 scripts/cluster_bench.py [--bin target/release/riskplan] [--clients 8] [--seconds 12]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_line(path: Path, text: str, limit: float = 60.0):
    end = time.monotonic() + limit
    while time.monotonic() < end:
        if path.exists() and text in path.read_text(errors="replace"):
            return
        time.sleep(0.05)
    raise RuntimeError(f"no '{text}' in {path} after {limit} s:\n{path.read_text(errors='replace')[-2000:]}")


def run_config(a, name, workers):
    """workers: one entry per server (the first is the primary)."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        router_ep = f"tcp/127.0.0.1:{free_port()}"
        # the scene, preloaded by the primary under the name `a.name`
        pre = tmp / "preload"
        pre.mkdir()
        shutil.copy(REPO / "scenes" / f"{a.scene}.json", pre / f"{a.name}.json")
        procs = []
        try:
            rlog = tmp / "router.log"
            procs.append(subprocess.Popen([a.bin, "router", "--listen", router_ep], stdout=subprocess.DEVNULL,
                                          stderr=open(rlog, "w"), env=env))
            wait_line(rlog, "router listening")
            for i, w in enumerate(workers):
                log = tmp / f"server{i}.log"
                argv = [a.bin, "serve", "--mode", "client", "--connect", router_ep, "--data", str(tmp / f"data{i}"),
                        "--workers", str(w), "--server-id", f"s{i}"]
                argv += ["--preload", str(pre)] if i == 0 else ["--replica"]
                procs.append(subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=open(log, "w"), env=env))
                wait_line(log, "riskplan: ready")
            time.sleep(1.0)   # tokens and queryables propagate through the router
            out = subprocess.run([a.bin, "client", "--endpoint", router_ep, "load", "--mix", "--clients", str(a.clients),
                                  "--seconds", str(a.seconds), "--scene", a.name],
                                 capture_output=True, text=True, env=env, timeout=a.seconds + 120)
            r = json.loads(out.stdout)
            return {"config": name, "workers": workers, "exit": out.returncode,
                    "throughput_qps": round(r["throughput_qps"], 1), "queries": r["queries"],
                    "outcomes": r["outcomes"], "replies_per_query": r["replies_per_query"],
                    "servers": r.get("servers"), "latency_ms": r["latency_ms"]}
        finally:
            for p in reversed(procs):
                p.terminate()
            for p in procs:
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=str(REPO / "target" / "release" / "riskplan"))
    ap.add_argument("--clients", type=int, default=8)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--scene", default="example-d1-cluttered-2d", help="a file of scenes/, without .json")
    ap.add_argument("--name", default="d1", help="the scene's name on the servers")
    a = ap.parse_args()
    configs = [("one server, 1 worker", [1]), ("primary + replica, 1 worker each", [1, 1]),
               ("one server, 2 workers", [2]), ("primary + 3 replicas, 1 worker each", [1, 1, 1, 1])]
    rows = [run_config(a, name, w) for name, w in configs]
    base, pair, two = (rows[0]["throughput_qps"], rows[1]["throughput_qps"], rows[2]["throughput_qps"])
    ok = all(r["exit"] == 0 and set(r["replies_per_query"]) == {"1"} for r in rows)
    print(json.dumps({"rows": rows, "pair_over_one_worker": round(pair / base, 2),
                      "pair_over_two_workers": round(pair / two, 2), "every_query_one_reply_no_error": ok}, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
