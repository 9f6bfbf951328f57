"""A planned servo reference trajectory (the content of a plan file)."""

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

    kind: Literal["mvn", "mintime", "synthetic", "homing", "jog"]
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
