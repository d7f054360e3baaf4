#!/usr/bin/env python3
"""Cold start of the CLI planner (docs/benchmarks.md, "Cold start"): the time to the first
certified path of `riskplan plan` (stats.time_to_feasible_s: from the planner's start, the
scene parsed, nothing built) against the project's uncertified `mc-rrt` in the same run,
median of the seeds, and the CLI call's wall time (process start included) beside it.

    OPENBLAS_NUM_THREADS=1 python3 scripts/cold_start.py [--bin target/release/riskplan]
        [--seeds 5] [--scenes illustrative-3 example-d1-cluttered-2d] [--reps 3]

With --reps R every (scene, planner, seed) runs R times, interleaved, and the median of
all runs is reported (the machine's noise on millisecond timings is large)."""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--bin", default=os.environ.get("RISKPLAN_BIN", "target/release/riskplan"))
ap.add_argument("--seeds", type=int, default=5)
ap.add_argument("--reps", type=int, default=3)
ap.add_argument("--scenes", nargs="+", default=["illustrative-3", "example-d1-cluttered-2d"])
ap.add_argument("--planners", nargs="+", default=["rrt-sos", "mc-rrt"])
ap.add_argument("--extra", nargs="*", default=[], help="more arguments for `riskplan plan`")
a = ap.parse_args()

env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
results = {}
with tempfile.TemporaryDirectory() as tmp:
    out = os.path.join(tmp, "plan.json")
    for _ in range(a.reps):
        for scene in a.scenes:
            for planner in a.planners:
                for seed in range(1, a.seeds + 1):
                    cmd = [a.bin, "plan", "--scene", f"scenes/{scene}.json", "--planner", planner,
                           "--seed", str(seed), "--out", out, *a.extra]
                    t = time.perf_counter()
                    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
                    wall = time.perf_counter() - t
                    if r.returncode != 0:
                        sys.exit(f"{' '.join(cmd)}: exit {r.returncode}: {r.stderr}")
                    s = json.load(open(out))["stats"]
                    key = (scene, planner)
                    results.setdefault(key, []).append((s["time_to_feasible_s"] * 1e3, wall * 1e3,
                                                        s["planning_time_s"] * 1e3))

print(f"| scene | planner | first certified path, median (ms) | min–max (ms) | whole plan (ms) | CLI call, process included (ms) |")
print("|---|---|---|---|---|---|")
for (scene, planner), v in results.items():
    first = [x[0] for x in v]
    print(f"| {scene} | {planner} | {statistics.median(first):.2f} | {min(first):.2f}–{max(first):.2f} | "
          f"{statistics.median(x[2] for x in v):.1f} | {statistics.median(x[1] for x in v):.0f} |")
