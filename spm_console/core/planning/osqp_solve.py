"""OSQP on the QP (30) with constraint screening and polishing.

Most region half-spaces are inactive at the optimum. The solver starts from the
candidate rows that are nearly active along a first guess, solves, adds every
candidate row the solution violates (with the nearly active ones), and repeats:
each reduced problem is a relaxation, so a solution satisfying all candidates is
optimal for the full problem. OSQP's solution polishing (an exact equality-
constrained solve on the detected active set) makes the answer exact to
round-off; an unpolished answer is re-solved with tighter tolerances.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.planning.qp_build import QpData

F = NDArray[np.float64]

#: Screening margins: a candidate within this distance of its bound joins the QP.
REGION_MARGIN_DEG = 1.0
SPEED_MARGIN_DEGPS = 2.0
#: A candidate violated by more than this (deg or deg/s) triggers another round.
SCREEN_TOL = 1e-7
MAX_ROUNDS = 12

OSQP_SETTINGS: dict[str, object] = {
    "verbose": False,
    "eps_abs": 1e-6,
    "eps_rel": 1e-6,
    "eps_prim_inf": 1e-7,
    "eps_dual_inf": 1e-7,
    "polishing": True,
    "polish_refine_iter": 5,
    "max_iter": 20000,
    "delta": 1e-7,
}


@dataclass
class QpOutcome:
    """Result of one screened solve."""

    status: str
    """'solved', 'infeasible' (OSQP's primal infeasibility certificate) or 'failed'."""
    z: F | None
    """Solution vector (layout of :class:`Layout`)."""
    objective: float
    qp_count: int
    """OSQP solves (one per screening round, plus tightening re-solves)."""
    rounds: int
    rows_used: int
    """Candidate rows that entered the last QP."""
    rows_total: int
    iterations: int
    polished: bool
    seconds: float
    y: F | None = None
    """Dual of the base rows (for warm starts)."""


def candidate_slack(data: QpData, z: F) -> F:
    """Normalized slack of every candidate row (deg for region rows, deg/s for speed): (m,)."""
    gz = data.G @ z
    s = np.minimum(data.g_hi - gz, gz - data.g_lo)
    return np.asarray(s / data.g_scale)


def _margins(data: QpData) -> F:
    return np.where(data.g_family == 2, SPEED_MARGIN_DEGPS, REGION_MARGIN_DEG)


def solve_screened(data: QpData, guess: F, warm_y: F | None = None,
                   screen: bool = True) -> QpOutcome:
    """Solve the QP, screening candidate rows from ``guess`` (a z vector)."""
    t0 = time.perf_counter()
    mg = _margins(data)
    total = data.G.shape[0]
    if screen:
        chosen = np.flatnonzero(candidate_slack(data, guess) < mg) if total else np.zeros(0, int)
    else:
        chosen = np.arange(total)
    z_prev: F | None = guess
    y_prev: F | None = warm_y
    qp_count = iters = 0
    polished = False
    for rounds in range(1, MAX_ROUNDS + 2):
        if rounds > MAX_ROUNDS:  # give up screening: every row
            chosen = np.arange(total)
        Gs = data.G[chosen]
        A = sp.vstack([data.A, Gs], format="csc")
        lo = np.concatenate([data.l, data.g_lo[chosen]])
        hi = np.concatenate([data.u, data.g_hi[chosen]])
        res, n_solves, it, pol = _osqp(data.P, data.q, A, lo, hi, z_prev, y_prev, data.A.shape[0])
        qp_count += n_solves
        iters += it
        polished = pol
        status = res.info.status
        if status == "primal infeasible":
            return QpOutcome("infeasible", None, np.inf, qp_count, rounds, chosen.size, total,
                             iters, False, time.perf_counter() - t0)
        if status not in ("solved", "solved inaccurate"):
            return QpOutcome("failed", None, np.nan, qp_count, rounds, chosen.size, total, iters,
                             False, time.perf_counter() - t0)
        z = np.asarray(res.x, float)
        if not total or chosen.size == total:
            break
        sl = candidate_slack(data, z)
        bad = sl < -SCREEN_TOL
        bad[chosen] = False
        if not bad.any():
            break
        near = sl < mg
        near[chosen] = True
        chosen = np.flatnonzero(near | bad)
        z_prev = z
        y_prev = np.asarray(res.y, float)[: data.A.shape[0]]
    obj = float(0.5 * z @ (data.P @ z) + data.q @ z)
    return QpOutcome("solved", z, obj, qp_count, rounds, chosen.size, total, iters, polished,
                     time.perf_counter() - t0, np.asarray(res.y, float)[: data.A.shape[0]])


def _osqp(P: sp.csc_matrix, q: F, A: sp.csc_matrix, lo: F, hi: F, z0: F | None,
          y_base: F | None, m_base: int) -> tuple[object, int, int, bool]:
    """One OSQP solve; re-solved with 100× tighter tolerances if polishing failed."""
    solver = osqp.OSQP()
    solver.setup(P, q, A, lo, hi, **OSQP_SETTINGS)
    if z0 is not None:
        y0 = np.zeros(A.shape[0])
        if y_base is not None:
            y0[:m_base] = y_base
        solver.warm_start(x=z0, y=y0)
    res = solver.solve()
    n, it = 1, int(res.info.iter)
    pol = int(res.info.status_polish) == 1
    if res.info.status in ("solved", "solved inaccurate") and not pol:
        solver.update_settings(eps_abs=1e-9, eps_rel=1e-9, max_iter=200000)
        solver.warm_start(x=res.x, y=res.y)
        res = solver.solve()
        n += 1
        it += int(res.info.iter)
        pol = int(res.info.status_polish) == 1
    return res, n, it, pol
