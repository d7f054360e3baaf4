#!/usr/bin/env python3
"""The peer a user would pick for the whole-path risk of a plan: Monte Carlo in
numpy — one draw of every parameter per scenario, the obstacles' polynomials evaluated at
dense times of every piece, the scenario counted when some obstacle's P >= 0 at some time.
An estimate (with a Clopper–Pearson interval), not a bound: it misses contacts between the
sampled times and has no guarantee at any sample size. Timed beside `riskplan verify
--whole-path` (the certified bound) on the same plan, in the same run.

    python3 scripts/whole_path_peer.py --scene scenes/example-d1-cluttered-2d.json \
        --trajectory plan.json [--samples 100000] [--times 100] [--riskplan target/release/riskplan]

Supports the reference scenes' parameter families (normal, uniform, beta) and obstacle
polynomials in x1..x3, t and the parameters (evaluated by Python on numpy arrays).
"""
from __future__ import annotations

import argparse
import json
import re
import subprocess
import time

import numpy as np
from scipy.stats import beta as beta_dist


def draw(spec: dict, n: int, rng: np.random.Generator) -> np.ndarray:
    d = spec["dist"]
    if d == "normal":
        return rng.normal(float(spec["mean"]), float(spec["std"]), n)
    if d == "uniform":
        return rng.uniform(float(spec["low"]), float(spec["high"]), n)
    if d == "beta":
        lo, hi = float(spec.get("low", 0.0)), float(spec.get("high", 1.0))
        return lo + (hi - lo) * rng.beta(float(spec["alpha"]), float(spec["beta"]), n)
    raise SystemExit(f"unsupported distribution {d}")


def clopper_pearson(k: int, n: int, conf: float = 0.98) -> tuple[float, float]:
    a = 1.0 - conf
    lo = 0.0 if k == 0 else beta_dist.ppf(a / 2, k, n - k + 1)
    hi = 1.0 if k == n else beta_dist.ppf(1 - a / 2, k + 1, n - k)
    return lo, hi


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", required=True)
    ap.add_argument("--trajectory", required=True)
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--times", type=int, default=100, help="sampled times per piece")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--riskplan", default="target/release/riskplan", help="binary for the certified bound")
    a = ap.parse_args()
    scene = json.load(open(a.scene))
    traj = json.load(open(a.trajectory))
    rng = np.random.default_rng(a.seed)
    t0 = time.perf_counter()
    params = {name: draw(spec, a.samples, rng)[:, None] for name, spec in scene.get("params", {}).items()}
    ts, xs = [], []
    for p in traj["pieces"]:
        tt = np.linspace(p["t0"], p["t1"], a.times)
        ts.append(tt)
        xs.append([sum(c * tt**k for k, c in enumerate(row)) for row in p["coeffs"]])
    t = np.concatenate(ts)[None, :]
    env = {f"x{d + 1}": np.concatenate([x[d] for x in xs])[None, :] for d in range(scene["dim"])}
    env.update(params)
    env["t"] = t
    hit = np.zeros(a.samples, dtype=bool)
    for o in scene["obstacles"]:
        expr = re.sub(r"\^", "**", o["poly"])
        val = eval(expr, {"__builtins__": {}}, env)  # noqa: S307 (the repository's own scene files)
        hit |= np.any(val >= 0, axis=1)
    k = int(hit.sum())
    mc_s = time.perf_counter() - t0
    lo, hi = clopper_pearson(k, a.samples)
    t1 = time.perf_counter()
    out = subprocess.run(
        [a.riskplan, "verify", "--scene", a.scene, "--trajectory", a.trajectory, "--whole-path", "--compact"],
        capture_output=True, text=True,
    )
    cert_s = time.perf_counter() - t1
    bound = json.loads(out.stdout)["whole_path_risk"]["bound"]
    print(json.dumps({
        "scene": scene["name"], "pieces": len(traj["pieces"]),
        "monte_carlo": {"samples": a.samples, "times_per_piece": a.times, "estimate": k / a.samples,
                        "interval_98": [lo, hi], "seconds": round(mc_s, 3)},
        "riskplan_verify_whole_path": {"bound": bound, "seconds_end_to_end": round(cert_s, 3)},
    }))


if __name__ == "__main__":
    main()
