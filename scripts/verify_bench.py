#!/usr/bin/env python3
"""Edge verification at the kernel's speed (docs/benchmarks.md, "`verify`").

Measures, on this host and in one run:

* the CLI, end to end: `riskplan verify` of a random trajectory of N pieces (default
  10 000) on illustrative-3, with the exact and the SOS method, the full (pretty) report
  and `--summary`, with the default threads (the machine's cores) and `--threads 1`,
  written to a pipe; per piece = (median time of N pieces − median time of 1 piece) /
  (N − 1), so that process start, scene loading and the contours' compilation are
  excluded;
* the service over Zenoh: one `verify` query of a random trajectory of M pieces (default
  100 000) on d1 (`summary: true`) against `riskplan serve` on loopback — with the Rust
  client (`riskplan client verify --summary`, bincode; the query's time is the CLI's wall
  time less that of a one-piece query, and the server's own time is read from its log),
  and with the Python client (JSON), the trajectory and a batch of M independent
  segments: cold (the first query after the scene arrived) and warm (median of --reps);
* the Python peers of `scripts/sos_peers.py` (a hand-written Clarabel program and cvxpy
  with Clarabel, per piece), when their wheels are installed.

The random trajectories join uniform points of the workspace (seeded), equal durations
over the horizon; about half the pieces of the illustrative-3 one cross the disk.

    python3 scripts/verify_bench.py [--bin target/release/riskplan] [--pieces 10000] [--zenoh-pieces 100000]
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def scene_box(name: str):
    s = json.loads((REPO / "scenes" / f"{name}.json").read_text())
    return s["workspace"]["lower"], s["workspace"]["upper"], s["horizon"]


def random_pieces(name: str, n: int, seed: int):
    """n straight pieces through n + 1 uniform points of the scene's workspace."""
    lo, hi, (h0, h1) = scene_box(name)
    rng = random.Random(seed)
    pts = [[rng.uniform(l, u) for l, u in zip(lo, hi)] for _ in range(n + 1)]
    times = [h0 + (h1 - h0) * i / n for i in range(n)] + [h1]
    pieces = []
    for i in range(n):
        a, b, ta, tb = pts[i], pts[i + 1], times[i], times[i + 1]
        rows = []
        for d in range(len(lo)):
            slope = (b[d] - a[d]) / (tb - ta)
            rows.append([a[d] - slope * ta, slope])   # x(t) = c0 + c1·t
        pieces.append({"t0": ta, "t1": tb, "coeffs": rows})
    return pieces, pts, times


def timed(argv, env, reps):
    out = []
    code = None
    for _ in range(reps):
        t = time.perf_counter()
        p = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
        out.append(time.perf_counter() - t)
        code = p.returncode
        if code not in (0, 1):
            raise RuntimeError(f"{argv}: exit {code}: {p.stderr.decode()[-2000:]}")
    return statistics.median(out), p.stdout


def cli_rows(a, env, tmp: Path):
    rows = []
    scene = REPO / "scenes" / "illustrative-3.json"
    big, _, _ = random_pieces("illustrative-3", a.pieces, a.seed)
    # the baseline: one random piece over the whole horizon
    small, _, _ = random_pieces("illustrative-3", 1, a.seed)
    for name, pieces in (("big", big), ("one", small)):
        (tmp / f"{name}.json").write_text(json.dumps({"format": "riskplan-trajectory/1", "pieces": pieces}))
    # the default threads (the machine's cores, for 4 096 pieces or more) and one thread
    for method in ("exact", "sos"):
        for report_kind in ("full", "summary"):
            for threads in (None, 1):
                base = [a.bin, "verify", "--scene", str(scene), "--method", method]
                base += ["--summary"] if report_kind == "summary" else []
                base += ["--threads", str(threads)] if threads else []
                base += ["--trajectory"]
                t1, _ = timed(base + [str(tmp / "one.json")], env, a.reps)
                tn, out = timed(base + [str(tmp / "big.json")], env, a.reps)
                report = json.loads(out)
                rows.append({"method": method, "report": report_kind, "threads": threads or os.cpu_count(),
                             "pieces": a.pieces, "not_safe": report["not_safe"],
                             "output_bytes": len(out), "median_s": round(tn, 4), "one_piece_median_s": round(t1, 4),
                             "per_piece_us": round((tn - t1) / (a.pieces - 1) * 1e6, 2)})
    return rows


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


def zenoh_rows(a, env, tmp: Path):
    try:
        import riskplan
    except ImportError:
        return {"skipped": "the Python client is not installed (pip install -e clients/python)"}
    ep = f"tcp/127.0.0.1:{free_port()}"
    pre = tmp / "preload"
    pre.mkdir()
    shutil.copy(REPO / "scenes" / "example-d1-cluttered-2d.json", pre / "d1.json")
    log = tmp / "serve.log"
    proc = subprocess.Popen([a.bin, "serve", "--listen", ep, "--data", str(tmp / "data"), "--preload", str(pre)],
                            stdout=subprocess.DEVNULL, stderr=open(log, "w"), env=env)
    try:
        wait_line(log, "riskplan: ready")
        pieces, pts, times = random_pieces("example-d1-cluttered-2d", a.zenoh_pieces, a.seed)
        traj = {"format": "riskplan-trajectory/1", "pieces": pieces}
        segs = [{"from": pts[i], "to": pts[i + 1], "t0": times[i], "t1": times[i + 1]} for i in range(len(pieces))]
        rows = {}
        # the Rust client (bincode): the CLI's wall time, less that of a one-piece query
        # (process start, connection, discovery); the server's own time from its log
        (tmp / "z_big.json").write_text(json.dumps(traj))
        (tmp / "z_one.json").write_text(json.dumps({"format": traj["format"], "pieces": [
            {"t0": 0.0, "t1": 1.0, "coeffs": pieces[0]["coeffs"]}]}))
        cl = [a.bin, "client", "--endpoint", ep, "verify", "--scene", "d1", "--summary", "--trajectory"]
        log_at = len(log.read_text())
        first = time.perf_counter()
        subprocess.run(cl + [str(tmp / "z_big.json")], stdout=subprocess.DEVNULL, env=env)
        cold = time.perf_counter() - first
        tn, _ = timed(cl + [str(tmp / "z_big.json")], env, a.reps)
        t1, _ = timed(cl + [str(tmp / "z_one.json")], env, a.reps)
        served = [float(line.split("duration_ms=")[1].split()[0]) / 1e3
                  for line in log.read_text()[log_at:].splitlines() if "kind=verify" in line and "duration_ms=" in line]
        rows["rust_client_trajectory"] = {
            "pieces": a.zenoh_pieces, "cold_wall_s": round(cold, 3), "warm_wall_median_s": round(tn, 3),
            "one_piece_wall_median_s": round(t1, 3), "query_s": round(tn - t1, 3),
            "server_cold_s": round(served[0], 3) if served else None,
            "server_warm_median_s": round(statistics.median(served[1:a.reps + 1]), 3) if len(served) > 1 else None}
        with riskplan.Client(ep, timeout=60) as c:
            for kind, kw in (("python_client_trajectory", {"trajectory": traj}), ("python_client_segments", {"segments": segs})):
                lat = []
                reply = None
                for i in range(a.reps + 1):
                    t = time.perf_counter()
                    reply = c.verify("d1", summary=True, **kw)
                    lat.append(time.perf_counter() - t)
                rows[kind] = {"pieces": a.zenoh_pieces, "not_safe": reply["not_safe"], "checked": reply["checked"],
                              "reply_bytes": len(json.dumps(reply)),
                              "cold_s": round(lat[0], 3), "warm_median_s": round(statistics.median(lat[1:]), 3)}
            # the client's own share: encoding the request as JSON
            t = time.perf_counter()
            json.dumps({"trajectory": traj, "summary": True}).encode()
            rows["client_json_encode_s"] = round(time.perf_counter() - t, 3)
        return rows
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def peers(a):
    p = subprocess.run([sys.executable, str(REPO / "scripts" / "sos_peers.py"), "--reps", str(a.peer_reps)],
                       capture_output=True, text=True)
    if p.returncode != 0:
        return {"skipped": p.stderr.strip()[-300:]}
    return [json.loads(line) for line in p.stdout.splitlines() if line.strip().startswith("{")]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=str(REPO / "target" / "release" / "riskplan"))
    ap.add_argument("--pieces", type=int, default=10_000)
    ap.add_argument("--zenoh-pieces", type=int, default=100_000)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--peer-reps", type=int, default=50)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--skip-zenoh", action="store_true")
    a = ap.parse_args()
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        out = {"cli_illustrative_3": cli_rows(a, env, tmp)}
        if not a.skip_zenoh:
            out["zenoh_d1"] = zenoh_rows(a, env, tmp)
        out["python_peers_sos_per_piece"] = peers(a)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
