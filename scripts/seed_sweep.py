#!/usr/bin/env python3
"""The default planner on every reference planning scene for many seeds, through every front
end: the local CLI (`riskplan plan`), the service with bincode (`riskplan client plan`) and the
service with JSON (`riskplan client --json plan`). Counts internal errors and other failures,
and whether the same seed gave the same plan (the same pieces, bit for bit) through each front
end as through the CLI (docs/benchmarks.md, "Seeds through every front end").

    python3 scripts/seed_sweep.py [--seeds 500] [--bin target/release/riskplan] [--endpoint E]

Without --endpoint a server is started on a free loopback port with the repository's scenes
preloaded (`serve --preload scenes`), and stopped at the end. Prints a Markdown table and one
JSON line; exits 1 when any plan ended in an internal error or any front end disagreed.
"""
import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENES = ["illustrative-3", "illustrative-4", "example-b-lane-change", "example-c-delivery",
          "example-d1-cluttered-2d", "example-d2-cluttered-3d"]
FRONT_ENDS = ["cli", "service-bincode", "service-json"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(binary: str, data: Path) -> tuple[subprocess.Popen, str]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    proc = subprocess.Popen([binary, "serve", "--listen", endpoint, "--data", str(data), "--preload",
                             str(ROOT / "scenes")], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    for line in proc.stderr:
        if "riskplan: ready" in line:
            break
        if time.monotonic() > deadline:
            break
    # the rest of its log is read and dropped, so that the pipe never fills
    import threading
    threading.Thread(target=lambda: [None for _ in proc.stderr], daemon=True).start()
    return proc, endpoint


def run(cmd: list[str], out: Path) -> tuple[str, object]:
    """(outcome, pieces): outcome 'ok', 'internal' (an internal error) or 'failed: ...'."""
    if out.exists():
        out.unlink()
    p = subprocess.run(cmd, capture_output=True, text=True)
    if "internal error" in p.stderr:
        return "internal", p.stderr.strip().splitlines()[-1]
    if p.returncode != 0 or not out.exists():
        return f"failed (exit {p.returncode}): {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ''}", None
    return "ok", json.loads(out.read_text())["pieces"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=500)
    ap.add_argument("--bin", default=str(ROOT / "target" / "release" / "riskplan"))
    ap.add_argument("--endpoint")
    ap.add_argument("--scenes", nargs="*", default=SCENES)
    a = ap.parse_args()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    tmp = Path(tempfile.mkdtemp(prefix="seed-sweep-"))
    server = None
    endpoint = a.endpoint
    if endpoint is None:
        server, endpoint = start_server(a.bin, tmp / "data")
    rows, failures = [], []
    started = time.monotonic()
    try:
        for scene in a.scenes:
            counts = {fe: {"ok": 0, "internal": 0, "failed": 0, "differs": 0} for fe in FRONT_ENDS}
            for seed in range(1, a.seeds + 1):
                cmds = {
                    "cli": [a.bin, "plan", "--scene", str(ROOT / "scenes" / f"{scene}.json"), "--seed", str(seed)],
                    "service-bincode": [a.bin, "client", "--endpoint", endpoint, "plan", "--scene", scene,
                                        "--seed", str(seed)],
                    "service-json": [a.bin, "client", "--endpoint", endpoint, "--json", "plan", "--scene", scene,
                                     "--seed", str(seed)],
                }
                pieces = {}
                for fe, cmd in cmds.items():
                    out = tmp / f"{fe}.json"
                    outcome, result = run(cmd + ["--out", str(out)], out)
                    key = outcome if outcome in ("ok", "internal") else "failed"
                    counts[fe][key] += 1
                    if outcome == "ok":
                        pieces[fe] = result
                    else:
                        failures.append({"scene": scene, "seed": seed, "front_end": fe, "outcome": outcome,
                                         "detail": result})
                for fe in FRONT_ENDS[1:]:
                    if fe in pieces and "cli" in pieces and pieces[fe] != pieces["cli"]:
                        counts[fe]["differs"] += 1
                        failures.append({"scene": scene, "seed": seed, "front_end": fe, "outcome": "differs"})
            rows.append((scene, counts))
            print(f"{scene}: {json.dumps(counts)}", file=sys.stderr, flush=True)
    finally:
        if server is not None:
            server.terminate()
            server.wait(timeout=30)
    elapsed = time.monotonic() - started
    print(f"Seeds 1–{a.seeds}, default planner (rrt-sos), {len(a.scenes)} scenes; {elapsed:.0f} s in all.\n")
    print("| scene | front end | plans | internal errors | other failures | plan differs from the CLI's |")
    print("|---|---|---|---|---|---|")
    for scene, counts in rows:
        for fe in FRONT_ENDS:
            c = counts[fe]
            differs = "—" if fe == "cli" else str(c["differs"])
            print(f"| {scene} | {fe} | {c['ok']} | {c['internal']} | {c['failed']} | {differs} |")
    print()
    print(json.dumps({"seeds": a.seeds, "scenes": {s: c for s, c in rows}, "failures": failures[:50],
                      "seconds": round(elapsed)}))
    bad = any(c[fe]["internal"] or c[fe]["differs"] for _, c in rows for fe in FRONT_ENDS)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
