"""What one receding-horizon solve of the follow QP answers (:mod:`.solver`).

Angles in degrees, speeds in deg/s, times in seconds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]

FollowStatus = Literal["reached", "tracking", "infeasible", "failed"]


@dataclass(frozen=True)
class FollowResult:
    """One receding-horizon solve (angles deg, speeds deg/s, time s)."""

    status: FollowStatus
    """'reached' (θ(H) = target, at rest), 'tracking' (terminal cost active: target not
    reachable within the horizon), 'infeasible' (refused: state outside the region or no
    admissible reference), 'failed' (solver did not converge or the check failed)."""
    reference_deg: F
    """(H, 3) θ*(0..H−1); row 0 is what the loop streams now. (0, 3) when not ok."""
    position_deg: F
    """(H+1, 3) predicted θ(0..H) (row 0 = the given state). (0, 3) when not ok."""
    velocity_degps: F
    """(H+1, 3) predicted θ̇(0..H). (0, 3) when not ok."""
    requested_deg: F
    """(3,) terminal target as given."""
    target_deg: F
    """(3,) terminal target used (projected when the given one was outside)."""
    clamped: bool
    """A given target (terminal or preview sample) was outside the region or the limits."""
    clamp_deg: float
    """Largest distance a target was moved by the projection, deg (≤ 2·margin_deg when
    not clamped)."""
    cost: float
    """Objective value on the predicted trajectory."""
    terminal_error_deg: float
    """‖θ(H) − target‖∞, deg (inf when not ok)."""
    seconds: float
    """Wall time of the whole solve call, s."""
    iterations: int
    warm: bool
    """Warm-started from the previous solution."""
    reason: str = ""
    """Why a result is not ok; empty otherwise."""
    detail: str = ""
    """Solver status text."""

    @property
    def ok(self) -> bool:
        return self.status in ("reached", "tracking")

    @property
    def horizon(self) -> int:
        return int(self.reference_deg.shape[0])

    @property
    def first_reference_deg(self) -> F:
        """θ*(0): the reference to send this period."""
        if not self.ok:
            raise ValueError(f"no reference: the follow solve is {self.status} ({self.reason})")
        return np.asarray(self.reference_deg[0])

    def reference_at(self, periods: int) -> F:
        """The reference ``periods`` periods after this solve (0 = the first), held at θ(H)
        past the horizon: what to stream when later solves miss their deadline."""
        if not self.ok:
            raise ValueError(f"no reference: the follow solve is {self.status} ({self.reason})")
        if periods < self.horizon:
            return np.asarray(self.reference_deg[max(periods, 0)])
        return np.asarray(self.position_deg[-1])
