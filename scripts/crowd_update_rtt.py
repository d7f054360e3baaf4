"""One pedestrian's update through the service, end to end (docs/benchmarks.md, "Robots
among moving people").

Run `riskplan serve` first, then
`python scripts/crowd_update_rtt.py [--pedestrians N] [--updates K] [--endpoint E]`.
Puts a 16 × 6 corridor with N pedestrians, then times, from the Python client: K
acknowledged `apply` requests that each send ONE pedestrian's new prediction (the first after the
scene arrived is reported apart: cold), and a receding-horizon plan (window 3 s, 50 ms
limit) after each. Prints one JSON
object. The kernel alone is `cargo bench --bench crowd` (update/one_of_N).
"""
import argparse
import json
import random
import statistics
import time

import riskplan


def prediction(x, v, t):
    return {"position": x, "velocity": v, "time": t,
            "radius": {"dist": "uniform", "low": 0.2, "high": 0.3},
            "position_std": 0.02, "velocity_std": 0.05}


def pct(v, q):
    v = sorted(v)
    return v[round((len(v) - 1) * q)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pedestrians", type=int, default=60)
    ap.add_argument("--updates", type=int, default=300)
    ap.add_argument("--endpoint", default="tcp/127.0.0.1:7447")
    a = ap.parse_args()
    rng = random.Random(7)
    walkers = {f"p{i}": ([rng.uniform(-4, 8), rng.uniform(-2.5, 2.5)], [rng.choice([-1, 1]) * rng.uniform(0.5, 1.3), 0.0])
               for i in range(a.pedestrians)}
    name = f"rtt-corridor-{a.pedestrians}"
    scene = {"format": "riskplan-scene/1", "name": name, "dim": 2,
             "workspace": {"lower": [-8, -3], "upper": [8, 3]}, "horizon": [0, 600], "risk": 0.01,
             "robot_radius": 0.25, "planner": {"max_speed": 1.5, "max_accel": 3.0},
             "obstacles": [{"id": k, "pedestrian": prediction(x, v, 0.0)} for k, (x, v) in walkers.items()]}
    upd, plan = [], []
    with riskplan.Client(a.endpoint) as c:
        c.apply(name, scene=scene)
        ids = list(walkers)
        for k in range(a.updates + 1):
            # a new measurement of one pedestrian (jittered by a few centimetres), predicted from now
            wid = ids[k % len(ids)]
            (x, v) = walkers[wid]
            m = [x[0] + rng.gauss(0, 0.02), x[1] + rng.gauss(0, 0.02)]
            began = time.perf_counter()
            c.update_pedestrians(name, {wid: prediction(m, v, 0.0)})
            upd.append((time.perf_counter() - began) * 1e3)
            began = time.perf_counter()
            try:
                c.replan(name, 0.0, [-7.5, 0.0], [7.5, 0.0], horizon=3.0, time_limit=0.05)
            except riskplan.NoPlanError:
                pass
            plan.append((time.perf_counter() - began) * 1e3)
    warm_u, warm_p = upd[1:], plan[1:]
    print(json.dumps({"pedestrians": a.pedestrians, "updates": a.updates,
                      "update_ms_cold": round(upd[0], 3), "update_ms_p50": round(statistics.median(warm_u), 3),
                      "update_ms_p99": round(pct(warm_u, 0.99), 3),
                      "plan_after_update_ms_cold": round(plan[0], 3), "plan_after_update_ms_p50": round(statistics.median(warm_p), 3),
                      "plan_after_update_ms_p99": round(pct(warm_p, 0.99), 3)}))


if __name__ == "__main__":
    main()
