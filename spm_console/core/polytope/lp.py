"""Small dense linear programs (a few variables, up to thousands of rows) for region building.

Solved by HiGHS through its own Python binding (``highspy``, the solver cvxpy ships with),
one solver object per thread, presolve off: scipy's ``linprog`` runs the same solver but
spends about 3 ms per call on checks and conversions, about 6 times the solve itself on the
4-variable LPs of a region build, which solves hundreds of them. The slow LP-per-row checks
that verify a build keep scipy's ``linprog`` (an independent route).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]

#: scipy.optimize.linprog's status codes, which callers already speak.
OPTIMAL, ITERATION_LIMIT, INFEASIBLE, UNBOUNDED, OTHER = 0, 1, 2, 3, 4

_local = threading.local()


@dataclass(frozen=True)
class LpResult:
    status: int
    """:data:`OPTIMAL`, :data:`INFEASIBLE`, :data:`UNBOUNDED`, … (scipy's codes)."""
    x: F
    """The solution (NaN unless optimal)."""
    fun: float
    """c·x at the solution (NaN unless optimal)."""


def _solver() -> Any:
    h = getattr(_local, "highs", None)
    if h is None:
        import highspy  # here: only a build solves LPs (~0.2 s to import)

        h = highspy.Highs()
        h.setOptionValue("output_flag", False)
        h.setOptionValue("presolve", "off")
        _local.highs = h
    return h


def solve_lp(c: F, A_ub: F, b_ub: F, lower: F | None = None, upper: F | None = None) -> LpResult:
    """min c·x subject to A_ub x ≤ b_ub and lower ≤ x ≤ upper (±inf where unbounded; None:
    free). Dense (m, n) ``A_ub``."""
    import highspy

    c = np.ascontiguousarray(c, float).ravel()
    A = np.ascontiguousarray(A_ub, float)
    b = np.ascontiguousarray(b_ub, float).ravel()
    m, n = A.shape
    if len(c) != n or len(b) != m:
        raise ValueError(f"LP shapes: c {c.shape}, A_ub {A.shape}, b_ub {b.shape}")
    inf = highspy.kHighsInf
    lo = np.full(n, -inf) if lower is None else np.where(np.isfinite(lower), lower, -inf)
    hi = np.full(n, inf) if upper is None else np.where(np.isfinite(upper), upper, inf)
    lp = highspy.HighsLp()
    lp.num_col_ = n
    lp.num_row_ = m
    lp.col_cost_ = c
    lp.col_lower_ = np.asarray(lo, float)
    lp.col_upper_ = np.asarray(hi, float)
    lp.row_lower_ = np.full(m, -inf)
    lp.row_upper_ = b
    lp.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
    lp.a_matrix_.start_ = np.arange(0, m * n + 1, n, dtype=np.int32)
    lp.a_matrix_.index_ = np.tile(np.arange(n, dtype=np.int32), m)
    lp.a_matrix_.value_ = A.ravel()
    h = _solver()
    h.clearModel()
    h.passModel(lp)
    h.run()
    st = h.getModelStatus()
    S = highspy.HighsModelStatus
    if st == S.kOptimal:
        x = np.array(h.getSolution().col_value, float)
        return LpResult(OPTIMAL, x, float(c @ x))
    code = {S.kInfeasible: INFEASIBLE, S.kUnbounded: UNBOUNDED,
            S.kIterationLimit: ITERATION_LIMIT}.get(st, OTHER)
    if st == S.kUnboundedOrInfeasible:  # without presolve HiGHS may not tell which: ask again
        h.setOptionValue("presolve", "on")
        try:
            h.run()
            st = h.getModelStatus()
        finally:
            h.setOptionValue("presolve", "off")
        code = {S.kInfeasible: INFEASIBLE, S.kUnbounded: UNBOUNDED}.get(st, OTHER)
        if st == S.kOptimal:
            x = np.array(h.getSolution().col_value, float)
            return LpResult(OPTIMAL, x, float(c @ x))
    return LpResult(code, np.full(n, np.nan), float("nan"))
