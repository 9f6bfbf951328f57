"""A planned servo reference trajectory (the content of a plan file, SPEC §5)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.region import Region

F = NDArray[np.float64]


@dataclass(frozen=True)
class Plan:
    """References θ*(k) and the model's predicted θ(k), θ̇(k), k = 0..N (deg, deg/s)."""

    kind: Literal["mvn", "mintime", "synthetic", "homing"]
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
    model: dict[str, Any]
    """Servo model used: {A, B, p, Ts, discretization}."""
    cost: float = float("nan")
    solve_seconds: float = float("nan")
    qp_count: int = 1
    profile_hash: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    """Anything else worth keeping (vmax, N−1 infeasibility certificate, between-sample checks)."""

    @property
    def N(self) -> int:
        return int(self.reference_deg.shape[0] - 1)

    @property
    def duration_s(self) -> float:
        return self.N * self.Ts
