"""One interface for the planner's QP solvers, and a solution that checks itself.

The reduced QP of (30): min ½ zᵀPz s.t. C z = d, lo ≤ G z ≤ hi on the pool rows chosen
(:mod:`spm_console.core.planning.qp_build`). A solver answers a :class:`QpSolution`: its
status, the point, the multipliers in one sign convention (Pz + Cᵀy_eq + Gᵀy_pool = 0,
y_pool > 0 at an upper bound and < 0 at a lower one), and, for an infeasible problem, a
checked Farkas certificate. :meth:`QpSolution.residuals` measures the primal and dual
residuals and the duality gap from those numbers alone, whichever solver gave them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan_report import Certificate
from spm_console.core.planning.qp_build import Equalities, Pool

F = NDArray[np.float64]
I = NDArray[np.int64]

QpStatus = Literal["solved", "infeasible", "failed"]


@dataclass(frozen=True)
class Residuals:
    """How well a point and its multipliers satisfy the KKT conditions (∞-norms)."""

    primal: float
    """Largest equality residual |Cz − d| or bound violation of a chosen row."""
    dual: float
    """Largest entry of Pz + Cᵀy_eq + Gᵀy_pool (the stationarity residual)."""
    gap: float
    """|primal objective − dual objective|: zᵀPz + dᵀy_eq + hiᵀ·y⁺ + loᵀ·y⁻ (q = 0)."""


@dataclass(frozen=True)
class QpSolution:
    """What a :class:`QpSolver` answers for one reduced QP."""

    solver: str
    """Which solver ('osqp', 'clarabel', …)."""
    status: QpStatus
    """'solved', 'infeasible' (a certificate that checks out) or 'failed'."""
    chosen: I
    """The pool rows the QP held."""
    z: F | None = None
    """The point (None unless solved)."""
    y_eq: F | None = None
    """Multipliers of the equalities."""
    y_pool: F | None = None
    """Multipliers of the chosen pool rows (> 0 at the upper bound, < 0 at the lower)."""
    certificate: Certificate | None = None
    """A checked Farkas certificate of infeasibility (a solver that gives one)."""
    iterations: int = 0
    seconds: float = 0.0
    detail: str = ""
    """The solver's own status words."""
    polished: bool = False
    """OSQP: its solution polishing succeeded."""

    @property
    def solved(self) -> bool:
        return self.status == "solved" and self.z is not None and self.y_pool is not None

    def residuals(self, eq: Equalities, pool: Pool) -> Residuals:
        """The KKT residuals of a solved QP, computed here (not the solver's report)."""
        if self.z is None or self.y_pool is None or self.y_eq is None:
            raise ValueError("only a solved QP has residuals")
        z, y = self.z, self.y_pool
        lo, hi = pool.lo[self.chosen], pool.hi[self.chosen]
        G = pool.rows(self.chosen)
        gz = G @ z
        with np.errstate(invalid="ignore"):
            over = np.concatenate([np.abs(eq.C @ z - eq.d), np.maximum(gz - hi, 0.0),
                                   np.maximum(lo - gz, 0.0), [0.0]])
        stationarity = eq.P @ z + eq.C.T @ self.y_eq + G.T @ y
        up, dn = np.maximum(y, 0.0), np.minimum(y, 0.0)
        # a multiplier on an infinite bound must be zero (dual feasibility): its size counts
        # as a dual residual, and it adds nothing to the gap
        fin_hi, fin_lo = np.isfinite(hi), np.isfinite(lo)
        off = np.concatenate([up[~fin_hi], -dn[~fin_lo], [0.0]])
        bound_terms = np.where(fin_hi, hi, 0.0) @ up + np.where(fin_lo, lo, 0.0) @ dn
        gap = float(z @ (eq.P @ z) + eq.d @ self.y_eq + bound_terms)
        dual = max(float(np.abs(stationarity).max(initial=0.0)), float(off.max()))
        return Residuals(float(np.nanmax(over)), dual, abs(gap))


class QpSolver(Protocol):
    """A solver of the reduced QP of (30)."""

    @property
    def name(self) -> str: ...

    def solve(self, eq: Equalities, pool: Pool, chosen: I, z0: F | None = None) -> QpSolution:
        """Solve with the equalities and the pool rows ``chosen`` (``z0``: a warm start, for a
        solver that takes one)."""
        ...
