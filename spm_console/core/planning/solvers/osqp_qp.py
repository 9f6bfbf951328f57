"""OSQP on the reduced QP (equalities + chosen pool rows), built directly as sparse matrices."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.planning.qp_build import Equalities, Pool
from spm_console.core.planning.solvers.base import QpSolution

F = NDArray[np.float64]
I = NDArray[np.int64]

OSQP_SETTINGS: dict[str, Any] = {
    "verbose": False,
    "eps_abs": 1e-6,
    "eps_rel": 1e-6,
    "eps_prim_inf": 1e-6,
    "eps_dual_inf": 1e-6,
    "polishing": True,
    "polish_refine_iter": 5,
    "max_iter": 20000,
    "delta": 1e-7,
}


@dataclass(frozen=True)
class OsqpQp:
    """:class:`~.base.QpSolver` by OSQP (warm-started at ``z0``); ``tight``: tolerances 1e-9
    and a larger iteration budget (a second try when the first active set was not clean).
    Its infeasibility answers carry no certificate the planner checks: 'infeasible' is
    OSQP's own status, possibly 'inaccurate'."""

    tight: bool = False

    @property
    def name(self) -> str:
        return "osqp"

    def solve(self, eq: Equalities, pool: Pool, chosen: I, z0: F | None = None) -> QpSolution:
        t0 = time.perf_counter()
        A = sp.vstack([eq.C, pool.rows(chosen)], format="csc")
        lo = np.concatenate([eq.d, pool.lo[chosen]])
        hi = np.concatenate([eq.d, pool.hi[chosen]])
        solver = osqp.OSQP()
        settings = dict(OSQP_SETTINGS)
        if self.tight:
            settings.update(eps_abs=1e-9, eps_rel=1e-9, max_iter=100000)
        solver.setup(eq.P, np.zeros(eq.layout.n), A, lo, hi, **settings)
        if z0 is not None:
            solver.warm_start(x=z0)
        res = solver.solve(raise_error=False)
        st = str(res.info.status)
        it = int(res.info.iter)
        dt = time.perf_counter() - t0
        if st.startswith("primal infeasible"):
            return QpSolution("osqp", "infeasible", chosen, iterations=it, seconds=dt, detail=st)
        if st in ("solved", "solved inaccurate"):
            y = np.asarray(res.y, float)
            m_eq = eq.C.shape[0]
            return QpSolution("osqp", "solved", chosen, np.asarray(res.x, float), y[:m_eq],
                              y[m_eq:], iterations=it, seconds=dt, detail=st,
                              polished=int(res.info.status_polish) == 1)
        return QpSolution("osqp", "failed", chosen, iterations=it, seconds=dt, detail=st)
