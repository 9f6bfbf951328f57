"""Result objects of the planners (STYLE §8: results are objects, not tuples)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.verify import ConstraintReport

F = NDArray[np.float64]


@dataclass(frozen=True)
class PlanResult:
    """An optimal reference for one horizon N (MVN (30), or the last QP of (31))."""

    status: Literal["optimal"]
    problem: PlanProblem
    reference_deg: F
    """(N+1, 3) θ*(k), deg; θ*(N) = goal."""
    position_deg: F
    """(N+1, 3) model positions θ(k) under the references, deg."""
    velocity_degps: F
    """(N+1, 3) model velocities θ̇(k), deg/s."""
    cost: float
    """Σ_k θ̇(k)ᵀθ̇(k), (deg/s)²."""
    solve_seconds: float
    """Wall time of building and solving, s."""
    qp_count: int
    check: ConstraintReport
    info: dict[str, Any] = field(default_factory=dict)
    """Solver details: screening rounds, rows used, iterations, polished."""

    @property
    def N(self) -> int:
        return self.problem.N

    def to_plan(self, kind: Literal["mvn", "mintime"] = "mvn", profile_hash: str = "",
                extra: dict[str, Any] | None = None) -> Plan:
        pb = self.problem
        ex: dict[str, Any] = {
            "start_deg": pb.start_deg.tolist(),
            "goal_deg": pb.goal_deg.tolist(),
            "vmax_degps": pb.vmax_degps,
            "intersample": pb.intersample,
            "hold_first": pb.hold_first,
            "reference_limits_deg": None if pb.ref_lo_deg is None and pb.ref_hi_deg is None else
            [None if pb.ref_lo_deg is None else pb.ref_lo_deg.tolist(),
             None if pb.ref_hi_deg is None else pb.ref_hi_deg.tolist()],
            "check": self.check.to_dict(),
            "solver": self.info,
        }
        ex.update(extra or {})
        return Plan(kind=kind, Ts=pb.model.ts, reference_deg=self.reference_deg,
                    position_deg=self.position_deg, velocity_degps=self.velocity_degps,
                    region=pb.region, model=pb.model.to_dict(), cost=self.cost,
                    solve_seconds=self.solve_seconds, qp_count=self.qp_count,
                    profile_hash=profile_hash, extra=ex)
