#!/usr/bin/env python3
"""The per-piece SOS certificate of eq. (15), as Python users would write it, timed
beside riskplan's (`benches/certify_sos.rs`, group `certify_sos`, `piece_*`).

One illustrative-3 piece is two programs: the Cantelli constraint
g1 = E[P]^2 - 0.9 E[P^2] (degree 4) and the mean constraint g2 = -E[P] (degree 2) of the
disk w^2 - x1^2 - x2^2, w ~ U[0.3, 0.4], along the segment (-1, 0.85) -> (1, 0.85),
tau in [0, 1]. Each program is the margin problem of docs/design.md section 5.5:

    max gamma  s.t.  p(tau) - gamma = v0' Q0 v0 + tau (1 - tau) v1' Q1 v1,  Q0, Q1 PSD,

coefficient matching in the monomial basis, p normalised by its Bernstein scale (as
riskplan does). Two peers:

* `clarabel`: a hand-written Clarabel program (scipy CSC matrices, PSD triangle cones),
  built and solved per program;
* `cvxpy`: the same model in cvxpy, solved with Clarabel (built once per degree with the
  coefficients as a `cp.Parameter`, cvxpy's fastest way to re-solve).

Prints one JSON object per peer: median milliseconds per piece over --reps runs, and the
margins found. Needs `pip install clarabel cvxpy numpy scipy`.

    python3 scripts/sos_peers.py [--reps 200]
"""

import argparse
import json
import math
import statistics
import sys
import time
from fractions import Fraction as F

import numpy as np
import scipy.sparse as sp

try:
    import clarabel
    import cvxpy as cp
except ImportError as e:  # pragma: no cover - a usage error, not a result
    sys.exit(f"error: {e.name} is missing: pip install clarabel cvxpy numpy scipy")


def pmul(a, b):
    out = [F(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def padd(a, b, s=F(1)):
    n = max(len(a), len(b))
    a = a + [F(0)] * (n - len(a))
    b = b + [F(0)] * (n - len(b))
    return [x + s * y for x, y in zip(a, b)]


def piece_constraints():
    """g1 and g2 of the benchmark piece, exact (the same arithmetic as benches/certify_sos.rs)."""
    x1 = [F(-1), F(2)]
    x2 = [F(85, 100)]
    rho = padd(pmul(x1, x1), pmul(x2, x2))
    ep = padd([F(37, 300)], rho, F(-1))
    ep2 = padd(padd([F(781, 50000)], [c * F(37, 150) for c in rho], F(-1)), pmul(rho, rho))
    g1 = padd(pmul(ep, ep), [c * F(9, 10) for c in ep2], F(-1))
    g2 = [-c for c in ep]
    return [float(c) for c in g1], [float(c) for c in g2]


def bernstein_scale(a):
    n = len(a) - 1
    s = 0.0
    for k in range(n + 1):
        b = sum(math.comb(k, i) / math.comb(n, i) * a[i] for i in range(k + 1))
        s = max(s, abs(b))
    return s


def normalised(a):
    s = bernstein_scale(a)
    return [c / s for c in a], s


def svec_index(i, j, side):
    """Position of Q[i][j] (i <= j) in Clarabel's PSD triangle (column-major upper)."""
    return j * (j + 1) // 2 + i


def clarabel_margin(p):
    """The hand-written Clarabel program; returns gamma (normalised units)."""
    n = len(p) - 1
    e0 = (n + 1) // 2
    s0, s1 = e0 + 1, e0
    t0, t1 = s0 * (s0 + 1) // 2, s1 * (s1 + 1) // 2
    nvar = 1 + t0 + t1
    rows, cols, vals, b = [], [], [], []
    # coefficient matching, k = 0..2 e0 (zero cone): gamma[k=0] + [s0]_k + [s1]_{k-1} - [s1]_{k-2} = p_k
    r = 0
    for k in range(2 * e0 + 1):
        if k == 0:
            rows.append(r); cols.append(0); vals.append(1.0)
        for (side, off, shift, sign) in ((s0, 1, 0, 1.0), (s1, 1 + t0, 1, 1.0), (s1, 1 + t0, 2, -1.0)):
            kk = k - shift
            if kk < 0:
                continue
            for i in range(side):
                j = kk - i
                if j < i or j >= side:
                    continue
                # Q_ij = x/sqrt(2) off the diagonal, counted twice in the symmetric sum
                coef = 1.0 if i == j else 2.0 / math.sqrt(2.0)
                rows.append(r); cols.append(off + svec_index(i, j, side)); vals.append(sign * coef)
        b.append(p[k] if k < len(p) else 0.0)
        r += 1
    n_eq = r
    # PSD cones: -x_block + s = 0
    for off, t in ((1, t0), (1 + t0, t1)):
        for i in range(t):
            rows.append(r); cols.append(off + i); vals.append(-1.0)
            b.append(0.0)
            r += 1
    A = sp.csc_matrix((vals, (rows, cols)), shape=(r, nvar))
    P = sp.csc_matrix((nvar, nvar))
    q = np.zeros(nvar)
    q[0] = -1.0
    cones = [clarabel.ZeroConeT(n_eq), clarabel.PSDTriangleConeT(s0), clarabel.PSDTriangleConeT(s1)]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-8
    sol = clarabel.DefaultSolver(P, q, A, np.array(b), cones, settings).solve()
    return sol.x[0]


_CVXPY_CACHE = {}


def cvxpy_problem(n):
    """The model for degree n in cvxpy, built once per degree with the coefficients as a
    parameter (cvxpy's fastest use: re-solves skip most of the canonicalisation)."""
    e0 = (n + 1) // 2
    Q0 = cp.Variable((e0 + 1, e0 + 1), PSD=True)
    Q1 = cp.Variable((e0, e0), PSD=True)
    g = cp.Variable()
    coeffs = cp.Parameter(2 * e0 + 1)

    def anti(Q, side, k):
        terms = [Q[i, k - i] for i in range(side) if 0 <= k - i < side]
        return sum(terms) if terms else 0

    cons = []
    for k in range(2 * e0 + 1):
        lhs = (g if k == 0 else 0) + anti(Q0, e0 + 1, k)
        if k >= 1:
            lhs = lhs + anti(Q1, e0, k - 1)
        if k >= 2:
            lhs = lhs - anti(Q1, e0, k - 2)
        cons.append(lhs == coeffs[k])
    return cp.Problem(cp.Maximize(g), cons), coeffs, g


def cvxpy_margin(p):
    """The same model in cvxpy with Clarabel; returns gamma (normalised units)."""
    n = len(p) - 1
    if n not in _CVXPY_CACHE:
        _CVXPY_CACHE[n] = cvxpy_problem(n)
    prob, coeffs, g = _CVXPY_CACHE[n]
    coeffs.value = np.array(p + [0.0] * (coeffs.shape[0] - len(p)))
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-8, tol_gap_rel=1e-8, tol_feas=1e-8)
    return g.value


def time_peer(fn, programs, reps):
    times = []
    margins = None
    for _ in range(reps):
        t = time.perf_counter()
        margins = [fn(p) * s for p, s in programs]
        times.append(time.perf_counter() - t)
    return statistics.median(times) * 1e3, margins


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=200, help="runs per peer (cvxpy gets a fifth of them, at least 20)")
    a = ap.parse_args()
    if a.reps < 1:
        sys.exit("error: --reps must be >= 1")
    g1, g2 = piece_constraints()
    programs = [normalised(g1), normalised(g2)]
    for name, fn, reps in (("clarabel", clarabel_margin, a.reps), ("cvxpy", cvxpy_margin, max(20, a.reps // 5))):
        fn(programs[0][0])  # warm-up (imports, first-call costs)
        ms, margins = time_peer(fn, programs, reps)
        print(json.dumps({"peer": name, "ms_per_piece": round(ms, 4), "reps": reps,
                          "margins": [round(m, 9) for m in margins]}))


if __name__ == "__main__":
    main()
