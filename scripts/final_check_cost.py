#!/usr/bin/env python3
"""The cost of the final check of every certified plan (docs/design.md §5.12) on the
reference planning scenes: for each scene and certified planner, seeds 1..SEEDS, the
CLI `riskplan plan` (end to end, cold: a fresh process per plan) and the
`stats.final_check.seconds` it reports; prints a Markdown table of medians.

    scripts/final_check_cost.py [path/to/riskplan] [SEEDS]
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

BIN = sys.argv[1] if len(sys.argv) > 1 else "target/release/riskplan"
SEEDS = int(sys.argv[2]) if len(sys.argv) > 2 else 5
SCENES = ["illustrative-3", "illustrative-4", "example-b-lane-change", "example-c-delivery",
          "example-d1-cluttered-2d", "example-d2-cluttered-3d"]
PLANNERS = {"rrt-sos": SCENES, "rrt-sos-paper": SCENES,
            "tv-sos": ["illustrative-3", "illustrative-4", "example-b-lane-change", "example-c-delivery"],
            "moment": ["illustrative-3"]}

env = dict(os.environ, OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"))
print("| scene | planner | plan (median) | final check (median) | share | pieces | CLI wall (median) |")
print("|---|---|---|---|---|---|---|")
for planner, scenes in PLANNERS.items():
    for scene in scenes:
        plans, checks, shares, pieces, walls = [], [], [], [], []
        for seed in range(1, SEEDS + 1):
            with tempfile.NamedTemporaryFile(suffix=".json") as out:
                t = time.perf_counter()
                r = subprocess.run([BIN, "plan", "--scene", f"scenes/{scene}.json", "--planner", planner,
                                    "--seed", str(seed), "--time-limit", "20", "--out", out.name],
                                   capture_output=True, text=True, env=env)
                wall = time.perf_counter() - t
                if r.returncode != 0:
                    continue
                s = json.load(open(out.name))["stats"]
            fc = s.get("final_check") or {}
            assert fc.get("disagreements", 0) == 0, (scene, planner, seed, fc)
            plans.append(s["planning_time_s"])
            checks.append(fc.get("seconds", 0.0))
            shares.append(fc.get("seconds", 0.0) / s["planning_time_s"])
            pieces.append(fc.get("pieces", 0))
            walls.append(wall)
        if not plans:
            print(f"| {scene} | {planner} | no plan | | | | |")
            continue
        med = statistics.median
        print(f"| {scene} | {planner} | {1e3 * med(plans):.2f} ms | {1e3 * med(checks):.3f} ms | "
              f"{100 * med(shares):.1f} % (max {100 * max(shares):.1f} %) | {med(pieces):.0f} | "
              f"{1e3 * med(walls):.0f} ms |")
