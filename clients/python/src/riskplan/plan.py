"""A plan returned by the service: the raw ``plan_reply`` dict plus numpy helpers."""
from __future__ import annotations

from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
from numpy.polynomial import polynomial as P

TRAJECTORY_FORMAT = "riskplan-trajectory/1"


class Trajectory:
    """Piecewise-polynomial trajectory (format v1): ``x_d(t) = Σ_k coeffs[d][k]·t^k``
    on ``[t0, t1]`` of each piece, in absolute time."""

    def __init__(self, raw: Dict[str, Any]):
        self.raw = raw
        pieces = raw.get("pieces") or []
        if not pieces:
            raise ValueError("a trajectory needs at least one piece")
        self._t0 = np.array([float(p["t0"]) for p in pieces])
        self._t1 = np.array([float(p["t1"]) for p in pieces])
        self._coeffs: List[List[np.ndarray]] = [[np.asarray(row, dtype=float) for row in p["coeffs"]] for p in pieces]

    @property
    def pieces(self) -> List[Dict[str, Any]]:
        return self.raw["pieces"]

    @property
    def dim(self) -> int:
        return len(self._coeffs[0])

    @property
    def t0(self) -> float:
        """Start time of the first piece."""
        return float(self._t0[0])

    @property
    def t1(self) -> float:
        """End time of the last piece."""
        return float(self._t1[-1])

    def trajectory(self) -> Dict[str, Any]:
        """The trajectory alone, format v1 (``{"format", "pieces"}``), e.g. for ``verify``."""
        return {"format": TRAJECTORY_FORMAT, "pieces": self.pieces}

    def position(self, t: Union[float, np.ndarray]) -> np.ndarray:
        """Position(s) at time(s) ``t``: shape ``(dim,)`` for a scalar, ``(n, dim)`` for an
        array. Times outside ``[t0, t1]`` are clamped to the ends."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        ts = np.clip(ts, self.t0, self.t1)
        idx = np.searchsorted(self._t1, ts, side="left")
        idx = np.minimum(idx, len(self._coeffs) - 1)
        out = np.empty((ts.size, self.dim))
        for i in np.unique(idx):
            mask = idx == i
            for d, row in enumerate(self._coeffs[i]):
                out[mask, d] = P.polyval(ts[mask], row)
        return out[0] if np.ndim(t) == 0 else out

    def velocity(self, t: float) -> np.ndarray:
        """Velocity at time ``t`` (clamped to ``[t0, t1]``; zero after the end, where a
        robot following the plan stops)."""
        tt = float(t)
        if tt > self.t1:
            return np.zeros(self.dim)
        tt = min(max(tt, self.t0), self.t1)
        i = min(int(np.searchsorted(self._t1, tt, side="left")), len(self._coeffs) - 1)
        return np.array([P.polyval(tt, P.polyder(row)) if len(row) > 1 else 0.0 for row in self._coeffs[i]])

    def waypoints(self) -> np.ndarray:
        """The piece end points: an ``(pieces + 1, dim)`` array (start, the junctions, end)."""
        pts = [self.position(float(t)) for t in self._t0]
        pts.append(self.position(self.t1))
        return np.vstack(pts)

    def times(self, n: int) -> np.ndarray:
        """``n`` evenly spaced times over ``[t0, t1]``."""
        return np.linspace(self.t0, self.t1, int(n))

    def sample(self, n: int = 100, return_times: bool = False):
        """Positions at ``n`` evenly spaced times over the trajectory's time span: an
        ``(n, dim)`` array, or ``(times, positions)`` with ``return_times=True``."""
        ts = self.times(n)
        xs = self.position(ts)
        return (ts, xs) if return_times else xs

    def length(self, n: int = 64) -> float:
        """Path length: ``n`` samples per piece (exact for straight pieces)."""
        total = 0.0
        for a, b in zip(self._t0, self._t1):
            xs = self.position(np.linspace(a, b, max(2, int(n))))
            total += float(np.sum(np.linalg.norm(np.diff(xs, axis=0), axis=1)))
        return total


class Plan(Trajectory):
    """A ``plan_reply``: the trajectory plus ``planner``, ``certified``, ``stats``,
    ``revision``, ``scene`` and ``risk``. ``raw`` is the reply dict as received."""

    @property
    def certified(self) -> bool:
        return bool(self.raw.get("certified"))

    @property
    def revision(self) -> int:
        return int(self.raw["revision"])

    @property
    def stats(self) -> Dict[str, Any]:
        return self.raw.get("stats", {})

    @property
    def planner(self) -> str:
        return self.raw.get("planner", "")

    @property
    def scene(self) -> str:
        return self.raw.get("scene", "")

    @property
    def risk(self) -> float:
        return float(self.raw["risk"])

    @property
    def progress(self) -> Optional[Dict[str, Any]]:
        """What a receding-horizon plan achieved (``reached_goal``, ``start_distance``,
        ``remaining_distance``, ``end_time``); ``None`` for other plans."""
        return self.stats.get("progress")

    def __repr__(self) -> str:
        return (
            f"Plan(scene={self.scene!r}, revision={self.raw.get('revision')}, planner={self.planner!r}, "
            f"certified={self.certified}, pieces={len(self.pieces)}, "
            f"time={self.stats.get('planning_time_s', float('nan')):.3f}s)"
        )
