"""OSQP on a reduced QP (equalities + screened pool rows), built directly as sparse matrices."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.planning.qp_build import Equalities, Pool

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


@dataclass
class OsqpOutcome:
    status: str
    """'solved', 'infeasible' (OSQP's certificate, possibly 'inaccurate') or 'failed'."""
    z: F | None
    y_pool: F | None
    """Multipliers of the chosen pool rows (> 0 at the upper bound, < 0 at the lower)."""
    iterations: int
    polished: bool
    seconds: float
    detail: str


def solve_osqp(eq: Equalities, pool: Pool, chosen: I, z0: F | None,
               tight: bool = False) -> OsqpOutcome:
    """min ½zᵀPz s.t. C z = d, lo ≤ G z ≤ hi on the rows ``chosen`` (warm-started at z0).

    ``tight``: tolerances 1e-9 and a larger iteration budget (a second try)."""
    t0 = time.perf_counter()
    A = sp.vstack([eq.C, pool.rows(chosen)], format="csc")
    lo = np.concatenate([eq.d, pool.lo[chosen]])
    hi = np.concatenate([eq.d, pool.hi[chosen]])
    solver = osqp.OSQP()
    settings = dict(OSQP_SETTINGS)
    if tight:
        settings.update(eps_abs=1e-9, eps_rel=1e-9, max_iter=100000)
    solver.setup(eq.P, np.zeros(eq.layout.n), A, lo, hi, **settings)
    if z0 is not None:
        solver.warm_start(x=z0)
    res = solver.solve(raise_error=False)
    st = str(res.info.status)
    it = int(res.info.iter)
    pol = int(res.info.status_polish) == 1
    dt = time.perf_counter() - t0
    if st.startswith("primal infeasible"):
        return OsqpOutcome("infeasible", None, None, it, False, dt, st)
    if st in ("solved", "solved inaccurate"):
        y = np.asarray(res.y, float)[eq.C.shape[0]:]
        return OsqpOutcome("solved", np.asarray(res.x, float), y, it, pol, dt, st)
    return OsqpOutcome("failed", None, None, it, False, dt, st)
