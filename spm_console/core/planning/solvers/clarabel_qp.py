"""Interior-point solves of (30) with Clarabel: optimal points or infeasibility certificates.

Clarabel's standard form is A x + s = b, s ∈ K. Equalities go to the zero cone, pool
rows (both sides where finite) to the non-negative cone. When Clarabel reports primal
infeasibility its dual vector y is a Farkas certificate: y ∈ K*, Aᵀy = 0, bᵀy < 0.
We check it ourselves (:class:`Certificate`) rather than trusting the status: with y
scaled to bᵀy = −1, any x feasible for the constraints would satisfy rᵀx ≤ −1 + c‖s‖
with r = Aᵀy and c the cone violation, i.e. would need ‖x‖∞ ≥ (1 − …)/‖r‖₁ — we report
that bound. A certificate for a screened subset of rows proves the full problem
infeasible (fewer constraints, larger feasible set).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.plan_report import Certificate
from spm_console.core.planning.qp_build import Equalities, Pool
from spm_console.core.planning.solvers.base import QpSolution

F = NDArray[np.float64]
I = NDArray[np.int64]

#: A certificate is accepted when it rules out every point with ‖x‖∞ below this: no angle,
#: speed or reference of a wrist comes near 10⁴ deg or deg/s, so nothing real is excluded.
CERTIFIED_RADIUS = 1e4


def _standard_form(eq: Equalities, pool: Pool, chosen: I) -> tuple[sp.csc_matrix, F, int, int]:
    """(A, b, equality rows, inequality rows) of {A z + s = b, s_eq = 0, s_ineq ≥ 0}: the
    equalities, then the chosen rows at their finite upper bounds, then at their finite lower
    bounds (negated); assembled from triplets at once (stacking sparse blocks costs more)."""
    lo, hi = pool.lo[chosen], pool.hi[chosen]
    up, dn = np.isfinite(hi), np.isfinite(lo)
    rows_up, rows_dn = chosen[up], chosen[dn]
    m_eq, n_up = eq.C.shape[0], rows_up.size
    Cc = eq.C.tocoo()
    ru, cu, vu = pool.triplets(rows_up)
    rd, cd, vd = pool.triplets(rows_dn)
    m = m_eq + n_up + rows_dn.size
    A = sp.csc_matrix((np.concatenate([Cc.data, vu, -vd]),
                       (np.concatenate([Cc.row, ru + m_eq, rd + m_eq + n_up]),
                        np.concatenate([Cc.col, cu, cd]))), shape=(m, eq.layout.n))
    b = np.concatenate([eq.d, hi[up], -lo[dn]])
    return A, b, m_eq, int(up.sum() + dn.sum())


def check_certificate(A: sp.csc_matrix, b: F, y: F, m_eq: int) -> Certificate:
    """Verify a Farkas certificate ``y`` for {x : A x + s = b, s_eq = 0, s_ineq ≥ 0}."""
    return farkas_verdict(b, y, m_eq, lambda v: np.asarray(A.T @ v))


def farkas_verdict(b: F, y: F, m_eq: int, transposed: Callable[[F], F]) -> Certificate:
    """:func:`check_certificate` with A given by ``transposed(v)`` = Aᵀv (A need not be
    assembled: the dual active set's rows are the equalities and a few dense rows)."""
    by = float(b @ y)
    if not np.isfinite(by) or by >= 0:
        return Certificate(np.inf, np.inf, 0.0, len(b), False)
    ys = y / -by
    r1 = float(np.abs(transposed(ys)).sum())
    neg = ys[m_eq:]
    cone = float(max(0.0, -neg.min())) if neg.size else 0.0
    # a feasible x with slack s = b − A x gives 0 ≤ yᵀs + c‖s‖₁ = −1 − rᵀx + c‖s‖₁
    # so 1 ≤ ‖r‖₁‖x‖∞ + c‖s‖₁; ignoring the c term only when c is negligible:
    radius = np.inf if r1 == 0 else 1.0 / r1
    valid = cone <= 1e-9 and radius >= CERTIFIED_RADIUS
    return Certificate(r1, cone, float(radius), len(b), bool(valid))


@dataclass(frozen=True)
class ClarabelQp:
    """:class:`~.base.QpSolver` by Clarabel (interior point: no warm start); an infeasible
    QP is answered 'infeasible' only with a certificate that checks out, else 'failed'."""

    @property
    def name(self) -> str:
        return "clarabel"

    def solve(self, eq: Equalities, pool: Pool, chosen: I, z0: F | None = None) -> QpSolution:
        t0 = time.perf_counter()
        A, b, m_eq, m_in = _standard_form(eq, pool, chosen)
        P = sp.triu(eq.P, format="csc")
        q = np.zeros(eq.layout.n)
        cones = [clarabel.ZeroConeT(m_eq)]
        if m_in:
            cones.append(clarabel.NonnegativeConeT(m_in))
        st = clarabel.DefaultSettings()
        st.verbose = False
        st.tol_gap_abs = 1e-9
        st.tol_gap_rel = 1e-10
        st.tol_feas = 1e-10
        sol = clarabel.DefaultSolver(P, q, A, b, cones, st).solve()
        status = str(sol.status)
        dt = time.perf_counter() - t0
        it = int(sol.iterations)
        S = clarabel.SolverStatus
        if sol.status in (S.PrimalInfeasible, S.AlmostPrimalInfeasible):
            cert = check_certificate(A, b, np.asarray(sol.z, float), m_eq)
            return QpSolution("clarabel", "infeasible" if cert.valid else "failed", chosen,
                              certificate=cert, iterations=it, seconds=time.perf_counter() - t0,
                              detail=status)
        if sol.status in (S.Solved, S.AlmostSolved):
            z_all = np.asarray(sol.z, float)
            zd = z_all[m_eq:]
            hi, lo = pool.hi[chosen], pool.lo[chosen]
            up, dn = np.isfinite(hi), np.isfinite(lo)
            y = np.zeros(chosen.size)
            y[up] += zd[: int(up.sum())]
            y[dn] -= zd[int(up.sum()):]
            return QpSolution("clarabel", "solved", chosen, np.asarray(sol.x, float),
                              z_all[:m_eq].copy(), y, iterations=it, seconds=dt, detail=status)
        return QpSolution("clarabel", "failed", chosen, iterations=it, seconds=dt, detail=status)
