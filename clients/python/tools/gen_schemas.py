#!/usr/bin/env python3
"""Generates proto/schemas/*.schema.json (JSON Schema draft 2020-12) from the message
descriptions of proto/README.md.

Each schema is self-contained (shared definitions such as the scene and trajectory
formats are copied into its `$defs`), so any validator can use one file alone.

    python3 clients/python/tools/gen_schemas.py            # write the files
    python3 clients/python/tools/gen_schemas.py --check    # exit 1 if a file is stale

Conventions:
- Requests (and the embedded scene v1 / trajectory v1 formats, whose specification says
  so) have `additionalProperties: false`: the README says unknown fields are errors.
  Replies are open (`additionalProperties` allowed) so that clients stay compatible
  with servers that add fields.
- The schemas encode the types and the value ranges and limits the README states.
  A payload that fails a *type* (wrong JSON type, unknown field, missing field) is
  answered `malformed_payload` by the server; one that fails a *range* (Δ ∉ (0,1),
  time limit ≤ 0, ...) is answered `invalid_request`, and one over a *limit*
  (points, grid side) `limit_exceeded`.
"""
from __future__ import annotations

import copy
import json
import re
import sys
from pathlib import Path

DIALECT = "https://json-schema.org/draft/2020-12/schema"
BASE = "https://riskplan.invalid/proto/v1/"

ROOT = Path(__file__).resolve().parents[3]
OUT = ROOT / "proto" / "schemas"

def planner_names() -> list[str]:
    """The planners' wire names, in `PlannerKind::ALL` order, read from the one place
    that names them (`PlannerKind::as_str` in crates/riskplan-plan/src/lib.rs): a new planner reaches
    the schemas when they are regenerated, and `--check` fails until they are."""
    src = (ROOT / "crates" / "riskplan-plan" / "src" / "lib.rs").read_text(encoding="utf-8")
    body = src[src.index("pub fn as_str(self) -> &'static str {"):]
    body = body[: body.index("\n    }\n")]
    names = re.findall(r'PlannerKind::\w+ => "([a-z0-9-]+)"', body)
    if not names:
        raise SystemExit("no planner names found in crates/riskplan-plan/src/lib.rs (PlannerKind::as_str)")
    return names


PLANNERS = planner_names()

U64 = {"type": "integer", "minimum": 0, "maximum": 18446744073709551615}
NUMBER = {"type": "number"}
VECTOR = {"type": "array", "items": {"type": "number"}, "minItems": 1, "description": "a point: one coordinate per dimension of the scene"}
SCENE_NAME = {
    "type": "string",
    "pattern": "^[A-Za-z0-9_.\\-]{1,128}$",
    "description": "a scene name: 1-128 characters from A-Z a-z 0-9 _ - .",
}
ERROR_CODES = [
    "malformed_payload",
    "unsupported_encoding",
    "payload_too_large",
    "limit_exceeded",
    "invalid_scene_name",
    "unknown_scene",
    "invalid_scene",
    "invalid_request",
    "invalid_trajectory",
    "outside_workspace",
    "unsafe_endpoint",
    "no_plan",
    "busy",
    "deadline_exceeded",
    "unavailable",
    "stale_revision",
    "internal",
]

SEGMENT = {
    "type": "object",
    "required": ["from", "to"],
    "additionalProperties": False,
    "properties": {
        "from": VECTOR,
        "to": VECTOR,
        "t0": {"type": "number", "description": "default: the horizon's start"},
        "t1": {"type": "number", "description": "default: the horizon's end"},
    },
}

DEADLINE_MS = {"type": "integer", "minimum": 0, "description": "milliseconds from the request's arrival (queue time included) within which the server must answer, else the error deadline_exceeded; default and cap: the server's --max-job-seconds"}

# ---------------------------------------------------------------------------------
# Shared definitions
# ---------------------------------------------------------------------------------

DEFS = {
    "exact_number": {
        "description": "a number of a scene file, read exactly: a JSON number (read through its shortest decimal text, so 0.3 is 3/10) or a string holding a decimal or a fraction such as \"37/300\"",
        "anyOf": [
            {"type": "number"},
            {
                "type": "string",
                "pattern": "^\\s*[+-]?([0-9]+(\\.[0-9]*)?|\\.[0-9]+)([eE][+-]?[0-9]+)?\\s*(/\\s*[+-]?([0-9]+(\\.[0-9]*)?|\\.[0-9]+)([eE][+-]?[0-9]+)?\\s*)?$",
            },
        ],
    },
    "distribution": {
        "description": "an uncertain parameter's distribution (scene format v1), tagged by `dist`",
        "type": "object",
        "required": ["dist"],
        "properties": {"dist": {"enum": ["uniform", "normal", "beta", "gamma", "exponential", "laplace", "discrete", "moments"]}},
        "oneOf": [
            {
                "properties": {"dist": {"const": "uniform"}, "low": {"$ref": "#/$defs/exact_number"}, "high": {"$ref": "#/$defs/exact_number"}},
                "required": ["dist", "low", "high"],
                "additionalProperties": False,
            },
            {
                "properties": {"dist": {"const": "normal"}, "mean": {"$ref": "#/$defs/exact_number"}, "std": {"$ref": "#/$defs/exact_number", "description": "standard deviation, not variance"}},
                "required": ["dist", "mean", "std"],
                "additionalProperties": False,
            },
            {
                "properties": {
                    "dist": {"const": "beta"},
                    "alpha": {"$ref": "#/$defs/exact_number"},
                    "beta": {"$ref": "#/$defs/exact_number"},
                    "low": {"$ref": "#/$defs/exact_number", "description": "default 0"},
                    "high": {"$ref": "#/$defs/exact_number", "description": "default 1"},
                },
                "required": ["dist", "alpha", "beta"],
                "additionalProperties": False,
            },
            {
                "properties": {"dist": {"const": "gamma"}, "shape": {"$ref": "#/$defs/exact_number"}, "scale": {"$ref": "#/$defs/exact_number"}},
                "required": ["dist", "shape", "scale"],
                "additionalProperties": False,
            },
            {
                "properties": {"dist": {"const": "exponential"}, "rate": {"$ref": "#/$defs/exact_number"}},
                "required": ["dist", "rate"],
                "additionalProperties": False,
            },
            {
                "properties": {"dist": {"const": "laplace"}, "mean": {"$ref": "#/$defs/exact_number"}, "scale": {"$ref": "#/$defs/exact_number"}},
                "required": ["dist", "mean", "scale"],
                "additionalProperties": False,
            },
            {
                "properties": {
                    "dist": {"const": "discrete"},
                    "values": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1},
                    "weights": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "description": "probabilities, summing to 1"},
                },
                "required": ["dist", "values", "weights"],
                "additionalProperties": False,
            },
            {
                "properties": {
                    "dist": {"const": "moments"},
                    "raw": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "description": "E[w^1], E[w^2], ..."},
                },
                "required": ["dist", "raw"],
                "additionalProperties": False,
            },
        ],
    },
    "params": {
        "description": "uncertain parameters by name (every identifier of a polynomial other than x1..x{dim} and t)",
        "type": "object",
        "propertyNames": {"pattern": "^[A-Za-z_][A-Za-z0-9_]*$"},
        "additionalProperties": {"$ref": "#/$defs/distribution"},
    },
    "polynomial": {
        "type": "string",
        "minLength": 1,
        "description": "polynomial text: numbers (0.3, 1e-3, 37/300), identifiers (x1..x{dim}, t, parameters), + - * ^, parentheses, unary minus; ^ takes a non-negative integer literal; / divides by a numeric constant only. The obstacle is the set where poly >= 0.",
    },
    "pedestrian": {
        "description": "a pedestrian (docs/formats.md §1.5.1): a moving disk/ball predicted at `time` with isotropic Gaussian errors of position and velocity and a radius with a bounded support; certified by its Gaussian tail bound (docs/design.md §3.11)",
        "type": "object",
        "required": ["position", "velocity", "time", "radius"],
        "additionalProperties": False,
        "properties": {
            "position": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "maxItems": 8},
            "velocity": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "maxItems": 8},
            "time": {"$ref": "#/$defs/exact_number"},
            "radius": {"oneOf": [{"$ref": "#/$defs/exact_number"}, {"$ref": "#/$defs/distribution"}], "description": "a number > 0, or a distribution with a bounded support (uniform, beta, discrete)"},
            "position_std": {"$ref": "#/$defs/exact_number"},
            "velocity_std": {"$ref": "#/$defs/exact_number"},
        },
    },
    "obstacle_id": {
        "type": "string",
        "minLength": 1,
        "description": "an obstacle id, unique in its scene (it is also a key-expression chunk in riskplan/scenes/<scene>/obstacles/<id>, so it should avoid / * $ ? #)",
    },
    "scene": {
        "description": "a scene, scene format v1 (docs/formats.md); unknown top-level fields are errors. Limits: dim <= 8, degree <= 8 in (x, t) and per parameter, <= 500 terms per obstacle, <= 512 obstacles, and the expansion and contour-work limits of docs/formats.md §1.7.",
        "type": "object",
        "required": ["format", "name", "dim", "workspace", "horizon", "risk", "obstacles"],
        "additionalProperties": False,
        "properties": {
            "format": {"const": "riskplan-scene/1"},
            "name": {"type": "string"},
            "description": {"type": "string"},
            "dim": {"type": "integer", "minimum": 1, "maximum": 8},
            "workspace": {
                "type": "object",
                "required": ["lower", "upper"],
                "additionalProperties": False,
                "properties": {
                    "lower": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "maxItems": 8},
                    "upper": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "maxItems": 8},
                },
            },
            "horizon": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 2, "maxItems": 2, "description": "[t0, tf]"},
            "risk": {"$ref": "#/$defs/exact_number", "description": "Δ in (0, 1): the bound on the probability of collision with each obstacle at every instant"},
            "risk_levels": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}},
            "params": {"$ref": "#/$defs/params"},
            "obstacles": {
                "type": "array",
                "maxItems": 512,
                "items": {
                    "oneOf": [
                        {
                            "type": "object",
                            "required": ["id", "poly"],
                            "additionalProperties": False,
                            "properties": {"id": {"$ref": "#/$defs/obstacle_id"}, "poly": {"$ref": "#/$defs/polynomial"}},
                        },
                        {
                            "type": "object",
                            "required": ["id", "pedestrian"],
                            "additionalProperties": False,
                            "properties": {"id": {"$ref": "#/$defs/obstacle_id"}, "pedestrian": {"$ref": "#/$defs/pedestrian"}},
                        },
                    ],
                },
            },
            "robot_radius": {"$ref": "#/$defs/exact_number", "description": "the robot's body: the radius of the disk/ball around its reference point (>= 0, below half the workspace's smallest side); every obstacle is grown by it (docs/design.md §3.12). Default 0"},
            "start": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "maxItems": 8, "description": "x(t0); absent in contour-only scenes"},
            "goal": {"type": "array", "items": {"$ref": "#/$defs/exact_number"}, "minItems": 1, "maxItems": 8, "description": "x(tf); absent in contour-only scenes"},
            "planner": {"description": "free form: planner parameters (the rrt_sos block is read by the planner)"},
            "expected": {"description": "free form: what the paper reports"},
            "notes": {"type": "array", "items": {"type": "string"}},
        },
    },
    "piece": {
        "description": "one polynomial piece x_d(t) = Σ_k coeffs[d][k]·t^k on [t0, t1], in absolute time",
        "type": "object",
        "required": ["t0", "t1", "coeffs"],
        "additionalProperties": False,
        "properties": {
            "t0": NUMBER,
            "t1": NUMBER,
            "coeffs": {
                "type": "array",
                "minItems": 1,
                "description": "one row per dimension; row d holds the coefficients of t^0, t^1, ... (degree <= 8)",
                "items": {"type": "array", "items": {"type": "number"}, "minItems": 1, "maxItems": 9},
            },
        },
    },
    "trajectory": {
        "description": "a trajectory, format v1: contiguous pieces (at most 10 000). The optional fields of a plan's output (planner, certified, stats, revision, scene, risk) may be present, so a plan_reply can be sent back as it is.",
        "type": "object",
        "required": ["format", "pieces"],
        "additionalProperties": False,
        "properties": {
            "format": {"const": "riskplan-trajectory/1"},
            "pieces": {"type": "array", "minItems": 1, "maxItems": 10000, "items": {"$ref": "#/$defs/piece"}},
            "planner": {"type": "string"},
            "certified": {"type": "boolean"},
            "stats": {"type": "object"},
            "revision": U64,
            "scene": {"type": "string"},
            "risk": NUMBER,
        },
    },
    "method": {"enum": ["exact", "sos", "both"]},
    "delta": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1, "description": "risk level Δ in (0, 1); default: the scene's"},
    "status": {"enum": ["safe", "unsafe", "undecided"]},
    "witness": {
        "description": "a time at which a constraint is <= 0 (absolute time) and the constraint's value there",
        "anyOf": [
            {"type": "null"},
            {"type": "object", "required": ["t", "value"], "properties": {"t": NUMBER, "value": NUMBER}},
        ],
    },
    "method_report": {
        "type": "object",
        "required": ["status"],
        "properties": {
            "status": {"$ref": "#/$defs/status"},
            "margin": {"type": ["number", "null"]},
            "witness": {"$ref": "#/$defs/witness"},
            "reason": {"type": ["string", "null"], "description": "why undecided (absent or null otherwise)"},
        },
    },
    "constraint_report": {
        "type": "object",
        "required": ["name", "status", "method"],
        "properties": {
            "name": {"enum": ["mean", "cantelli"], "description": "mean: −E[P] > 0; cantelli: E[P]² − (1−Δ)E[P²] > 0"},
            "status": {"$ref": "#/$defs/status"},
            "margin": {"type": ["number", "null"], "description": "proven lower bound on the constraint's minimum over the piece (safe), or the witness value (unsafe)"},
            "witness": {"$ref": "#/$defs/witness"},
            "method": {"type": "string"},
            "reason": {"type": ["string", "null"], "description": "why undecided (absent or null otherwise)"},
            "methods": {
                "type": ["array", "null"],
                "description": "per method, with method both: [name, report] pairs (absent or null otherwise)",
                "items": {"type": "array", "prefixItems": [{"type": "string"}, {"$ref": "#/$defs/method_report"}], "minItems": 2, "maxItems": 2},
            },
        },
    },
    "piece_report": {
        "type": "object",
        "required": ["t0", "t1", "safe", "workspace", "obstacles"],
        "properties": {
            "t0": NUMBER,
            "t1": NUMBER,
            "safe": {"type": "boolean"},
            "workspace": {
                "type": "object",
                "required": ["status"],
                "properties": {"status": {"$ref": "#/$defs/status"}, "witness": {"$ref": "#/$defs/witness"}},
            },
            "obstacles": {
                "type": "array",
                "items": {
                    "type": "object",
                    "required": ["id", "status", "constraints"],
                    "properties": {
                        "id": {"type": "string"},
                        "status": {"$ref": "#/$defs/status"},
                        "constraints": {"type": "array", "items": {"$ref": "#/$defs/constraint_report"}},
                    },
                },
            },
        },
    },
    "counter": {
        "type": "object",
        "required": ["served", "failed"],
        "properties": {"served": U64, "failed": U64},
    },
}

# which definitions each definition uses (to copy only what a schema needs)
def _refs(node, acc):
    if isinstance(node, dict):
        for k, v in node.items():
            if k == "$ref" and isinstance(v, str) and v.startswith("#/$defs/"):
                name = v[len("#/$defs/"):]
                if name not in acc:
                    acc.add(name)
                    _refs(DEFS[name], acc)
            else:
                _refs(v, acc)
    elif isinstance(node, list):
        for v in node:
            _refs(v, acc)
    return acc


def ref(name):
    return {"$ref": f"#/$defs/{name}"}


# ---------------------------------------------------------------------------------
# Messages
# ---------------------------------------------------------------------------------

CHANGE_PUT = {
    "type": "object",
    "required": ["op", "id", "poly"],
    "additionalProperties": False,
    "properties": {
        "op": {"const": "put"},
        "id": ref("obstacle_id"),
        "poly": ref("polynomial"),
        "params": {**ref("params"), "description": "declares or replaces the parameters the obstacle introduces (scene format parameter syntax)"},
    },
}
CHANGE_PEDESTRIAN = {
    "type": "object",
    "required": ["op", "id", "pedestrian"],
    "additionalProperties": False,
    "properties": {"op": {"const": "put"}, "id": ref("obstacle_id"), "pedestrian": ref("pedestrian")},
}
CHANGE_DELETE = {
    "type": "object",
    "required": ["op", "id"],
    "additionalProperties": False,
    "properties": {"op": {"const": "delete"}, "id": ref("obstacle_id")},
}

MESSAGES = {
    "apply_request": {
        "title": "apply_request",
        "description": "get on riskplan/scenes/<scene>/apply. Either a whole scene (replace it, creating it if needed) or a list of obstacle changes applied atomically, in order, to an existing scene. The reply (apply_reply) is sent after the update is persisted.",
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "scene": ref("scene"),
            "changes": {"type": "array", "maxItems": 512, "items": {"oneOf": [CHANGE_PUT, CHANGE_PEDESTRIAN, CHANGE_DELETE]}},
            "deadline_ms": DEADLINE_MS,
        },
        "oneOf": [{"required": ["scene"]}, {"required": ["changes"]}],
    },
    "apply_reply": {
        "title": "apply_reply",
        "description": "reply to apply_request, sent after the update is persisted",
        "type": "object",
        "required": ["scene", "revision"],
        "properties": {"scene": SCENE_NAME, "revision": U64},
    },
    "obstacle_put": {
        "title": "obstacle_put",
        "description": "put on riskplan/scenes/<scene>/obstacles/<id>: add or replace one obstacle (no reply; a put that fails validation is counted in status requests.put.failed)",
        "type": "object",
        "required": ["poly"],
        "additionalProperties": False,
        "properties": {"poly": ref("polynomial"), "params": ref("params")},
    },
    "plan_request": {
        "title": "plan_request",
        "description": "get on riskplan/scenes/<scene>/plan. Every field is optional. Defaults: the scene's start and goal, rrt-sos, 10 s (capped by the server's --max-plan-seconds), seed 1, the scene's planner block (max_speed, max_accel; rrt_sos for rrt-sos-paper), the piece ladder, no improve, the scene's Δ, exact, smoothing on, per-obstacle risk.",
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "start": VECTOR,
            "goal": VECTOR,
            "planner": {"enum": PLANNERS},
            "time_limit": {"type": "number", "exclusiveMinimum": 0, "description": "seconds (> 0); the server caps it at --max-plan-seconds"},
            "seed": U64,
            "pieces": {"type": "integer", "minimum": 1, "maximum": 1000, "description": "pieces of the time-layered planner (forces it; default: the ladder 1, 2, 4, … 32); for tv-sos the first rung's pieces (1 to 16; default: the scene's planner.time_varying_sos.pieces, else 2); for moment the first rung's pieces (1 to 8; default: the scene's planner.standard_sos.piecewise_linear_pieces, else 2)"},
            "improve": {"type": "boolean", "description": "the improve step (rrt-sos-paper on static scenes only)"},
            "delta": ref("delta"),
            "certifier": ref("method"),
            "max_speed": {"type": "number", "exclusiveMinimum": 0, "description": "speed limit, workspace units per time unit (default: the scene's planner.max_speed, else none)"},
            "max_accel": {"type": "number", "exclusiveMinimum": 0, "description": "acceleration limit of the corner blends (default: the scene's planner.max_accel, else none)"},
            "smooth": {"type": "boolean", "description": "shortcut and blend the path into C¹ pieces of degree ≤ 2, each certified (default true; rrt-sos and mc-rrt)"},
            "bound": {"enum": ["auto", "cantelli"], "description": "which risk bounds may prove safety: auto (Cantelli, then zero risk from bounded support and shifted moment bounds of orders 4, 6, 8 on sub-intervals; docs/design.md §3.7–§3.10, §5.13) or cantelli (the paper's eq. (10), (12)). Default: the scene's planner.bound, else auto"},
            "risk_mode": {"enum": ["per-obstacle", "joint", "joint-weighted", "trajectory"], "description": "per-obstacle (the paper's: each obstacle ≤ Δ at each instant); joint: any obstacle ≤ Δ at each instant, Δ split evenly (Boole); joint-weighted: split by need at start and goal, then by closeness to the start–goal line. The Δᵢ used are in stats.risk_allocation. trajectory: the probability of meeting any obstacle at any time along the plan ≤ Δ (docs/design.md 5.14; rrt-sos budgets its search; stats.whole_path_risk)."},
            "t_now": {"type": "number", "description": "a receding-horizon request (docs/design.md §6.9): the current time, inside the scene's horizon; with it position, horizon and goal are required and start is not allowed"},
            "position": {**VECTOR, "description": "the robot's position at t_now (strictly inside every Δ-contour)"},
            "velocity": {**VECTOR, "description": "the robot's velocity at t_now (default: at rest); its speed at most max_speed"},
            "horizon": {"type": "number", "exclusiveMinimum": 0, "description": "the window H: the plan covers [t_now, t_now + H], cut at the scene's horizon"},
            "robot_id": {"type": "string", "pattern": "^[A-Za-z0-9._-]{1,128}$", "description": "the server keeps this robot's last plan and continues from it (warm start)"},
            "warm_start": {"type": "array", "minItems": 1, "maxItems": 10000, "items": ref("piece"), "description": "the previous plan's pieces to continue from (instead of the one kept per robot_id)"},
            "robot_radius": {"type": "number", "minimum": 0, "description": "the robot's body radius (default: the scene's robot_radius, else 0): every obstacle grown by it (docs/design.md §3.12)"},
        },
    },
    "plan_reply": {
        "title": "plan_reply",
        "description": "reply to plan_request: a trajectory (format v1) with its provenance",
        "type": "object",
        "required": ["format", "pieces", "planner", "certified", "stats", "revision", "scene", "risk"],
        "properties": {
            "format": {"const": "riskplan-trajectory/1"},
            "pieces": {"type": "array", "minItems": 1, "items": ref("piece")},
            "planner": {"enum": PLANNERS},
            "certified": {"type": "boolean", "description": "every piece proven safe (always false for mc-rrt)"},
            "stats": {
                "type": "object",
                "required": ["planning_time_s", "iterations", "edges_checked"],
                "properties": {
                    "planning_time_s": {"type": "number", "minimum": 0},
                    "iterations": U64,
                    "edges_checked": U64,
                    "pieces": {"type": ["integer", "null"], "description": "pieces of the layered planner's rung that succeeded"},
                    "smoothing": {"type": ["object", "null"], "description": "shortcut and blend counts: waypoints_before, waypoints_after, corners_blended, corners_stopped, corners_sharp, accel_violations; and the wall times (seconds) of the random shortcuts (shortcut_seconds, every candidate path's included), the vertex reduction (reduction_seconds) and the corner blends (blend_seconds), parts of improve_time_s"},
                    "risk_allocation": {"type": ["array", "null"], "items": {"type": "array", "prefixItems": [{"type": "string"}, {"type": "number"}]}, "description": "[obstacle id, Δᵢ] per obstacle in a joint risk mode"},
                    "sdp": {"type": ["object", "null"], "description": "tv-sos, moment, moment-poly (null for the others): sizes of the last SDP built (variables, rows, psd_cones, largest_psd) and solver totals (solves, ipm_iterations, solver_time_s, setup_time_s)"},
                    "ladder": {"type": "array", "items": {"type": "object"}, "description": "tv-sos, moment, moment-poly (empty for the others): the retry ladder's steps (pieces, seed, eta, iterations, dirac_gap, from_rrt, outcome)"},
                    "average_risk": {"type": ["array", "null"], "items": {"type": "array", "prefixItems": [{"type": "string"}, {"type": "number"}]}, "description": "moment, moment-poly: [obstacle id, average-risk bound] per obstacle: the largest Cantelli bound of the time-averaged moments over the pieces (a weak guarantee; the plan itself is certified per instant)"},
                    "final_check": {
                        "type": ["object", "null"],
                        "description": "certified plans: the final check of the whole trajectory by the verify path before it is called certified (docs/design.md §5.12); null for uncertified planners",
                        "required": ["seconds", "pieces", "disagreements"],
                        "additionalProperties": False,
                        "properties": {
                            "seconds": {"type": "number", "minimum": 0, "description": "wall time of the final check(s), included in planning_time_s"},
                            "pieces": {"type": "integer", "minimum": 0},
                            "disagreements": {"type": "integer", "minimum": 0, "description": "trajectories the planner's fast edge check accepted and the final check rejected: each an internal error (a bug), logged; the plan was then made again without the fast path"},
                            "invalid": {"type": "integer", "minimum": 0, "description": "trajectories the planner returned that the final check found not valid (pieces that do not meet, outside the horizon, ...): each an internal error (a bug of its post-processing), logged; the plan was then made again without smoothing"},
                            "whole_path_seconds": {"type": "number", "minimum": 0, "description": "wall time of the whole-path bound (stats.whole_path_risk), included in seconds"},
                            "verify_seconds": {"type": "number", "minimum": 0, "description": "wall time of the verify path alone, included in seconds; on crowded scenes the whole-path bound runs beside it, and seconds - verify_seconds is the wait for that bound"},
                        },
                    },
                    "whole_path_risk": {"type": ["number", "null"], "minimum": 0, "maximum": 1, "description": "certified plans: P(the plan meets some obstacle at some time) <= this, the parameters drawn once (docs/design.md 5.14), from the final check; absent when the deadline left no time for it and, outside trajectory mode, for receding plans and scenes with a parameter whose distribution function cannot be enclosed (a scale whose inverse overflows); in trajectory mode <= Δ"},
                },
            },
            "revision": U64,
            "scene": {"type": "string"},
            "risk": {"type": "number", "description": "Δ used"},
        },
    },
    "verify_request": {
        "title": "verify_request",
        "description": "get on riskplan/scenes/<scene>/verify: a trajectory (format v1, up to 200 000 pieces), one straight segment (default over the scene's horizon), or a batch of up to 200 000 segments, each verified on its own. Payload up to 32 MiB (other requests: 1 MiB).",
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "trajectory": ref("trajectory"),
            "segment": SEGMENT,
            "segments": {"type": "array", "minItems": 1, "maxItems": 200000, "items": SEGMENT, "description": "a batch: each segment verified on its own; the reply lists the indices of those not proven safe in `not_safe_segments`"},
            "method": ref("method"),
            "delta": ref("delta"),
            "bound": {"enum": ["auto", "cantelli"], "description": "which bounds may prove a piece (default auto); with auto each obstacle report lists under `bounds` which bound proved which part of the piece"},
            "summary": {"type": "boolean", "description": "true: `pieces` in the reply holds only the first piece (or segment) that is not safe (none when safe); no report is built for the others"},
            "whole_path": {"type": "boolean", "description": "true: the reply's `whole_path_risk` bounds the probability of meeting any obstacle at any time of the trajectory (the parameters drawn once), beyond the per-instant risk; a trajectory of at most 2000 pieces or one segment, not a `segments` batch"},
            "deadline_ms": DEADLINE_MS,
        },
        "oneOf": [{"required": ["trajectory"]}, {"required": ["segment"]}, {"required": ["segments"]}],
    },
    "verify_reply": {
        "title": "verify_reply",
        "description": "reply to verify_request: the report of `riskplan verify`, plus the scene revision",
        "type": "object",
        "required": ["safe", "method", "risk", "pieces", "revision"],
        "properties": {
            "safe": {"type": "boolean", "description": "every piece certified safe (undecided counts as not safe)"},
            "method": ref("method"),
            "risk": {"type": "number", "description": "Δ used"},
            "pieces": {"type": "array", "items": ref("piece_report"), "description": "one report per piece (or segment), or with `summary` only the first not safe"},
            "revision": U64,
            "checked": {**U64, "description": "pieces (or segments) decided"},
            "not_safe": {**U64, "description": "how many of them are not proven safe"},
            "first_not_safe": {"type": ["integer", "null"], "minimum": 0, "description": "index of the first piece (or segment) not proven safe"},
            "not_safe_segments": {"type": "array", "items": U64, "description": "for a `segments` batch, the index of every segment not proven safe (empty otherwise)"},
            "whole_path_risk": {
                "type": ["object", "null"],
                "description": "with `whole_path`: P(the trajectory meets some obstacle at some time) <= bound, the parameters drawn once (docs/design.md 5.14); the sum over the obstacles of their bounds",
                "required": ["bound", "obstacles"],
                "properties": {
                    "bound": {"type": "number", "minimum": 0, "maximum": 1},
                    "obstacles": {"type": "array", "items": {
                        "type": "object",
                        "required": ["id", "bound", "how", "pieces"],
                        "properties": {
                            "id": {"type": "string"},
                            "bound": {"type": "number", "minimum": 0, "maximum": 1, "description": "P(the trajectory meets this obstacle at some time) <= bound"},
                            "how": {"enum": ["partition", "pooled", "sum"], "description": "partition: the parameter space partitioned over every piece at once (uniform, normal, discrete, exponential, Laplace, integer-shape beta and gamma parameters); pooled: one moment envelope over every piece; sum: the pieces' moment bounds added up"},
                            "pieces": {"type": "array", "items": {"type": "number", "minimum": 0, "maximum": 1}, "description": "each piece's own bound, in order"},
                        },
                    }},
                },
            },
        },
    },
    "risk_request": {
        "title": "risk_request",
        "description": "get on riskplan/scenes/<scene>/risk: risk bounds at points, or on an N×N grid over the first two axes (other coordinates at `lower`), at one time (default: the horizon's start)",
        "type": "object",
        "additionalProperties": False,
        "properties": {
            "points": {"type": "array", "maxItems": 100000, "items": VECTOR, "description": "at most 100 000 points"},
            "grid": {
                "type": "object",
                "required": ["lower", "upper", "n"],
                "additionalProperties": False,
                "properties": {
                    "lower": VECTOR,
                    "upper": VECTOR,
                    "n": {"type": "integer", "minimum": 2, "maximum": 316, "description": "points per side (grid side <= 316, so that n^2 <= 100 000 points)"},
                },
            },
            "time": {"type": "number"},
            "bound": {"enum": ["auto", "cantelli"], "description": "auto (default): `bounds` and `obstacles` hold the best bound at each point; cantelli: Cantelli's."},
            "every_bound": {"type": "boolean", "description": "true: the reply's `by_bound` lists every bound (cantelli, support, moment4/6/8) per obstacle and point (default false: six numbers per point and obstacle make large replies)"},
            "deadline_ms": DEADLINE_MS,
        },
        "oneOf": [{"required": ["points"]}, {"required": ["grid"]}],
    },
    "risk_reply": {
        "title": "risk_reply",
        "description": "reply to risk_request. Bounds (floating point, for displays) one per point: the best bound allowed by `bound` per obstacle (`obstacles`), its max over obstacles (`bounds`), and every bound per obstacle (`by_bound`).",
        "type": "object",
        "required": ["revision", "time", "points", "bounds", "obstacles"],
        "properties": {
            "revision": U64,
            "time": NUMBER,
            "points": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
            "bounds": {"type": "array", "items": {"type": "number"}},
            "obstacles": {"type": "object", "additionalProperties": {"type": "array", "items": {"type": "number"}}},
        },
    },
    "scene_reply": {
        "title": "scene_reply",
        "description": "reply to a get on riskplan/scenes/<scene>",
        "type": "object",
        "required": ["name", "revision", "scene"],
        "properties": {"name": SCENE_NAME, "revision": U64, "scene": ref("scene")},
    },
    "status_reply": {
        "title": "status_reply",
        "description": "reply to a get on riskplan/status",
        "type": "object",
        "required": ["uptime_s", "scenes", "cache", "queue", "requests"],
        "properties": {
            "role": {"enum": ["primary", "replica"], "description": "primary: takes writes (a single server is one); replica: answers reads only and follows a primary (deploy/cluster)"},
            "state": {"enum": ["loading", "ready"], "description": "loading until the stored scenes and --preload files are in (every request but status and echo is answered unavailable), ready after"},
            "server_id": {"type": "string", "pattern": "^[0-9A-Za-z_-]{0,64}$", "description": "the server's id: its liveliness token riskplan/_servers/<id>/<role> and its own keys riskplan/@<id>/... (proto/README.md, Discovery)"},
            "uptime_s": {"type": "number", "minimum": 0},
            "scenes": {
                "type": "array",
                "items": {
                    "type": "object",
                    "required": ["name", "revision", "obstacles"],
                    "properties": {"name": SCENE_NAME, "revision": U64, "obstacles": {**U64, "description": "number of obstacles"}},
                },
            },
            "cache": {"type": "object", "required": ["entries", "hits", "misses"], "properties": {"entries": U64, "hits": U64, "misses": U64}},
            "queue": {
                "type": "object",
                "required": ["depth", "running", "workers", "capacity"],
                "properties": {"depth": U64, "running": U64, "workers": U64, "capacity": U64},
            },
            "requests": {"type": "object", "description": "per request kind (e.g. put)", "additionalProperties": ref("counter")},
            "problems": {"type": "array", "items": {"type": "string"}, "description": "problems met loading the stored scenes: files moved to <data>/quarantine/ and why"},
        },
    },
    "error": {
        "title": "error",
        "description": "the payload of every reply_err",
        "type": "object",
        "required": ["code", "message", "field"],
        "properties": {
            "code": {"enum": ERROR_CODES},
            "message": {"type": "string"},
            "field": {"type": ["string", "null"], "description": "a JSON path of the field at fault, or null"},
        },
    },
}


def build(name: str) -> dict:
    body = copy.deepcopy(MESSAGES[name])
    schema = {"$schema": DIALECT, "$id": f"{BASE}{name}.schema.json"}
    schema.update(body)
    used = sorted(_refs(body, set()))
    if used:
        schema["$defs"] = {k: copy.deepcopy(DEFS[k]) for k in used}
    return schema


def render(name: str) -> str:
    return json.dumps(build(name), indent=2, ensure_ascii=False) + "\n"


def main(argv: list[str]) -> int:
    check = "--check" in argv
    stale = []
    OUT.mkdir(parents=True, exist_ok=True)
    for name in MESSAGES:
        path = OUT / f"{name}.schema.json"
        text = render(name)
        if check:
            if not path.exists() or path.read_text() != text:
                stale.append(str(path))
        else:
            path.write_text(text)
    if stale:
        print("stale schemas (run clients/python/tools/gen_schemas.py):", *stale, sep="\n  ")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
