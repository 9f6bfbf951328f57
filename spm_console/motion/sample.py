"""One executor cycle's telemetry (what the UI and the run log receive)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]


@dataclass(frozen=True)
class Sample:
    """Telemetry of cycle k. Angles in degrees, velocities in deg/s, times in seconds.

    ``measured_deg`` is NaN when the bus read of this cycle failed (after retries).
    """

    t: float
    """Time of the cycle's start since the run's first deadline, s."""
    k: int
    """Cycle index over the whole run (all phases)."""
    phase: str
    """Which segment of the run: 'homing', 'approach', 'plan'."""
    reference_deg: F
    """θ*(k) sent this cycle (3,)."""
    measured_deg: F
    """θ(k) read back (3,), NaN when the read failed."""
    predicted_deg: F
    """Model (28) simulated open loop from the start under the references (3,)."""
    predicted_velocity_degps: F
    """Model velocity (3,)."""
    filtered_deg: F
    """Kalman-filtered position (3,) at the read instant k·Ts + read_offset_s."""
    velocity_degps: F
    """Kalman-filtered velocity (3,) at the read instant."""
    fd_velocity_degps: F
    """Backward finite difference of the measured positions (3,), the baseline."""
    tracking_error_deg: float
    """max_i |measured − model at the read instant| (NaN when the read failed); the
    safety check's quantity."""
    bus_s: float
    """Time spent on the bus this cycle (write + read + retries), s."""
    late_s: float
    """How late the cycle started after its absolute deadline, s."""
    retries: int = 0
    """Read retries needed this cycle."""
    read_offset_s: float = 0.0
    """When the (successful) read was sent, after the cycle's deadline k·Ts, s (NaN when
    the read failed)."""
    target_deg: F | None = None
    """Live following: the target the reference was re-planned toward (3,), deg; None for
    planned motions."""
    target_clamp_deg: float | None = None
    """Live following: how far the follower's projection moved the target of the plan in use,
    deg, when that target lay outside its region or the servo limits (the plan is then
    clamped to the edge); 0 when it lay inside; None for planned motions."""
    stale_replies: int = 0
    """Stale status packets the bus discarded since the run began, up to this cycle (late
    replies to earlier requests, or replies nothing asked for; not in samples.csv)."""

    @property
    def read_ok(self) -> bool:
        return bool(np.all(np.isfinite(self.measured_deg)))
