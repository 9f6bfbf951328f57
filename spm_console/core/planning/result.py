"""Result objects of the planners (objects, not tuples)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan, PlanOptions, Vec3
from spm_console.core.plan_report import ConstraintReport
from spm_console.core.planning.active_set import WorkingSet
from spm_console.core.planning.problem import PlanProblem

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
    working_set: WorkingSet | None = None
    """The pool rows at a bound at the optimum (certified by the KKT conditions): a warm
    start for a neighbouring problem with the same pool (another switch sample)."""

    @property
    def N(self) -> int:
        return self.problem.N

    def to_plan(self, kind: Literal["mvn", "mintime"] = "mvn", profile_hash: str = "") -> Plan:
        """The plan with what was asked (:class:`PlanOptions`), the constraint report and the
        solver's details."""
        pb = self.problem
        limits = None if pb.ref_lo_deg is None and pb.ref_hi_deg is None else \
            (_vec3(pb.ref_lo_deg), _vec3(pb.ref_hi_deg))
        options = PlanOptions(
            start_deg=_vec3_of(pb.start_deg), goal_deg=_vec3_of(pb.goal_deg),
            vmax_degps=None if pb.vmax_degps is None else float(pb.vmax_degps),
            intersample=pb.intersample, hold_first=pb.hold_first, reference_limits_deg=limits)
        return Plan(kind=kind, Ts=pb.model.ts, reference_deg=self.reference_deg,
                    position_deg=self.position_deg, velocity_degps=self.velocity_degps,
                    region=pb.region, model=pb.model, cost=self.cost,
                    solve_seconds=self.solve_seconds, qp_count=self.qp_count,
                    profile_hash=profile_hash, options=options, check=self.check,
                    solver=dict(self.info),
                    route=pb.route if pb.route is not None and pb.route.count > 1 else None)


def _vec3_of(v: F) -> Vec3:
    a, b, c = (float(x) for x in np.asarray(v, float).reshape(3))
    return a, b, c


def _vec3(v: F | None) -> Vec3 | None:
    return None if v is None else _vec3_of(v)
