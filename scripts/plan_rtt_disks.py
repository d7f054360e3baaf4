#!/usr/bin/env python3
"""Default plans on a crowded scene through the service, end to end (docs/benchmarks.md,
"The service on 512 disks"): what a robot sees, beside what the server's own statistics say.

Run `riskplan serve` first (release build, OPENBLAS_NUM_THREADS=1), then
`python scripts/plan_rtt_disks.py [--disks 512] [--seeds 8] [--passes 3] [--endpoint E]`.

The scene is the growth family of `benches/common/mod.rs` (`disks_scene`): n uncertain disks
at constant density (workspace side 10·√n), radius r ~ U[0.8, 1.6] scaled by s ~ U[0.9, 1.1],
centre offset along x₁ by d ~ N(0, 0.05), start and goal at opposite corners. It is drawn
here with Python's generator (another instance of the family than the bench's, which uses
ChaCha8); `--scene FILE` plans on a given scene file instead.

The scene is sent with an acknowledged `apply`, then: the first plan (cold: nothing of the
scene built but what the apply builds), one pass of seeds 1..S (warm: the pass the bench
calls warm), and `--passes - 1` more passes of the same requests (steady: a server answering
the same robots). For every plan the client's round trip is timed, and the reply's own
`stats` give the time to the first certified path and the whole plan inside the server.
`--pause S` waits S seconds between the apply and the cold plan (the server's background
warm-up, docs/design.md §7.9, has then had S seconds).
Prints a Markdown table and one JSON line.
"""
import argparse
import json
import math
import random
import statistics
import time

import riskplan


def disks_scene(n: int, seed: int) -> dict:
    rng = random.Random(seed)
    side = 10.0 * math.sqrt(n)
    params, obstacles = {}, []
    k = 0
    while len(obstacles) < n:
        cx, cy, r = rng.uniform(0, side), rng.uniform(0, side), rng.uniform(0.8, 1.6)
        if any(math.hypot(cx - x, cy - y) < r + 3.0 for x, y in [(0.5, 0.5), (side - 0.5, side - 0.5)]):
            continue
        k += 1
        params[f"s{k}"] = {"dist": "uniform", "low": 0.9, "high": 1.1}
        params[f"d{k}"] = {"dist": "normal", "mean": 0, "std": 0.05}
        cx, cy, r = round(cx, 2), round(cy, 2), round(r, 2)
        obstacles.append({"id": f"disk{k}", "poly": f"({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - {cy})^2"})
    return {"format": "riskplan-scene/1", "name": f"disks-{n}", "dim": 2,
            "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
            "params": params, "obstacles": obstacles, "start": [0.5, 0.5], "goal": [side - 0.5, side - 0.5]}


def plan_once(c, name, seed, limit):
    began = time.perf_counter()
    p = c.plan(name, seed=seed, time_limit=limit)
    rtt = (time.perf_counter() - began) * 1e3
    if not p.certified:
        raise SystemExit(f"seed {seed}: no certified plan")
    s = p.stats
    return {"seed": seed, "rtt_ms": rtt, "whole_ms": s["planning_time_s"] * 1e3,
            "first_ms": s["time_to_feasible_s"] * 1e3, "whole_path_risk": s.get("whole_path_risk")}


def summary(rows):
    med = lambda k: statistics.median(r[k] for r in rows)
    return {"plans": len(rows), "rtt_ms": round(med("rtt_ms"), 3), "whole_ms": round(med("whole_ms"), 3),
            "first_ms": round(med("first_ms"), 3),
            "whole_over_first": round(statistics.median(r["whole_ms"] / r["first_ms"] for r in rows), 2),
            "rtt_over_first": round(statistics.median(r["rtt_ms"] / r["first_ms"] for r in rows), 2),
            "rtt_minus_whole_ms": round(statistics.median(r["rtt_ms"] - r["whole_ms"] for r in rows), 3)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--disks", type=int, default=512)
    ap.add_argument("--scene", help="plan on this scene file instead of a generated one")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--passes", type=int, default=3, help="passes of seeds 1..S after the cold plan (≥ 1)")
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--endpoint", default="tcp/127.0.0.1:7447")
    ap.add_argument("--pause", type=float, default=0.0,
                    help="seconds between the apply's reply and the cold plan (a robot that sends its map and "
                         "plans later: the server warms the scene meanwhile unless `serve --no-warm-up`)")
    a = ap.parse_args()
    if a.passes < 1 or a.seeds < 1:
        ap.error("--passes and --seeds must be at least 1")
    scene = json.load(open(a.scene)) if a.scene else disks_scene(a.disks, 1)
    name = f"rtt-{scene.get('name', 'scene')}"
    with riskplan.Client(a.endpoint, timeout=60.0) as c:
        began = time.perf_counter()
        c.apply(name, scene=scene)
        apply_ms = (time.perf_counter() - began) * 1e3
        time.sleep(a.pause)
        cold = plan_once(c, name, 1, a.time_limit)
        passes = [[plan_once(c, name, seed, a.time_limit) for seed in range(1, a.seeds + 1)] for _ in range(a.passes)]
    warm, steady = passes[0], [r for p in passes[1:] for r in p]
    out = {"scene": name, "obstacles": len(scene["obstacles"]), "apply_ms": round(apply_ms, 1), "pause_s": a.pause,
           "cold": {k: round(v, 3) if isinstance(v, float) else v for k, v in cold.items()},
           "warm": summary(warm), "steady": summary(steady) if steady else None}
    print("| pass | plans | round trip (ms) | whole plan in the server (ms) | first path (ms) | whole ÷ first | round trip ÷ first | round trip − whole (ms) |")
    print("|---|---|---|---|---|---|---|---|")
    c0 = out["cold"]
    print(f"| cold (first plan after the apply) | 1 | {c0['rtt_ms']:.2f} | {c0['whole_ms']:.2f} | {c0['first_ms']:.2f} | "
          f"{c0['whole_ms'] / c0['first_ms']:.1f}× | {c0['rtt_ms'] / c0['first_ms']:.1f}× | {c0['rtt_ms'] - c0['whole_ms']:.2f} |")
    for label, s in [("warm (seeds 1..S once)", out["warm"]), ("steady (the same again)", out["steady"])]:
        if s:
            print(f"| {label} | {s['plans']} | {s['rtt_ms']:.2f} | {s['whole_ms']:.2f} | {s['first_ms']:.2f} | "
                  f"{s['whole_over_first']:.1f}× | {s['rtt_over_first']:.1f}× | {s['rtt_minus_whole_ms']:.2f} |")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
