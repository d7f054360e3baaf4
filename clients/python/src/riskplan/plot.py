"""matplotlib helpers (``pip install riskplan[plot]``).

``draw_scene`` asks the server for Cantelli bounds on a grid (``risk_grid``) and draws
the Δ-risk contour (the level set bound = Δ: outside the curve the probability of
collision with each obstacle is at most Δ), the start and goal, and optionally a plan.
"""
from __future__ import annotations

from typing import Any, Optional, Sequence, Union

import numpy as np

from .plan import Trajectory


def draw_scene(client, name: str, delta: Optional[float] = None, time: Optional[float] = None, ax=None,
               plan: Union[None, Trajectory, dict] = None, n: int = 200,
               window: Optional[Sequence[float]] = None, fill: bool = True, samples: int = 400):
    """Draws scene ``name`` of a running server on ``ax`` (a new figure when ``None``)
    and returns the axes.

    - ``delta``: the risk level of the contour (default: the scene's ``risk``).
    - ``time``: the instant of the contour (default: the horizon's start).
    - ``plan``: a :class:`riskplan.Plan` (or a plan_reply / trajectory dict) to overlay.
    - ``n``: grid side of the ``risk_grid`` query (≤ 500); ``window``:
      ``(xmin, xmax, ymin, ymax)`` (default: the workspace's first two axes).
    """
    import matplotlib.pyplot as plt

    reply = client.get_scene(name)
    scene = reply["scene"]
    if delta is None:
        delta = _num(scene["risk"])
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    lower = [_num(v) for v in scene["workspace"]["lower"]]
    upper = [_num(v) for v in scene["workspace"]["upper"]]
    if window is not None:
        lower[0], upper[0], lower[1], upper[1] = (float(v) for v in window)
    X, Y, B = client.risk_grid(name, lower, upper, n, time=time)
    if fill:
        ax.contourf(X, Y, B, levels=[delta, max(1.0, float(np.nanmax(B)))], colors=["#f4a6a6"], alpha=0.6)
    cs = ax.contour(X, Y, B, levels=[delta], colors=["#b00000"], linewidths=1.5)
    t_label = "" if time is None else f", t = {time:g}"
    handles, labels = [], []
    try:
        from matplotlib.lines import Line2D

        handles.append(Line2D([], [], color="#b00000"))
        labels.append(f"Δ = {delta:g} risk contour{t_label}")
    except Exception:  # pragma: no cover
        pass
    if plan is not None:
        traj = plan if isinstance(plan, Trajectory) else Trajectory(plan)
        xs = traj.sample(samples)
        wp = traj.waypoints()
        label = "plan"
        if getattr(traj, "raw", {}).get("certified") is not None:
            label = "certified plan" if traj.raw.get("certified") else "plan (NOT certified)"
        (line,) = ax.plot(xs[:, 0], xs[:, 1], "-", color="#1f4fbf", lw=2)
        ax.plot(wp[:, 0], wp[:, 1], "o", color="#1f4fbf", ms=3)
        handles.append(line)
        labels.append(label)
    for key, marker, label in (("start", "s", "start"), ("goal", "*", "goal")):
        if scene.get(key) is not None:
            p = [_num(v) for v in scene[key]]
            (h,) = ax.plot(p[0], p[1], marker, color="black", ms=9 if marker == "*" else 7)
            handles.append(h)
            labels.append(label)
    ax.set_xlim(lower[0], upper[0])
    ax.set_ylim(lower[1], upper[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x1")
    ax.set_ylabel("x2")
    ax.set_title(f"{reply['name']} (revision {reply['revision']})")
    if handles:
        ax.legend(handles, labels, loc="best", fontsize="small")
    return ax


def _num(v: Any) -> float:
    """A scene number (JSON number, or text such as "37/300") as a float."""
    if isinstance(v, (int, float)):
        return float(v)
    s = str(v).strip()
    if "/" in s:
        a, b = s.split("/", 1)
        return float(a) / float(b)
    return float(s)
