"""A planned servo reference trajectory (the content of a plan file), and its summary."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan_report import ConstraintReport, InfeasibilityRecord
from spm_console.core.polytope.region import Region
from spm_console.core.regions.route import RegionRoute
from spm_console.core.servo.model import ServoModel

F = NDArray[np.float64]
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class PlanOptions:
    """What the planner was asked (MVN and minimum-time plans). Degrees, deg/s."""

    start_deg: Vec3
    """Start motor angles θ(0), deg."""
    goal_deg: Vec3
    """Goal motor angles, deg."""
    vmax_degps: float | None = None
    """Speed bound at the samples, deg/s (None: unbounded)."""
    intersample: int = 1
    """K: region and speed also enforced at K−1 instants inside each interval."""
    hold_first: bool = True
    """θ*(0) held at θ(0) (the paper's (30b))."""
    reference_limits_deg: tuple[Vec3 | None, Vec3 | None] | None = None
    """(lower, upper) bounds of the free references θ*(k), deg; None: unbounded."""


@dataclass(frozen=True)
class Plan:
    """References θ*(k) and the model's predicted θ(k), θ̇(k), k = 0..N (deg, deg/s)."""

    kind: Literal["mvn", "mintime", "synthetic", "homing", "jog", "experiment"]
    """What problem produced it."""
    Ts: float
    """Sampling interval, s."""
    reference_deg: F
    """(N+1, 3) references θ*(k), deg."""
    position_deg: F
    """(N+1, 3) model positions θ(k), deg."""
    velocity_degps: F
    """(N+1, 3) model velocities θ̇(k), deg/s."""
    region: Region
    """Region P the plan was constrained to."""
    model: ServoModel
    """Servo model the positions and velocities come from."""
    cost: float = float("nan")
    solve_seconds: float = float("nan")
    qp_count: int = 1
    profile_hash: str = ""
    options: PlanOptions | None = None
    """The planner's request (None for line and synthetic plans)."""
    check: ConstraintReport | None = None
    """The planner's constraint report (None for line and synthetic plans)."""
    certificate: InfeasibilityRecord | None = None
    """Minimum time: the record that N − 1 steps are infeasible."""
    solver: dict[str, Any] | None = None
    """Free-form solver diagnostics, only shown (never read back by key)."""
    route: RegionRoute | None = None
    """A plan across several regions: the regions in order and the switch samples
    (``region`` is then the first one); None for a plan inside ``region`` alone."""
    notes: dict[str, Any] = field(default_factory=dict)
    """Free-form details, only shown and kept in the file (never read back by key): a line
    plan's speed bound, ramp speed and move samples, a synthetic plan's duration, and any
    unknown keys of a plan file's 'extra'."""

    @property
    def regions(self) -> RegionRoute:
        """The route (one region when the plan has no route)."""
        return self.route if self.route is not None else RegionRoute.single(self.region)

    @property
    def N(self) -> int:
        return int(self.reference_deg.shape[0] - 1)

    @property
    def duration_s(self) -> float:
        return self.N * self.Ts

    def summary(self) -> PlanSummary:
        """What the front ends, run logs and plan files show of this plan."""
        return PlanSummary.of(self)


def _vec3(v: F) -> Vec3:
    a, b, c = (float(x) for x in v)
    return (a, b, c)


@dataclass(frozen=True)
class PlanSummary:
    """What is shown of a plan, built once from it: the CLI's ``plan`` output, a script's
    plan step, the console's plan text, a run log's record of its plans and a plan file's
    header all render this object. Degrees, deg/s, seconds."""

    kind: str
    """What problem produced it (:attr:`Plan.kind`)."""
    N: int
    """Intervals; the plan has N + 1 samples."""
    Ts: float
    """Sampling interval, s."""
    duration_s: float
    """N·Ts, s."""
    cost: float
    """The planner's cost, (deg/s)² (NaN for line and synthetic plans)."""
    solve_seconds: float
    """Wall time of the solve, s (NaN when not solved)."""
    qp_count: int
    """QPs solved."""
    start_deg: Vec3
    """Model position θ(0), deg."""
    goal_deg: Vec3
    """Model position θ(N), deg."""
    first_reference_deg: Vec3
    """First reference θ*(0), deg (θ(0) unless the first reference was left free)."""
    last_reference_deg: Vec3
    """Last reference θ*(N), deg (where the servos are told to stop)."""
    max_speed_degps: float
    """max |θ̇(k)| of the model at the samples, over the joints, deg/s."""
    vmax_degps: float | None
    """The speed bound the planner was given, deg/s (None: none recorded)."""
    halfspaces: int
    """Half-spaces of the (first) region."""
    profile_hash: str
    route: RegionRoute | None
    """The regions in order and the switch samples (None: one region)."""
    check: ConstraintReport | None
    """The planner's constraint report (None for line and synthetic plans)."""
    certificate: InfeasibilityRecord | None
    """Minimum time: the record that N − 1 steps are infeasible."""
    solver: dict[str, Any] | None
    """Free-form solver diagnostics."""

    @classmethod
    def of(cls, plan: Plan) -> PlanSummary:
        return cls(
            kind=plan.kind, N=plan.N, Ts=plan.Ts, duration_s=plan.duration_s, cost=plan.cost,
            solve_seconds=plan.solve_seconds, qp_count=plan.qp_count,
            start_deg=_vec3(plan.position_deg[0]), goal_deg=_vec3(plan.position_deg[-1]),
            first_reference_deg=_vec3(plan.reference_deg[0]),
            last_reference_deg=_vec3(plan.reference_deg[-1]),
            max_speed_degps=float(np.abs(plan.velocity_degps).max()),
            vmax_degps=None if plan.options is None else plan.options.vmax_degps,
            halfspaces=plan.region.halfspaces, profile_hash=plan.profile_hash,
            route=plan.route, check=plan.check, certificate=plan.certificate,
            solver=plan.solver)

    def figures(self) -> dict[str, Any]:
        """The figures every record of a plan names alike: kind, Ts, N, duration_s, cost,
        solve_seconds, qp_count (in that order)."""
        return {"kind": self.kind, "Ts": self.Ts, "N": self.N, "duration_s": self.duration_s,
                "cost": self.cost, "solve_seconds": self.solve_seconds,
                "qp_count": self.qp_count}

    @property
    def verified(self) -> bool | None:
        """The constraint report's verdict (None: the plan has no report)."""
        return None if self.check is None else self.check.ok

    def stored_region(self) -> str:
        """The region of a plan read from a file, in words."""
        if self.route is None:
            return f"stored in the plan ({self.halfspaces} half-spaces)"
        return f"stored in the plan: {self.route.describe()}"
