"""Solve the QP (30) for one N: a dual active-set method first, then a screened QP solver.

1. From a warm working set (empty by default: most pool rows are inactive at the
   optimum) the dual active-set method (:mod:`dual_active_set`) ends, within its steps,
   with an optimality certificate (the KKT check of :mod:`active_set`) or a checked
   infeasibility certificate.
2. Otherwise a QP solver (OSQP, or Clarabel when an infeasibility certificate may be
   needed) solves the QP on the *screened* pool: the rows nearly active along the
   current point, plus every row the last solution violates, round after round —
   each reduced QP is a relaxation, so a solution satisfying the whole pool is
   optimal, and an infeasibility certificate of a reduced QP proves the full problem
   infeasible. The solver's active set then seeds the exact refinement, which
   certifies the optimum to round-off.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan_report import Certificate
from spm_console.core.planning.active_set import refine
from spm_console.core.planning.dual_active_set import dual_active_set
from spm_console.core.planning.qp_build import Equalities, Pool
from spm_console.core.planning.solvers.base import QpSolution, QpSolver
from spm_console.core.planning.solvers.clarabel_qp import ClarabelQp
from spm_console.core.planning.solvers.osqp_qp import OsqpQp

F = NDArray[np.float64]
I = NDArray[np.int64]

Backend = Literal["osqp", "clarabel"]

#: The solver of each backend (:class:`~spm_console.core.planning.solvers.base.QpSolver`).
SOLVERS: dict[Backend, QpSolver] = {"osqp": OsqpQp(), "clarabel": ClarabelQp()}

#: Screening margins: a pool row this close to its bound joins the reduced QP.
REGION_MARGIN_DEG = 0.3
SPEED_MARGIN_DEGPS = 0.5
#: A pool row violated by more than this (deg or deg/s) triggers another round.
SCREEN_TOL = 1e-7
MAX_ROUNDS = 10


@dataclass
class QpOutcome:
    """Result of one solve of (30) for a fixed N."""

    status: str
    """'solved', 'infeasible' or 'failed'."""
    z: F | None
    method: str
    """'active-set' (exact KKT solves only) or '<backend>+active-set' or '<backend>'."""
    solver_calls: int
    """Calls of the QP solver (OSQP or Clarabel)."""
    kkt_solves: int
    rounds: int
    rows_used: int
    rows_total: int
    iterations: int
    certified: bool
    """Optimality verified by the KKT conditions (exact refinement)."""
    seconds: float
    active: I = field(default_factory=lambda: np.zeros(0, np.int64))
    side: I = field(default_factory=lambda: np.zeros(0, np.int64))
    certificate: Certificate | None = None
    """Infeasibility certificate (Clarabel backend)."""
    detail: str = ""

    @property
    def qp_count(self) -> int:
        """QPs solved: solver calls, or 1 for a pure active-set solve."""
        return max(self.solver_calls, 1)

    def info(self) -> dict[str, Any]:
        return {"method": self.method, "solver_calls": self.solver_calls,
                "kkt_solves": self.kkt_solves, "rounds": self.rounds, "rows_used": self.rows_used,
                "rows_total": self.rows_total, "solver_iterations": self.iterations,
                "kkt_certified": self.certified, "qp_seconds": self.seconds}


def margins(pool: Pool) -> F:
    return np.where((pool.family == 2) | (pool.family == 3), SPEED_MARGIN_DEGPS, REGION_MARGIN_DEG)


def solve_qp(eq: Equalities, pool: Pool, guess: F, active: I | None = None,
             side: I | None = None, backend: Backend = "clarabel",
             try_active_set: bool = True) -> QpOutcome:
    """Solve (30); ``guess`` (a z vector) seeds the screening, (active, side) the refinement."""
    t0 = time.perf_counter()
    kkt = 0
    if try_active_set:
        r = dual_active_set(eq, pool, active, side)
        kkt += r.solves
        if r.ok:
            return QpOutcome("solved", r.z, "active-set", 0, kkt, 0, r.active.size, pool.m, 0, True,
                             time.perf_counter() - t0, r.active, r.side)
        if r.certificate is not None and r.certificate.valid:
            return QpOutcome("infeasible", None, "active-set", 0, kkt, 0, r.active.size + 1,
                             pool.m, 0, False, time.perf_counter() - t0,
                             certificate=r.certificate)
        if r.z is not None and float(np.abs(eq.C @ r.z - eq.d).max(initial=0.0)) <= 1e-6:
            guess = r.z  # a point that holds the equalities seeds the screening
    mg = margins(pool)
    total = pool.m
    sl0 = pool.slack(guess)
    chosen = np.flatnonzero(sl0 < mg) if total else np.zeros(0, np.int64)
    if active is not None and len(active):
        chosen = np.union1d(chosen, active)
    solver = SOLVERS[backend]
    z_prev: F = guess
    calls = iters = 0
    sol: QpSolution | None = None
    rounds = 0
    for rounds in range(1, MAX_ROUNDS + 2):
        if rounds > MAX_ROUNDS:
            chosen = np.arange(total)
        sol = solver.solve(eq, pool, chosen, z_prev)
        calls += 1
        iters += sol.iterations
        if not sol.solved:
            return QpOutcome(sol.status, None, backend, calls, kkt, rounds, chosen.size, total,
                             iters, False, time.perf_counter() - t0,
                             certificate=sol.certificate, detail=sol.detail)
        assert sol.z is not None
        z = sol.z
        if chosen.size == total:
            break
        sl = pool.slack(z)
        bad = sl < -SCREEN_TOL
        bad[chosen] = False
        if not bad.any():
            break
        near = sl < mg
        near[chosen] = True
        chosen = np.flatnonzero(near | bad)
        z_prev = z
    assert sol is not None and sol.z is not None and sol.y_pool is not None
    z, y = sol.z, sol.y_pool
    # exact refinement on the solver's active set
    r2 = refine(eq, pool, *_active_of(pool, z, y, chosen))
    kkt += r2.solves
    if not r2.ok and backend == "osqp":  # OSQP's active set was not clean: once more, tighter
        again = OsqpQp(tight=True).solve(eq, pool, chosen, z)
        calls += 1
        iters += again.iterations
        if again.solved and again.z is not None and again.y_pool is not None:
            z, y = again.z, again.y_pool
            r2 = refine(eq, pool, *_active_of(pool, z, y, chosen))
            kkt += r2.solves
    if r2.ok:
        return QpOutcome("solved", r2.z, f"{backend}+active-set", calls, kkt, rounds, chosen.size,
                         total, iters, True, time.perf_counter() - t0, r2.active, r2.side)
    act, sd = _active_of(pool, z, y, chosen)
    return QpOutcome("solved", z, backend, calls, kkt, rounds, chosen.size, total, iters, False,
                     time.perf_counter() - t0, act, sd)


def _active_of(pool: Pool, z: F, y: F, chosen: I) -> tuple[I, I]:
    """Rows of ``chosen`` with a significant multiplier and (nearly) zero slack, and their side."""
    ymax = float(np.abs(y).max()) if y.size else 0.0
    sl = pool.slack(z)[chosen]
    on = (np.abs(y) > 1e-6 * max(ymax, 1.0)) & (sl < 1e-4)
    return chosen[on], np.where(y[on] > 0, 1, -1).astype(np.int64)
