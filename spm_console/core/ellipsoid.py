"""Maximum-volume ellipsoid inscribed in a polytope (the MVIE step of IRIS).

E = {C y + d : ‖y‖ ≤ 1} ⊆ {x : A x ≤ b}  ⇔  ‖C a_i‖ + a_iᵀ d ≤ b_i for every row.
Maximize log det C (a convex problem, solved with cvxpy + Clarabel). The caller
should pass well-scaled coordinates (order 1).
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


def inscribed_ellipsoid(A: F, b: F) -> Ellipsoid:
    """The maximum-volume ellipsoid inside {x : A x ≤ b} (bounded, full-dimensional)."""
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
            Cv = np.asarray(C.value)
            Cv = 0.5 * (Cv + Cv.T)
            dv = np.asarray(d.value)
            # shrink slightly if the solver's tolerance put the ellipsoid outside
            over = (np.linalg.norm(A @ Cv, axis=1) + A @ dv - b).max()
            if over > 0:
                slack = b - A @ dv
                if (slack <= 0).any():
                    last = SolverError("inscribed ellipsoid: centre outside the polytope")
                    continue
                scale = float(np.min(slack / np.maximum(np.linalg.norm(A @ Cv, axis=1), 1e-300)))
                Cv = Cv * min(1.0, scale)
            return Ellipsoid(Cv, dv)
        last = SolverError(f"inscribed ellipsoid: solver status {prob.status}")
    raise SolverError(f"maximum-volume inscribed ellipsoid failed: {last}")
