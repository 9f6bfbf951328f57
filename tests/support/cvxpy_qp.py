"""The reduced QP of (30) (equalities + chosen pool rows) solved by cvxpy: a third
:class:`~spm_console.core.planning.solvers.base.QpSolver`, for the tests (not shipped).

cvxpy gets the matrices and states the problem its own way (two-sided bounds as two
inequalities); the multipliers it returns are mapped to the solvers' one convention."""

from __future__ import annotations

import time
from dataclasses import dataclass

import cvxpy as cp
import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.qp_build import Equalities, Pool
from spm_console.core.planning.solvers.base import QpSolution

F = NDArray[np.float64]
I = NDArray[np.int64]


@dataclass(frozen=True)
class CvxpyQp:
    """cvxpy with ``solver`` (Clarabel by default)."""

    solver: str = "CLARABEL"

    @property
    def name(self) -> str:
        return f"cvxpy/{self.solver.lower()}"

    def solve(self, eq: Equalities, pool: Pool, chosen: I, z0: F | None = None) -> QpSolution:
        t0 = time.perf_counter()
        G = pool.rows(chosen).tocsr()
        lo, hi = pool.lo[chosen], pool.hi[chosen]
        up, dn = np.flatnonzero(np.isfinite(hi)), np.flatnonzero(np.isfinite(lo))
        z = cp.Variable(eq.layout.n)
        cons = [eq.C @ z == eq.d]
        if up.size:
            cons.append(G[up] @ z <= hi[up])
        if dn.size:
            cons.append(G[dn] @ z >= lo[dn])
        prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(z, eq.P, assume_PSD=True)), cons)
        prob.solve(solver=self.solver)
        dt = time.perf_counter() - t0
        if prob.status in ("infeasible", "infeasible_inaccurate"):
            return QpSolution(self.name, "infeasible", chosen, seconds=dt, detail=prob.status)
        if prob.status not in ("optimal", "optimal_inaccurate") or z.value is None:
            return QpSolution(self.name, "failed", chosen, seconds=dt, detail=str(prob.status))
        # cvxpy: L = f + λᵀ(Cz − d) + μ_upᵀ(G z − hi) + μ_dnᵀ(lo − G z), μ ≥ 0
        y = np.zeros(chosen.size)
        k = 1
        if up.size:
            y[up] += np.asarray(cons[k].dual_value, float)
            k += 1
        if dn.size:
            y[dn] -= np.asarray(cons[k].dual_value, float)
        return QpSolution(self.name, "solved", chosen, np.asarray(z.value, float),
                          np.asarray(cons[0].dual_value, float), y, seconds=dt,
                          detail=str(prob.status))
