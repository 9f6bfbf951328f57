"""Maximum-volume ellipsoid inscribed in a polytope (the MVIE step of IRIS).

E = {C y + d : ‖y‖ ≤ 1} ⊆ {x : A x ≤ b}  ⇔  ‖C a_i‖ + a_iᵀ d ≤ b_i for every row.
Maximize log det C, a convex problem. It is handed to Clarabel directly in conic form
(:func:`_conic_mvie`: the 3-D problem is small, and building it through cvxpy cost ten times
the solve); cvxpy with Clarabel, then SCS, is the fallback. The caller should pass
well-scaled coordinates (order 1).

Conic form (Ben-Tal & Nemirovski's log det): variables C (symmetric), d, a lower-triangular
Z and t; maximize Σ t_k subject to (b_i − a_iᵀ d, C a_i) in the second-order cone for every
row, [[C, Z], [Zᵀ, Diag(Z)]] positive semidefinite (then log det C ≥ Σ log Z_kk), and
(t_k, 1, Z_kk) in the exponential cone (e^{t_k} ≤ Z_kk).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.errors import SolverError

F = NDArray[np.float64]


@dataclass(frozen=True)
class Ellipsoid:
    """E = {C y + d : ‖y‖ ≤ 1}, C symmetric positive definite."""

    C: F
    d: F

    @property
    def log_volume(self) -> float:
        """log det C (volume up to the constant 4π/3)."""
        return float(np.linalg.slogdet(self.C)[1])

    def metric(self) -> F:
        """M = (C Cᵀ)⁻¹: (x − d)ᵀ M (x − d) ≤ 1 inside E."""
        Ci = np.linalg.inv(self.C)
        return np.asarray(Ci.T @ Ci)

    @classmethod
    def ball(cls, center: F, radius: float) -> Ellipsoid:
        return cls(np.eye(len(center)) * radius, np.asarray(center, float))


#: Variable layout of the conic form: C's upper triangle (C00 C01 C11 C02 C12 C22), d, Z's
#: lower triangle (Z00 Z10 Z11 Z20 Z21 Z22), t.
_C_AT = np.array([[0, 1, 3], [1, 2, 4], [3, 4, 5]])
_D0, _Z0, _T0, _NV = 6, 9, 15, 18
_Z_AT = {(0, 0): 9, (1, 0): 10, (1, 1): 11, (2, 0): 12, (2, 1): 13, (2, 2): 14}


def _psd_rows() -> tuple[list[int], list[int], list[float]]:
    """(row, variable, coefficient) of −svec([[C, Z], [Zᵀ, Diag(Z)]]): Clarabel's triangle
    (upper, column by column, off-diagonal entries times √2)."""
    rows: list[int] = []
    cols: list[int] = []
    vals: list[float] = []
    r = 0
    for col in range(6):
        for row in range(col + 1):
            scale = 1.0 if row == col else float(np.sqrt(2.0))
            var = None
            if col < 3:
                var = int(_C_AT[row, col])
            elif row < 3 and col - 3 <= row:
                var = _Z_AT[(row, col - 3)]
            elif row == col:
                var = _Z_AT[(row - 3, row - 3)]
            if var is not None:
                rows.append(r)
                cols.append(var)
                vals.append(-scale)
            r += 1
    return rows, cols, vals


_PSD = _psd_rows()


def _conic_mvie(A: F, b: F) -> tuple[F, F] | None:
    """(C, d) of the maximum-volume inscribed ellipsoid from Clarabel on the conic form of the
    module docstring, or None when Clarabel does not report it solved. 3-D only."""
    import clarabel  # here: only a build grows ellipsoids
    from scipy import sparse

    m = len(A)
    # second-order cones, rows 4i..4i+3: s = (b_i − a_iᵀ d, C a_i); with Ax + s = h:
    # row 4i holds a_i on d, row 4i+1+r holds −a_ic on C[r, c]
    i3, k3 = np.repeat(np.arange(m), 3), np.tile(np.arange(3), m)
    i9 = np.repeat(np.arange(m), 9)
    r9, c9 = np.tile(np.repeat(np.arange(3), 3), m), np.tile(np.arange(3), 3 * m)
    rows = [4 * i3, 4 * i9 + 1 + r9]
    cols = [_D0 + k3, _C_AT[r9, c9]]
    vals = [A[i3, k3], -A[i9, c9]]
    h = np.zeros(4 * m + 21 + 9)
    h[4 * np.arange(m)] = b
    base = 4 * m
    pr, pc, pv = _PSD
    rows.append(base + np.asarray(pr))
    cols.append(np.asarray(pc))
    vals.append(np.asarray(pv))
    base += 21
    for q in range(3):  # exponential cones: s = (t_q, 1, Z_qq)
        rows.append(np.array([base, base + 2]))
        cols.append(np.array([_T0 + q, _Z_AT[(q, q)]]))
        vals.append(np.array([-1.0, -1.0]))
        h[base + 1] = 1.0
        base += 3
    Am = sparse.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                           shape=(base, _NV))
    q_obj = np.zeros(_NV)
    q_obj[_T0:] = -1.0
    cones = ([clarabel.SecondOrderConeT(4)] * m + [clarabel.PSDTriangleConeT(6)]
             + [clarabel.ExponentialConeT()] * 3)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    sol = clarabel.DefaultSolver(sparse.csc_matrix((_NV, _NV)), q_obj, Am, h, cones,
                                 settings).solve()
    if str(sol.status) not in ("Solved", "AlmostSolved"):
        return None
    x = np.asarray(sol.x, float)
    if not np.all(np.isfinite(x)):
        return None
    return x[_C_AT], x[_D0:_Z0]


def _fitted(A: F, b: F, Cv: F, dv: F) -> Ellipsoid | None:
    """The solver's (C, d), symmetrized and shrunk if its tolerance put E outside the
    polytope; None when the centre itself is outside or C is not positive definite."""
    Cv = 0.5 * (Cv + Cv.T)
    if np.linalg.eigvalsh(Cv)[0] <= 0:
        return None
    over = (np.linalg.norm(A @ Cv, axis=1) + A @ dv - b).max()
    if over > 0:
        slack = b - A @ dv
        if (slack <= 0).any():
            return None
        scale = float(np.min(slack / np.maximum(np.linalg.norm(A @ Cv, axis=1), 1e-300)))
        Cv = Cv * min(1.0, scale)
    return Ellipsoid(Cv, np.asarray(dv, float))


def inscribed_ellipsoid(A: F, b: F) -> Ellipsoid:
    """The maximum-volume ellipsoid inside {x : A x ≤ b} (bounded, full-dimensional)."""
    if A.shape[1] == 3:
        got = _conic_mvie(A, b)
        if got is not None:
            E = _fitted(A, b, *got)
            if E is not None:
                return E
    return _cvxpy_mvie(A, b)


def _cvxpy_mvie(A: F, b: F) -> Ellipsoid:
    """The fallback (any dimension): cvxpy with Clarabel, then SCS."""
    import cvxpy as cp  # here, not at import: loading cvxpy costs ~0.4 s per process

    n = A.shape[1]
    C = cp.Variable((n, n), PSD=True)
    d = cp.Variable(n)
    cons = [cp.norm(A @ C, axis=1) + A @ d <= b]
    prob = cp.Problem(cp.Maximize(cp.log_det(C)), cons)
    last: Exception | None = None
    for solver in (cp.CLARABEL, cp.SCS):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # accuracy is checked below
                prob.solve(solver=solver)
        except cp.error.SolverError as exc:  # pragma: no cover - solver-specific
            last = exc
            continue
        if prob.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and C.value is not None:
            E = _fitted(A, b, np.asarray(C.value), np.asarray(d.value))
            if E is None:
                last = SolverError("inscribed ellipsoid: degenerate, or its centre outside the "
                                   "polytope")
                continue
            return E
        last = SolverError(f"inscribed ellipsoid: solver status {prob.status}")
    raise SolverError(f"maximum-volume inscribed ellipsoid failed: {last}")
