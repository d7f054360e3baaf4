#!/usr/bin/env python3
"""The report writer of scripts/reproduce.sh (Python 3.11, standard library only).

Subcommands (scripts/reproduce.sh calls them in this order):

  prepare --scenes DIR --out DIR --spot-mc N --traj-mc N --traj-times K
      Writes the authors' printed time-varying SOS trajectories (expected.trajectories.
      time_varying_sos.global of the reference scenes) and a straight start-goal line per
      planning scene as trajectory files (format v1, docs/formats.md §2), and the query lists
      risk-tasks.tsv (riskplan risk) and verify-tasks.tsv (riskplan verify).
  plans --bench FILE
      Prints one line per scene × planner of the benchmark's JSON lines: scene, planner,
      improve (0/1), file stem (for riskplan plan --seed 1 and its figure).
  collect --raw DIR --out DIR
      Gathers the one-file-per-query reports of riskplan risk / verify into risk.jsonl and
      verify.jsonl ({"id", "report"} per line).
  meta --out FILE
      Writes the run's facts (from the RP_* environment variables set by reproduce.sh).
  report --scenes DIR --results DIR --figures DIR --out FILE
      Writes docs/reproduction.md. Every number comes from the scenes (what the paper reports)
      or from the raw results (what we measured); the descriptions of the paper's figures and
      the reasons for known differences are text kept below (PAPER_FIGURES, WHY). Fails
      (exit status 1, naming the file) if a result or a figure it wants is missing.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import re
import statistics
import sys
from decimal import Decimal
from pathlib import Path

TRAJECTORY_FORMAT = "riskplan-trajectory/1"


def die(msg: str) -> None:
    print(f"reproduce_report.py: error: {msg}", file=sys.stderr)
    sys.exit(1)


def load_json(path: Path):
    if not path.is_file():
        die(f"{path}: missing (run scripts/reproduce.sh)")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        die(f"{path}: not JSON: {e}")


def load_scenes(scenes_dir: Path) -> dict[str, dict]:
    files = sorted(scenes_dir.glob("*.json"))
    if not files:
        die(f"{scenes_dir}: no scene files")
    out = {}
    for f in files:
        s = load_json(f)
        s["_file"] = str(f)
        out[f.stem] = s
    return out


def is_dynamic(scene: dict) -> bool:
    return any(re.search(r"\bt\b", o["poly"]) for o in scene["obstacles"])


def delta_of(scene: dict) -> Decimal:
    return Decimal(str(scene["risk"]))


def authors_global(scene: dict):
    try:
        return scene["expected"]["trajectories"]["time_varying_sos"]["global"]
    except (KeyError, TypeError):
        return None


def authors_trajectory(scene: dict) -> dict:
    """expected.trajectories.time_varying_sos.global as format v1: piece [t0, t1] = interval,
    coeffs per coordinate = [offset, slope] in absolute time (as crates/riskplan-app/tests/integration/certify_scenes.rs)."""
    pieces = [
        {"t0": p["interval"][0], "t1": p["interval"][1], "coeffs": [[o, k] for o, k in zip(p["offset"], p["slope"])]}
        for p in authors_global(scene)
    ]
    return {"format": TRAJECTORY_FORMAT, "pieces": pieces, "planner": "authors' time-varying SOS (as printed)", "scene": scene["name"]}


def straight_trajectory(scene: dict) -> dict:
    (t0, t1), a, b = scene["horizon"], scene["start"], scene["goal"]
    coeffs = []
    for ad, bd in zip(a, b):
        s = (bd - ad) / (t1 - t0)
        coeffs.append([ad - s * t0, s])
    return {"format": TRAJECTORY_FORMAT, "pieces": [{"t0": t0, "t1": t1, "coeffs": coeffs}], "planner": "straight line (control)", "scene": scene["name"]}


def continuity_gaps(traj: dict) -> list[list[float]]:
    """[t, largest coordinate jump] at each time two pieces share."""
    out = []
    for a, b in zip(traj["pieces"], traj["pieces"][1:]):
        t = b["t0"]
        ya = [sum(c * t**k for k, c in enumerate(row)) for row in a["coeffs"]]
        yb = [sum(c * t**k for k, c in enumerate(row)) for row in b["coeffs"]]
        out.append([t, max(abs(x - y) for x, y in zip(ya, yb))])
    return out


def eval_traj(traj: dict, t: float) -> list[float]:
    for p in traj["pieces"]:
        if p["t0"] <= t <= p["t1"]:
            return [sum(c * t**k for k, c in enumerate(row)) for row in p["coeffs"]]
    die(f"time {t} outside the trajectory of {traj.get('scene')}")


def num(x) -> str:
    """A number for the command line (riskplan reads decimals exactly)."""
    return repr(float(x)) if not isinstance(x, str) else x


def delta_ladder(d: Decimal) -> list[Decimal]:
    """Δ and a few levels slightly above it (for a rejected trajectory: how much larger a Δ certifies it)."""
    return [d] + [d + Decimal(s) for s in ("0.00001", "0.0001", "0.001", "0.01")]


# --------------------------------------------------------------------------------------------
# prepare / plans / meta


def cmd_prepare(a) -> None:
    scenes = load_scenes(Path(a.scenes))
    if a.traj_times < 2:
        die("--traj-times must be at least 2")
    out = Path(a.out)
    (out / "trajectories").mkdir(parents=True, exist_ok=True)
    risk_tasks, verify_tasks = [], []

    def risk_task(tid, name, t, delta, mc, x):
        risk_tasks.append("\t".join([tid, name, num(t), str(delta), str(mc), " ".join(num(v) for v in x)]))

    for name, s in scenes.items():
        d = delta_of(s)
        if s.get("start") is None:  # contour-only experiment: its spot values
            spot = s.get("expected", {}).get("derived_checks", {}).get("spot_values", {}).get("points", [])
            if not spot:
                die(f"{s['_file']}: contour-only scene without expected.derived_checks.spot_values")
            for i, p in enumerate(spot):
                risk_task(f"spot--{name}--{i}", name, p["t"], d, a.spot_mc, p["x"])
            radii = s.get("expected", {}).get("derived_checks", {}).get("contour_radii")
            if radii:  # illustrative-1: the moments at the origin, and the contour radii
                risk_task(f"origin--{name}", name, 0, d, a.spot_mc, [0] * s["dim"])
                for r in radii["radii"]:
                    if r["Delta"] in s["expected"]["risk_levels_paper_text"]:
                        for kind, key in (("inner", "inner_approx_radius"), ("true", "true_contour_radius")):
                            risk_task(f"radius-{kind}--{name}--{r['Delta']}", name, 0, d, a.spot_mc, [r[key]] + [0] * (s["dim"] - 1))
            continue
        trajs = {"straight-line": straight_trajectory(s)}
        if authors_global(s):
            trajs["authors-tv-sos"] = authors_trajectory(s)
        for which, traj in trajs.items():
            path = out / "trajectories" / f"{name}--{which}.json"
            path.write_text(json.dumps(traj, indent=1) + "\n")
            deltas = delta_ladder(d) if which == "authors-tv-sos" else [d]
            # pieces must meet to within 1e-9 × max(1, workspace diagonal) (docs/formats.md §2.3);
            # printed coefficients that do not are verified piece by piece
            gaps = continuity_gaps(traj)
            tol = 1e-9 * max(1.0, math.dist(s["workspace"]["lower"], s["workspace"]["upper"]))
            split = any(g > tol for _, g in gaps)
            (out / "trajectories" / f"{name}--{which}.meta.json").write_text(
                json.dumps({"gaps": gaps, "tolerance": tol, "split": split, "pieces": len(traj["pieces"])}, indent=1) + "\n")
            files = [("", path)]
            if split:
                files = []
                for k, piece in enumerate(traj["pieces"]):
                    pp = out / "trajectories" / f"{name}--{which}--piece{k + 1}.json"
                    pp.write_text(json.dumps(dict(traj, pieces=[piece]), indent=1) + "\n")
                    files.append((f"--piece{k + 1}", pp))
            for dd in deltas:
                for suffix, f in files:
                    verify_tasks.append("\t".join([f"{which}--{name}--{dd}{suffix}", name, str(f), str(dd)]))
            (h0, h1), k = s["horizon"], a.traj_times
            times = [h0 + (h1 - h0) * i / (k - 1) for i in range(k)]
            if which == "authors-tv-sos":  # where the file's own sampling found the largest bound
                per = s["expected"].get("derived_checks", {}).get("reported_time_varying_sos_trajectory", {}).get("per_obstacle", {})
                times += [v["argmax_tau"] for v in per.values() if "argmax_tau" in v]
            for i, t in enumerate(times):
                risk_task(f"traj--{name}--{which}--{i}", name, t, d, a.traj_mc, eval_traj(traj, t))
    (out / "risk-tasks.tsv").write_text("".join(t + "\n" for t in risk_tasks))
    (out / "verify-tasks.tsv").write_text("".join(t + "\n" for t in verify_tasks))


def read_bench(path: Path) -> list[dict]:
    if not path.is_file():
        die(f"{path}: missing (the benchmark's JSON lines)")
    recs = []
    for i, line in enumerate(path.read_text().splitlines(), 1):
        if line.strip():
            try:
                recs.append(json.loads(line))
            except json.JSONDecodeError as e:
                die(f"{path}:{i}: not JSON: {e}")
    if not recs:
        die(f"{path}: empty")
    return recs


def stem_of(scene: str, label: str) -> str:
    return f"{scene}--{label.replace(' --', '-').replace(' ', '-')}"


def cmd_plans(a) -> None:
    seen = []
    for r in read_bench(Path(a.bench)):
        key = (r["scene"], r["planner"])
        if key not in seen:
            seen.append(key)
    for scene, label in seen:
        print("\t".join([scene, label.split()[0], "1" if "--improve" in label else "0", stem_of(scene, label)]))


def cmd_collect(a) -> None:
    """One JSON line {"id", "report"} per raw risk / verify report, sorted by id."""
    raw, out = Path(a.raw), Path(a.out)
    for kind in ("risk", "verify"):
        lines = []
        for f in sorted((raw / kind).glob("*.json")):
            try:
                rep = json.loads(f.read_text())
            except json.JSONDecodeError as e:
                die(f"{f}: not JSON ({e}); riskplan {kind} wrote no report")
            lines.append(json.dumps({"id": f.stem, "report": rep}, separators=(",", ":")))
        if not lines:
            die(f"{raw / kind}: no reports")
        (out / f"{kind}.jsonl").write_text("".join(x + "\n" for x in lines))


def read_reports(path: Path) -> dict[str, dict]:
    if not path.is_file():
        die(f"{path}: missing (run scripts/reproduce.sh)")
    out = {}
    for i, line in enumerate(path.read_text().splitlines(), 1):
        try:
            r = json.loads(line)
        except json.JSONDecodeError as e:
            die(f"{path}:{i}: not JSON: {e}")
        out[r["id"]] = r["report"]
    return out


def cmd_meta(a) -> None:
    env = os.environ
    keys = ["BIN", "SEEDS", "TIME_LIMIT", "AUDIT_SAMPLES", "AUDIT_TIMES", "SPOT_MC", "TRAJ_MC", "TRAJ_TIMES", "CONTOUR_MC", "ARGS", "KNOBS", "START", "END", "STAGES", "NPROC", "CPU", "GIT", "DIRTY", "VERSION"]
    missing = [k for k in keys if f"RP_{k}" not in env]
    if missing:
        die(f"meta: environment variables missing: {', '.join('RP_' + k for k in missing)}")
    m = {k.lower(): env[f"RP_{k}"] for k in keys}
    m["stages"] = {kv.split("=")[0]: int(kv.split("=")[1]) for kv in m["stages"].split()}
    m["openblas_num_threads"] = env.get("OPENBLAS_NUM_THREADS", "unset")
    m["date_utc"] = datetime.datetime.fromtimestamp(int(m["start"]), datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    Path(a.out).write_text(json.dumps(m, indent=1) + "\n")


# --------------------------------------------------------------------------------------------
# What the paper shows, and why we differ: text, written for this report (no numbers here).

EXPERIMENTS = [
    ("illustrative-1", "Illustrative Example 1: static risk contours of an uncertain disk", "Sec. IV-A, Figs. 1–2"),
    ("illustrative-2", "Illustrative Example 2: dynamic risk contours of a moving disk", "Sec. IV-B, Fig. 3"),
    ("illustrative-3", "Illustrative Example 3: planning around a static uncertain disk", "Sec. V-A, Fig. 4"),
    ("illustrative-4", "Illustrative Example 4: planning around a moving uncertain disk", "Sec. V-B, Fig. 5"),
    ("example-a1-2d", "Example A-1: risk contours of a nonconvex 2-D obstacle", "Sec. VI-A.1, Figs. 6–7"),
    ("example-a2-3d", "Example A-2: risk contours of a nonconvex 3-D obstacle", "Sec. VI-A.2, Fig. 8"),
    ("example-b-lane-change", "Example B: lane change among two uncertain cars", "Sec. VI-B, Fig. 9"),
    ("example-c-delivery", "Example C: delivery robot among three moving obstacles", "Sec. VI-C, Fig. 10"),
    ("example-d1-cluttered-2d", "Example D-1: static clutter in 2-D", "Sec. VI-D.1, Fig. 11"),
    ("example-d2-cluttered-3d", "Example D-2: moving clutter in 3-D", "Sec. VI-D.2, Fig. 12"),
]

# Per experiment: (the paper's figure, described in our words; our figure files (contour scenes) or
# None (planning scenes: one figure per planner, seed 1)).
PAPER_FIGURES = {
    "illustrative-1": [
        ("Fig. 1: the ratio (E[P²] − E[P]²)/E[P²] over the plane, and the closed curves where it equals Δ "
         "(Δ = 0.2, 0.1, 0.07, 0.05) around the disk; outside a curve (and where E[P] ≤ 0) the risk is at most Δ.",
         ["illustrative-1-contours.svg"]),
        ("Fig. 2: the true Δ-contours estimated by Monte Carlo (green) against the analytic inner approximation "
         "(solid) and an order-20 polynomial from the authors' earlier optimisation-based method (dashed); the "
         "analytic curves lie closer to the true ones.", None),
    ],
    "illustrative-2": [
        ("Fig. 3: (a) the ratio as a surface at t = 0, 0.5, 1; (b) the 0.1-contours of the moving disk at those "
         "three times, with the mean path of its centre dashed.", ["illustrative-2-contours.svg"]),
    ],
    "illustrative-3": [
        ("Fig. 4, four panels: (a) two mirror-image degree-2 polynomial trajectories and (b) two mirror-image "
         "2-piece linear trajectories from standard SOS, both keeping well away from the disk (conservative); "
         "(c) the RRT-SOS piecewise-linear path; (d) the 2-piece time-varying SOS path, which grazes the 0.1-contour.", None),
    ],
    "illustrative-4": [
        ("Fig. 5: the moving disk's 0.1-contours with the time-varying SOS trajectory (solid), which bends away "
         "from the obstacle's path, and the RRT-SOS trajectory (dashed): two pieces at different speeds that look "
         "like one straight line.", None),
    ],
    "example-a1-2d": [
        ("Fig. 6: (a) the nonconvex obstacle drawn for several values of ω; (b) its inner-approximated contours "
         "for Δ = 0.3, 0.1, 0.05, 0.02, 0.01.", ["example-a1-2d-contours.svg"]),
        ("Fig. 7: the true contours from Monte Carlo (green) with the inner approximations (solid) inside them.", None),
    ],
    "example-a2-3d": [
        ("Fig. 8: (a) the 3-D nonconvex obstacle for several values of ω; (b) its contour surfaces for "
         "Δ = 0.5, 0.3, 0.1, 0.05, drawn in 3-D.",
         ["example-a2-3d-slice-x3-minus0.5.svg", "example-a2-3d-slice-x3-0.svg", "example-a2-3d-slice-x3-plus0.5.svg"]),
    ],
    "example-b-lane-change": [
        ("Fig. 9: the lane change from the start (square) to the goal (triangle): time-varying SOS (solid) and "
         "RRT-SOS (dotted), with the mean paths of the two surrounding cars dashed.", None),
    ],
    "example-c-delivery": [
        ("Fig. 10: the delivery robot's path from the start (square) up to the goal (triangle) across three rows "
         "of moving uncertain discs: time-varying SOS (solid) and RRT-SOS (dotted).", None),
    ],
    "example-d1-cluttered-2d": [
        ("Fig. 11: the RRT-SOS path from (0, 0) to (5, 5) between the eight uncertain discs, with the discs' "
         "0.1-contours.", None),
    ],
    "example-d2-cluttered-3d": [
        ("Fig. 12: a 3-D view of the RRT-SOS path among six moving uncertain spheres.", None),
    ],
}

# What each of our planners is, and which of the paper's run times it answers (static, dynamic).
PLANNERS = {
    "rrt-sos": ("ours: bidirectional / time-layered RRT, shortcut and C¹ blends, exact certifier", None, None),
    "rrt-sos-paper": ("the paper's RRT-SOS as published (widening stripes, rlim)", "rrt_sos_feasible", "rrt_sos"),
    "rrt-sos-paper --improve": ("RRT-SOS with its improve step (the paper's \"optimal\")", "rrt_sos_optimal", None),
    "mc-rrt": ("Monte Carlo RRT baseline (10 scenarios × 20 waypoints per edge)", "monte_carlo_rrt_feasible", None),
    "tv-sos": ("time-varying SOS (Sec. V-B), moment relaxation on Clarabel", "time_varying_sos", "time_varying_sos"),
    "moment": ("standard SOS, piecewise linear (average risk)", "standard_sos_piecewise_linear", "standard_sos_piecewise_linear"),
    "moment-poly": ("standard SOS, one polynomial (average risk)", "standard_sos_polynomial", "standard_sos_polynomial"),
}

# Run times the paper reports that no planner of ours answers.
PAPER_ONLY = {"monte_carlo_rrt_optimal": "Monte Carlo RRT, optimal path:"}

# Reasons for known differences (text only; the numbers that go with them are filled in from the data).
WHY = {
    "platform": "The paper's times are MATLAB + Spotless (RRT-SOS, standard SOS via GloptiPoly) and Julia + "
                "MOSEK (time-varying SOS) on a 2.7 GHz Intel i7 with 8 GB; ours are one Rust process with "
                "OPENBLAS_NUM_THREADS=1 on the machine in the header. Ratios compare implementations, not algorithms.",
    "edge_check": "rrt-sos-paper follows the published search, but each edge is proven by the exact Bernstein "
                  "checker (interval arithmetic, exact fallback) instead of an SOS program solved by Spotless; "
                  "the paper quotes about {paper_edge} per SOS edge check (Illustrative Example 3), ours takes a "
                  "median {ours_edge} per edge on this scene.",
    "mc_rrt": "The paper's Monte Carlo RRT has no published code; ours is our default tree search with the paper's "
              "edge test (10 scenarios × 20 waypoints), so its time measures that test, not the authors' program "
              "(paper: {paper_mc_edge} per edge check; ours: {ours_mc_edge}). As the paper says, it gives no "
              "guarantee: its worst audited risk is {mc_worst} against Δ = {delta}, over Δ in {mc_over} of "
              "{mc_solved} plans.",
    "mc_rrt_dyn": "The paper ran the Monte Carlo baseline only on Illustrative Example 3; here it runs on every "
                  "planning scene for comparison (worst audited risk {mc_worst} against Δ = {delta}, over Δ in "
                  "{mc_over} of {mc_solved} plans).",
    "rrt_sos": "rrt-sos (our default planner) is not in the paper; it is shown as the reference for speed and length.",
    "standard_sos": "The paper's standard SOS planners bound only the time-averaged risk (t treated as uniform on "
                    "each piece), which does not bound the risk at each instant. Ours solves the same moment "
                    "relaxation, extracts its atoms and certifies each atom's trajectory against the per-instant Δ; "
                    "when none is certified it tightens the optimisation's risk level Δ_opt = η·Δ, then adds a piece "
                    "(seed 1: {moment_ladder}). "
                    "An atom that is not certified is reported as leaving the workspace where it does (sampled, for "
                    "the log only): the degree-2 optimum of the paper's problem bulges past the box [−1, 1]² of "
                    "this scene. The authors' polynomial script also hard-codes the constraints of a radius Uniform[0.1, 0.15] "
                    "and their piecewise-linear one uses the horizon [0, 2]; ours use the scene's disk and horizon.",
    "tv_sos": "Our tv-sos solves the paper's moment relaxation on Clarabel instead of MOSEK and starts from the "
              "default RRT-SOS path (else the perturbed straight line). The paper verifies the heuristic's "
              "trajectory with the SOS condition afterwards and, if it fails, reruns with more iterations or "
              "pieces by hand; ours certifies every piece and retries by itself (fresh seeds, more pieces, a "
              "tighter optimisation risk Δ_opt = η·Δ). Seed 1: {tv_ladder}.",
    "authors_rejected": "The authors' printed trajectory is not certified at Δ = {delta}: {authors_failure}. "
                        "{authors_ladder} The authors' run solved the SOS program to MOSEK's tolerance, so a "
                        "trajectory that touches the contour can cross it by that tolerance; our certifier decides "
                        "in exact arithmetic and gives no benefit of the doubt.",
    "authors_ok": "The authors' printed trajectory is certified at Δ = {delta} by both methods (smallest proven "
                  "margin {authors_margin}).",
    "illustrative-1": "Fig. 2's dashed order-20 polynomial comes from the authors' earlier optimisation-based "
                      "contour method, which riskplan does not implement; our figure shows the analytic curves and "
                      "the Monte Carlo shading only. The paper prints the moments rounded to four digits; riskplan "
                      "computes them exactly.",
    "illustrative-2": "The paper states the workspace [−1, 1]², which the moving disk never enters; the scene uses "
                      "the box the authors' code plots. Panel (a), the ratio as a surface, is not drawn. The paper "
                      "writes N(0, 0.1) for ω₂ meaning standard deviation 0.1, as the authors' code does.",
    "example-a1-2d": "Fig. 6(a) draws the obstacle for several values of ω; ours draws it at the mean of ω (grey) "
                     "with the Monte Carlo shading of Fig. 7 in the same figure.",
    "example-a2-3d": "riskplan draws 2-D figures: the 3-D contour surfaces of Fig. 8 appear as three slices "
                     "x3 = const. The paper's N(0.1, 0.001) means variance 0.001 here (standard deviation 0.0316), "
                     "as in the authors' code.",
    "illustrative-3": "Our figures show one plan per planner; the paper's panels (a) and (b) show both mirror-image "
                      "solutions that GloptiPoly extracted. The authors' Monte Carlo RRT 'optimal' run (paper: {mc_opt}) has no counterpart: mc-rrt has "
                      "no improve step.",
    "illustrative-4": "The paper's RRT-SOS used 2 pieces here; rrt-sos-paper reads the scene's planner block.",
    "example-b-lane-change": "The goal is (2, 1) as in the authors' code (the paper's text says (2, 0)). The authors' "
                             "time-varying SOS script constrains only the car in lane 1 and omits the second car; "
                             "ours, and our check of their trajectory, use both cars. RRT-SOS used 3 pieces, "
                             "time-varying SOS 2.",
    "example-c-delivery": "The paper names ω₁ in the second obstacle's path where ω₂ is meant; each obstacle has its "
                          "own parameter, as in the authors' code. The scene's workspace is the intersection of the "
                          "two boxes the authors' scripts use.",
    "example-d1-cluttered-2d": "The paper's noise variance 0.001 is kept (standard deviation 0.0316). Only RRT-SOS "
                               "was run in the paper; the other planners are ours.",
    "example-d2-cluttered-3d": "The start is (−1, −1, −1) as in the authors' code (the paper says (−1, −1, 0)). The "
                               "authors' mean constraint omits the noise variance (conservative); ours uses the exact "
                               "moments. Our figures are the x1–x2 projection, each contour the section at the "
                               "path's x3 at its time; the paper's is a 3-D view.",
}


# --------------------------------------------------------------------------------------------
# Formatting


def fmt_s(x) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    if x < 1e-3:
        return f"{x * 1e6:.0f} µs"
    if x < 1:
        return f"{x * 1e3:.1f} ms"
    return f"{x:.2f} s"


def fmt_g(x, digits=4) -> str:
    if x is None:
        return "–"
    if x == 0:
        return "0"
    if abs(x) < 1e-3 or abs(x) >= 1e5:
        return f"{x:.{digits - 1}e}"
    return f"{x:.{digits}g}"


def fmt_ratio(paper, ours) -> str:
    if paper is None or ours is None or ours <= 0:
        return "–"
    r = paper / ours
    if r >= 1:
        return f"{r:,.0f}× faster" if r >= 10 else f"{r:.1f}× faster"
    return f"{1 / r:.1f}× slower"


def median(v):
    v = [x for x in v if x is not None]
    return statistics.median(v) if v else None


# --------------------------------------------------------------------------------------------
# Reading the results


def analyse_verify(rep: dict) -> dict:
    """safe (both methods), per-method verdicts, the first failure, the smallest proven margin."""
    methods: dict[str, bool] = {}
    fails, margins = [], []
    for i, p in enumerate(rep["pieces"]):
        ws = p["workspace"]["status"]
        if ws != "safe":
            fails.append({"piece": i + 1, "what": "workspace", "status": ws, "witness": p["workspace"].get("witness")})
        for o in p["obstacles"]:
            for c in o["constraints"]:
                per = c.get("methods") or [[c["method"], c]]
                for name, m in per:
                    methods[name] = methods.get(name, True) and m["status"] == "safe" and ws == "safe"
                if c["status"] != "safe":
                    wit = c.get("witness")
                    for name, m in per:  # the proving method's witness, if the combined one has none
                        wit = wit or m.get("witness")
                    by = [(name, m["witness"]) for name, m in per if m.get("witness")]
                    fails.append({"piece": i + 1, "what": f"{c['name']} constraint of {o['id']}", "status": c["status"],
                                  "witness": wit, "by": by, "reason": c.get("reason")})
                elif c.get("margin") is not None:
                    margins.append(c["margin"])
    return {"safe": rep["safe"], "risk": rep["risk"], "methods": methods, "fails": fails, "margin": min(margins) if margins else None}


def describe_failure(v: dict, short: bool = False) -> str:
    f = v["fails"][0]
    if short:
        at = f" at t = {f['witness']['t']:.3f}" if f.get("witness") else ""
        return f"piece {f['piece']}, {f['what']}: {f['status']}{at}" + (f" (+{len(v['fails']) - 1})" if len(v["fails"]) > 1 else "")
    s = f"piece {f['piece']}, {f['what']}: {f['status']}"
    if len(f.get("by") or []) > 1:
        s += " (witness " + "; ".join(f"{name}: t = {w['t']:.4f}, value {fmt_g(w['value'], 3)}" for name, w in f["by"]) + ")"
    elif f.get("witness"):
        s += f" (witness t = {f['witness']['t']:.4f}, value {fmt_g(f['witness']['value'], 3)})"
    elif f.get("reason"):
        s += f" ({f['reason']})"
    if len(v["fails"]) > 1:
        s += f"; {len(v['fails']) - 1} more"
    return s


def verdict_word(v: dict) -> str:
    per = ", ".join(f"{m} {'✓' if ok else '✗'}" for m, ok in v["methods"].items())
    return f"{'**certified**' if v['safe'] else '**not certified**'} ({per})"


class Results:
    def __init__(self, scenes: dict, results: Path, figures: Path):
        self.scenes, self.dir, self.figdir = scenes, results, figures
        self.meta = load_json(results / "run.json")
        self.bench = {}
        for r in read_bench(results / "bench.jsonl"):
            self.bench.setdefault((r["scene"], r["planner"]), []).append(r)
        self.verify_tasks = self._tsv(results / "verify-tasks.tsv")
        self.risk_tasks = self._tsv(results / "risk-tasks.tsv")
        self.verify_reports = read_reports(results / "verify.jsonl")
        self.risk_reports = read_reports(results / "risk.jsonl")

    @staticmethod
    def _tsv(path: Path) -> list[list[str]]:
        if not path.is_file():
            die(f"{path}: missing")
        return [line.split("\t") for line in path.read_text().splitlines() if line]

    def figure(self, name: str) -> str:
        """The markdown path (relative to docs/) of a figure that must exist."""
        p = self.figdir / name
        if not p.is_file():
            die(f"{p}: figure missing")
        return os.path.relpath(p, Path("docs")).replace(os.sep, "/")

    def verify(self, tid: str) -> dict:
        if tid not in self.verify_reports:
            die(f"{self.dir / 'verify.jsonl'}: no report '{tid}'")
        return analyse_verify(self.verify_reports[tid])

    def verify_given(self, scene: str, which: str, delta) -> dict:
        """The verdict on a given trajectory; printed pieces that do not meet were verified one by one."""
        meta = load_json(self.dir / "trajectories" / f"{scene}--{which}.meta.json")
        if not meta["split"]:
            v = self.verify(f"{which}--{scene}--{delta}")
            v["split"] = None
            return v
        parts = [self.verify(f"{which}--{scene}--{delta}--piece{k + 1}") for k in range(meta["pieces"])]
        fails = []
        for k, v in enumerate(parts):
            fails += [dict(f, piece=k + 1) for f in v["fails"]]
        methods = {m: all(v["methods"].get(m, False) for v in parts) for m in parts[0]["methods"]}
        margins = [v["margin"] for v in parts if v["margin"] is not None]
        worst = max(meta["gaps"], key=lambda g: g[1])
        return {"safe": all(v["safe"] for v in parts), "risk": parts[0]["risk"], "methods": methods, "fails": fails,
                "margin": min(margins) if margins else None, "split": worst}

    def risk(self, tid: str) -> dict:
        if tid not in self.risk_reports:
            die(f"{self.dir / 'risk.jsonl'}: no report '{tid}'")
        return self.risk_reports[tid]

    def labels(self, scene: str) -> list[str]:
        """The planners this scene must have in the benchmark (as riskplan bench chooses them)."""
        s = self.scenes[scene]
        labels = ["rrt-sos", "rrt-sos-paper"] + ([] if is_dynamic(s) else ["rrt-sos-paper --improve"]) + ["mc-rrt"]
        block = s.get("planner") or {}
        if "time_varying_sos" in block:
            labels.append("tv-sos")
        if "standard_sos" in block:
            labels += ["moment", "moment-poly"]
        for lab in labels:
            if (scene, lab) not in self.bench:
                die(f"{self.dir / 'bench.jsonl'}: no runs of {lab} on {scene}")
        return labels

    def summary(self, scene: str, label: str) -> dict:
        recs = self.bench[(scene, label)]
        solved = [r for r in recs if "audit" in r]
        st = lambda r: r["stats"]  # noqa: E731
        edge = [st(r)["checker_time_s"] / st(r)["edges_checked"] for r in recs if st(r).get("edges_checked")]
        return {
            "runs": len(recs),
            "solved": len(solved),
            "time": median([st(r)["planning_time_s"] for r in solved]),
            "first": median([st(r).get("time_to_feasible_s") for r in solved]),
            "length": median([st(r).get("path_length") for r in solved]),
            "worst": max((r["audit"]["max_risk_estimate"] for r in solved), default=None),
            "over": sum(bool(r["audit"]["exceeds_delta_99"]) for r in solved),
            "certified": sum(bool(r.get("certified")) for r in solved),
            "edge": median(edge),
            "fail_status": sorted({r["status"] for r in recs if "audit" not in r}),
            "fail_time": median([st(r)["planning_time_s"] for r in recs if "audit" not in r]),
            "seed1": next((r for r in recs if r["seed"] == 1), None),
        }

    def traj_mc(self, scene: str, which: str) -> dict:
        rows = [t for t in self.risk_tasks if t[0].startswith(f"traj--{scene}--{which}--")]
        if not rows:
            die(f"{self.dir / 'risk-tasks.tsv'}: no Monte Carlo queries along {which} of {scene}")
        worst, bound, over, n = (-1.0, None), 0.0, 0, None
        delta = float(rows[0][3])
        for t in rows:
            r = self.risk(t[0])
            for o in r["obstacles"]:
                mc = o["mc"]
                n = mc["samples"]
                if (mc["estimate"], mc["upper"]) > (worst[0], worst[4] if len(worst) > 4 else -1):
                    worst = (mc["estimate"], r["time"], o["id"], mc["lower"], mc["upper"])
                bound = max(bound, o["bound"])
                over += mc["lower"] > delta
        return {"worst": worst[0], "t": worst[1], "obstacle": worst[2], "lower": worst[3], "upper": worst[4], "bound": bound,
                "over": over, "times": len(rows), "samples": n}


# --------------------------------------------------------------------------------------------
# The report


def paper_time(scene: dict, key: str | None):
    if key is None:
        return None, "–"
    e = (scene.get("expected") or {}).get("run_time_s") or {}
    v = e.get(key)
    if not v or "paper" not in v:
        return None, "–"
    txt = f"paper: {v['paper']} s"
    if v.get("Results.txt") not in (None, v["paper"]):
        txt += f" (code: {v['Results.txt']} s)"
    return float(v["paper"]), txt


def ladder_text(rec: dict | None, start: bool = True) -> str:
    if not rec:
        return "no seed-1 run"
    steps = rec["stats"].get("ladder") or []
    if not steps:
        return "no ladder recorded"
    last = steps[-1]
    etas = ", ".join(fmt_g(x["eta"], 3) for x in steps)
    s = f"{len(steps)} step{'s' if len(steps) > 1 else ''} (η = {etas}), the last with {last['pieces']} piece{'s' if last['pieces'] > 1 else ''}"
    if start:
        s += f" from {'the RRT-SOS path' if last.get('from_rrt') else 'the straight line'}"
    s += f": {last['outcome']}"
    if last["outcome"] != "certified" and len(steps) > 1:
        # no plan: every step's outcome says why
        s += "; the steps: " + "; ".join(f"η = {fmt_g(x['eta'], 3)}, {x['pieces']} piece{'s' if x['pieces'] > 1 else ''}: "
                                         f"{x['outcome']}" for x in steps[:-1])
    avg = rec["stats"].get("average_risk")
    if avg:
        s += "; its average-risk bound " + ", ".join(f"{fmt_g(v, 3)} ({k})" for k, v in avg)
    return s


def header(R: Results) -> list[str]:
    m = R.meta
    debug = "/debug/" in m["bin"]
    dirty = int(m["dirty"])
    cmd = f"{m['knobs']} scripts/reproduce.sh" + (f" {m['args']}" if m["args"] else "")
    stages = ", ".join(f"{k} {v} s" for k, v in m["stages"].items())
    total = int(m["end"]) - int(m["start"])
    lines = [
        "# Reproduction of the paper's experiments",
        "",
        "Jasour, Han, Williams, *Convex Risk Bounded Continuous-Time Trajectory Planning in Uncertain Nonconvex "
        "Environments*, RSS 2021: every experiment (Illustrative Examples 1–4, Examples A–D) with every planner the "
        "paper used on it, and ours beside them. **Generated** by `scripts/reproduce.sh` from the reference scenes "
        "(`scenes/`, whose `expected` blocks hold what the paper reports) and the raw results in "
        "`docs/reproduction/`; do not edit by hand. Regenerate with",
        "",
        f"    {cmd}",
        "",
        "| run | |",
        "|---|---|",
        f"| date | {m['date_utc']} |",
        f"| machine | {m['nproc']} cores (`nproc`), {m['cpu'] or 'CPU model unknown'} |",
        f"| git | `{m['git']}`" + (f" with {dirty} uncommitted changed file{'s' if dirty != 1 else ''}" if dirty else "") + " |",
        f"| binary | `{m['bin']}` ({m['version']})" + (" — **a debug build: run times are not representative**" if debug else "") + " |",
        f"| `OPENBLAS_NUM_THREADS` | {m['openblas_num_threads']} |",
        f"| seeds | {'1' if m['seeds'] == '1' else '1–' + m['seeds']} per planner and scene (figures and plan files: seed 1) |",
        f"| time limit | {m['time_limit']} s per planner run |",
        f"| Monte Carlo | plan audit {m['audit_samples']} scenarios × {m['audit_times']} times per piece; spot points {m['spot_mc']} samples; "
        f"trajectories {m['traj_mc']} samples × {m['traj_times']} times; figures {m['contour_mc']} samples per grid point |",
        f"| run time | {total} s ({stages}) |",
        "",
        "**How to read the planner tables.** *paper* is the run time the paper reports (the authors' code's "
        "`Results.txt` in brackets where it differs); *ours* the median planning time over the seeds that found a "
        "plan, *first plan* the median time to the first feasible path; *paper ÷ ours* the speed ratio; *length* "
        "the median path length; *MC risk* the largest Monte Carlo estimate of the collision probability with one "
        "obstacle at any audited time over all plans, against Δ; *over Δ* the plans whose 99 % Clopper–Pearson "
        "lower bound exceeds Δ somewhere; *certified* the plans the planner certified; *verify* the verdict of "
        "`riskplan verify --method both` (exact and SOS) on the seed-1 plan. Planners in *italics* are not in the "
        "paper for that experiment.",
        "",
    ]
    return lines


def summary_table(R: Results) -> list[str]:
    out = ["## Summary", "", "| experiment | paper's planners: ours solved / certified / over Δ | authors' printed trajectory |", "|---|---|---|"]
    for scene, title, where in EXPERIMENTS:
        s = R.scenes[scene]
        if s.get("start") is None:
            pts = [t for t in R.risk_tasks if t[0].startswith(f"spot--{scene}--")]
            ok = sum(1 for t in pts if spot_consistent(R, t, s))
            out.append(f"| [{title.split(':')[0]}](#{anchor(title)}) | contours only: at {ok} of {len(pts)} spot points ours agree with the scene file | – |")
            continue
        cells = []
        for lab in R.labels(scene):
            key = PLANNERS[lab][2 if is_dynamic(s) else 1]
            if paper_time(s, key)[0] is None:
                continue
            sm = R.summary(scene, lab)
            cells.append(f"{lab} {sm['solved']}/{sm['certified']}/{sm['over']}")
        authors = "–"
        if authors_global(s):
            v = R.verify_given(scene, "authors-tv-sos", delta_of(s))
            authors = "certified" if v["safe"] else "not certified at Δ = " + str(delta_of(s))
        out.append(f"| [{title.split(':')[0]}](#{anchor(title)}) | {'; '.join(cells)} (of {R.meta['seeds']}) | {authors} |")
    return out + [""]


def anchor(title: str) -> str:
    a = title.lower()
    a = re.sub(r"[^\w\- ]", "", a)
    return a.replace(" ", "-")


def spot_consistent(R: Results, task: list[str], scene: dict) -> bool:
    """Ours agree with the file: E[P] to 1e-8 relative, the bound likewise, the file's MC inside our interval
    widened by its own 4σ."""
    i = int(task[0].rsplit("--", 1)[1])
    p = scene["expected"]["derived_checks"]["spot_values"]["points"][i]
    r = R.risk(task[0])
    for o in r["obstacles"]:
        f = p["per_obstacle"][o["id"]]
        if abs(o["mean"] - f["E_P"]) > 1e-8 * max(1, abs(f["E_P"])):
            return False
        if f["cantelli_bound"] is not None and abs(o["bound"] - f["cantelli_bound"]) > 1e-8 * max(1, f["cantelli_bound"]):
            return False
        q = f["mc_risk"]
        sd = 4 * math.sqrt(max(q * (1 - q), 1e-6) / 1e6)
        if not (o["mc"]["lower"] - sd <= q <= o["mc"]["upper"] + sd):
            return False
    return True


def figure_block(R: Results, scene: str, planner_figs: list[tuple[str, str]] | None) -> list[str]:
    out = ["**Figures.**", ""]
    for desc, ours in PAPER_FIGURES[scene]:
        out.append(f"- Paper — {desc}")
        if ours:
            for f in ours:
                out.append(f"  ![{scene}: {f}]({R.figure(f)})")
    if planner_figs:
        out.append("")
        out.append("Ours (seed 1; grey: the planner's tree, edges it accepted (certified, except mc-rrt's); blue: the path; "
                   "curves: the Cantelli Δ-contours, for moving obstacles at the waypoint times):")
        out.append("")
        for i in range(0, len(planner_figs), 3):
            row = planner_figs[i:i + 3]
            out.append("| " + " | ".join(lab for lab, _ in row) + " |")
            out.append("|" + "---|" * len(row))
            out.append("| " + " | ".join(f"![{scene} {lab}]({R.figure(f)})" for lab, f in row) + " |")
            out.append("")
    return out + [""]


def contour_section(R: Results, scene: str) -> list[str]:
    s = R.scenes[scene]
    out = []
    pts = s["expected"]["derived_checks"]["spot_values"]["points"]
    out += [f"**Spot values** (not in the paper: computed independently when the scene file was made, Monte Carlo "
            f"with 10⁶ samples; ours exact, Monte Carlo with {R.meta['spot_mc']} samples, 99 % interval):", "",
            "| x | t | obstacle | E[P] file | E[P] ours | Cantelli bound file | bound ours | MC file | MC ours [99 %] | agree |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for i, p in enumerate(pts):
        tid = f"spot--{scene}--{i}"
        r = R.risk(tid)
        ok = spot_consistent(R, [tid], s)
        for o in r["obstacles"]:
            f = p["per_obstacle"][o["id"]]
            mc = o["mc"]
            out.append(f"| ({', '.join(fmt_g(x, 3) for x in p['x'])}) | {fmt_g(p['t'], 3)} | {o['id']} | {fmt_g(f['E_P'], 6)} | {fmt_g(o['mean'], 6)} "
                       f"| {fmt_g(f['cantelli_bound'], 5) if f['cantelli_bound'] is not None else '– (E[P] > 0)'} | {fmt_g(o['bound'], 5)} "
                       f"| {fmt_g(f['mc_risk'], 4)} | {fmt_g(mc['estimate'], 4)} [{fmt_g(mc['lower'], 3)}, {fmt_g(mc['upper'], 3)}] | {'✓' if ok else '✗'} |")
    out.append("")
    if scene == "illustrative-1":
        e = s["expected"]
        r0 = R.risk(f"origin--{scene}")["obstacles"][0]
        out += [f"**Moments.** The paper prints E[ω²] = {e['E_P_paper'].split(' ')[0]} and E[ω⁴] = {e['E_P2_paper'].split(' ')[0]}; "
                f"ours (E[P] and E[P²] at the origin, exact) {r0['mean']:.10f} and {r0['second_moment']:.10f}.", ""]
        out += ["**Contour radii** (the scene file's radii of the inner approximation and of the true contour; "
                "at the first our Cantelli bound should equal Δ, at the second the true risk is Δ):", "",
                "| Δ | inner radius | our bound there | MC there | true radius | MC there [99 %] |", "|---|---|---|---|---|---|"]
        for r in e["derived_checks"]["contour_radii"]["radii"]:
            if r["Delta"] not in e["risk_levels_paper_text"]:
                continue
            ri, rt = R.risk(f"radius-inner--{scene}--{r['Delta']}")["obstacles"][0], R.risk(f"radius-true--{scene}--{r['Delta']}")["obstacles"][0]
            out.append(f"| {r['Delta']} | {r['inner_approx_radius']} | {ri['bound']:.8f} | {fmt_g(ri['mc']['estimate'], 3)} | {r['true_contour_radius']} "
                       f"| {fmt_g(rt['mc']['estimate'], 3)} [{fmt_g(rt['mc']['lower'], 3)}, {fmt_g(rt['mc']['upper'], 3)}] |")
        out.append("")
    return out


def planning_section(R: Results, scene: str) -> tuple[list[str], dict]:
    s = R.scenes[scene]
    dyn = is_dynamic(s)
    delta = delta_of(s)
    ctx: dict = {"delta": str(delta)}
    out = ["| planner | what | paper | ours | first plan | paper ÷ ours | solved | length | MC risk (Δ = "
           f"{delta}) | over Δ | certified | verify |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    figs = []
    for lab in R.labels(scene):
        what, k_static, k_dyn = PLANNERS[lab]
        p, ptxt = paper_time(s, k_dyn if dyn else k_static)
        sm = R.summary(scene, lab)
        stem = stem_of(scene, lab)
        plan_file = R.dir / "plans" / f"{stem}.json"
        if plan_file.is_file():
            v = R.verify(f"plan--{stem}")
            vtxt = "✓" if v["safe"] else "✗ " + describe_failure(v, short=True)
        else:
            vtxt = "no plan (seed 1)"
        figs.append((lab if plan_file.is_file() else f"{lab} (no plan: the tree only)", f"{stem}.svg"))
        name = lab if p is not None else f"*{lab}*"
        fail = f" ({', '.join(sm['fail_status'])}, median {fmt_s(sm['fail_time'])})" if sm["fail_status"] else ""
        out.append(f"| {name} | {what} | {ptxt} | {fmt_s(sm['time'])} | {fmt_s(sm['first'])} | {fmt_ratio(p, sm['time'])} "
                   f"| {sm['solved']}/{sm['runs']}{fail} | {fmt_g(sm['length'], 4)} | {fmt_g(sm['worst'], 3)} | {sm['over']}/{sm['solved']} "
                   f"| {sm['certified']}/{sm['solved']} | {vtxt} |")
        ctx[lab] = sm
    out.append("")
    # what the paper reports that no planner of ours answers
    extra = []
    rt = (s.get("expected") or {}).get("run_time_s") or {}
    for key, v in rt.items():
        if key == "per_edge_check":
            extra.append("one edge check takes " + ", ".join(f"{v[k]} s by {n}" for k, n in (("sos", "SOS"), ("monte_carlo", "Monte Carlo")) if k in v)
                         + " (compared with ours below)")
        elif not any(PLANNERS[lab][2 if dyn else 1] == key for lab in R.labels(scene)):
            extra.append(f"{PAPER_ONLY.get(key, key)} {v['paper']} s")
    if extra:
        out += [f"Also reported by the paper, without a counterpart row: {'; '.join(extra)}.", ""]
    # the authors' trajectory and the straight line
    out += ["**The certifier on given trajectories** (`riskplan verify --method both`; Monte Carlo along it: "
            f"{R.meta['traj_mc']} samples at each of the times listed, largest estimate per obstacle):", "",
            "| trajectory | Δ | verdict | smallest proven margin / first failure | MC risk along it (max) | Cantelli bound along it (max) |",
            "|---|---|---|---|---|---|"]
    notes = []
    for which, label in (("authors-tv-sos", "authors' time-varying SOS (as printed)"), ("straight-line", "straight start–goal line (control)")):
        if which == "authors-tv-sos" and not authors_global(s):
            continue
        v = R.verify_given(scene, which, delta)
        mc = R.traj_mc(scene, which)
        detail = f"margin {fmt_g(v['margin'], 3)}" if v["safe"] else describe_failure(v)
        where = (f"0 at all {mc['times']} times (99 % upper {fmt_g(mc['upper'], 3)})" if mc["worst"] == 0 else
                 f"{fmt_g(mc['worst'], 3)} at t = {mc['t']:.3f} ({mc['obstacle']}; 99 % [{fmt_g(mc['lower'], 3)}, {fmt_g(mc['upper'], 3)}]; {mc['times']} times)")
        out.append(f"| {label} | {delta} | {verdict_word(v)} | {detail} | {where} | {fmt_g(mc['bound'], 4)} |")
        if v["split"]:
            meta = load_json(R.dir / "trajectories" / f"{scene}--{which}.meta.json")
            notes.append(f"As printed, the pieces of the {label.split(' (')[0]} do not meet: they jump by {fmt_g(v['split'][1], 2)} "
                         f"at t = {v['split'][0]:g}, more than trajectory format v1 allows ({fmt_g(meta['tolerance'], 2)}, "
                         "docs/formats.md §2.3), so `riskplan verify` refuses the file as a whole; each printed piece "
                         "was verified on its own (a verdict on exactly the printed numbers).")
        if which == "authors-tv-sos":
            ctx["authors"] = v
            ctx["authors_mc"] = mc
            if not v["safe"]:
                ladder = []
                for dd in delta_ladder(delta)[1:]:
                    vv = R.verify_given(scene, which, dd)
                    ladder.append((dd, vv))
                    out.append(f"| ″ | {dd} | {verdict_word(vv)} | {'margin ' + fmt_g(vv['margin'], 3) if vv['safe'] else describe_failure(vv)} | ″ | |")
                ctx["authors_ladder"] = ladder
    out.append("")
    out += [f"{n}\n" for n in notes]
    ctx["figs"] = figs
    return out, ctx


def paper_edge_check(R: Results, kind: str) -> float:
    """The paper's per-edge check time (reported once, for Illustrative Example 3)."""
    try:
        return float(R.scenes["illustrative-3"]["expected"]["run_time_s"]["per_edge_check"][kind])
    except KeyError:
        die(f"{R.scenes['illustrative-3']['_file']}: expected.run_time_s.per_edge_check.{kind} missing")


def why_section(R: Results, scene: str, ctx: dict) -> list[str]:
    s = R.scenes[scene]
    bullets = []
    if s.get("start") is not None:
        bullets.append(WHY["platform"])
        dyn = is_dynamic(s)
        rt = (s.get("expected") or {}).get("run_time_s") or {}
        edge = rt.get("per_edge_check", {})
        pp = ctx.get("rrt-sos-paper")
        if pp and pp["edge"] is not None:
            bullets.append(WHY["edge_check"].format(paper_edge=f"{paper_edge_check(R, 'sos'):g} s", ours_edge=fmt_s(pp["edge"])))
        mc = ctx.get("mc-rrt")
        if mc:
            f = {"mc_worst": fmt_g(mc["worst"], 3), "delta": ctx["delta"], "mc_over": mc["over"], "mc_solved": mc["solved"],
                 "paper_mc_edge": f"{paper_edge_check(R, 'monte_carlo'):g} s", "ours_mc_edge": fmt_s(mc["edge"])}
            bullets.append((WHY["mc_rrt"] if "monte_carlo_rrt_feasible" in rt and not dyn else WHY["mc_rrt_dyn"]).format(**f))
        bullets.append(WHY["rrt_sos"])
        if "tv-sos" in ctx:
            bullets.append(WHY["tv_sos"].format(tv_ladder=ladder_text(ctx["tv-sos"]["seed1"])))
        if "moment" in ctx:
            bullets.append(WHY["standard_sos"].format(moment_ladder="piecewise linear: " + ladder_text(ctx["moment"]["seed1"], False)
                                                      + "; polynomial: " + ladder_text(ctx["moment-poly"]["seed1"], False)))
        if "authors" in ctx:
            v = ctx["authors"]
            if v["safe"]:
                bullets.append(WHY["authors_ok"].format(delta=ctx["delta"], authors_margin=fmt_g(v["margin"], 3)))
            else:
                cert = [dd for dd, vv in ctx.get("authors_ladder", []) if vv["safe"]]
                lad = (f"It is certified at Δ = {cert[0]} (both methods)." if cert else
                       f"It is not certified at any of Δ = {', '.join(str(dd) for dd, _ in ctx.get('authors_ladder', []))} either.")
                mc = ctx["authors_mc"]
                if mc["upper"] <= float(ctx["delta"]) / 10:
                    lad += (f" Monte Carlo puts its true risk far below Δ (estimate at most {fmt_g(mc['worst'], 3)}, 99 % upper bound "
                            f"{fmt_g(mc['upper'], 3)} at the worst of {mc['times']} times) while the Cantelli bound reaches "
                            f"{fmt_g(mc['bound'], 4)}: the bound, not the true risk, is what touches Δ.")
                bullets.append(WHY["authors_rejected"].format(delta=ctx["delta"], authors_failure=describe_failure(v), authors_ladder=lad))
    if scene in WHY:
        extra = {}
        if scene == "illustrative-3":
            extra["mc_opt"] = paper_time(s, "monte_carlo_rrt_optimal")[1].replace("paper: ", "")
        bullets.append(WHY[scene].format(**extra))
    return ["**Where we differ, and why.**", ""] + [f"- {b}" for b in bullets] + [""]


def cmd_report(a) -> None:
    scenes = load_scenes(Path(a.scenes))
    for scene, _, _ in EXPERIMENTS:
        if scene not in scenes:
            die(f"{a.scenes}/{scene}.json: missing")
    R = Results(scenes, Path(a.results), Path(a.figures))
    lines = header(R) + summary_table(R)
    for scene, title, where in EXPERIMENTS:
        s = scenes[scene]
        lines += [f"## {title}", "", f"Paper: {where}. Scene: `scenes/{scene}.json`. {s.get('description', '')}".rstrip(), ""]
        if s.get("start") is None:
            lines += contour_section(R, scene)
            lines += figure_block(R, scene, None)
            lines += why_section(R, scene, {})
        else:
            body, ctx = planning_section(R, scene)
            lines += body
            lines += figure_block(R, scene, ctx["figs"])
            lines += why_section(R, scene, ctx)
    lines += ["## Raw results", "",
              "`docs/reproduction/`: `run.json` (this run's facts), `bench.jsonl` (every benchmark run: seed, status, "
              "stats, audit) and `bench-table.md` (riskplan's own table of it), `plans/` (seed-1 plans), `verify/` "
              "(verify reports), `risk/` (risk queries), `trajectories/` (the authors' trajectories and straight lines "
              "as trajectory files), `*-tasks.tsv` (the queries run), `log.txt` (every command and its messages). "
              "Figures: `docs/figures/repro/`.", ""]
    Path(a.out).write_text("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("--scenes", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--spot-mc", type=int, required=True)
    p.add_argument("--traj-mc", type=int, required=True)
    p.add_argument("--traj-times", type=int, required=True)
    p = sub.add_parser("plans")
    p.add_argument("--bench", required=True)
    p = sub.add_parser("collect")
    p.add_argument("--raw", required=True)
    p.add_argument("--out", required=True)
    p = sub.add_parser("meta")
    p.add_argument("--out", required=True)
    p = sub.add_parser("report")
    p.add_argument("--scenes", required=True)
    p.add_argument("--results", required=True)
    p.add_argument("--figures", required=True)
    p.add_argument("--out", required=True)
    a = ap.parse_args()
    {"prepare": cmd_prepare, "plans": cmd_plans, "collect": cmd_collect, "meta": cmd_meta, "report": cmd_report}[a.cmd](a)


if __name__ == "__main__":
    main()
