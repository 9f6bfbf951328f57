"""Safety checks of the executor (pure logic over the profile's ``safety`` section).

Each check returns a :class:`StopReason` (kind, exit code, operator message) or
``None``. The executor applies the profile's stop action when one fires.
Angles in degrees, times in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.core.workspace.certify import CertifiedSet
from spm_console.devices.dynamixel.control_table import describe_hardware_error
from spm_console.errors import ExitCode

F = NDArray[np.float64]

StopKind = Literal["estop", "tracking", "comm", "hw_error", "region", "limit"]

EXIT_CODES: dict[str, ExitCode] = {
    "estop": ExitCode.STOP_ESTOP,
    "tracking": ExitCode.STOP_TRACKING,
    "comm": ExitCode.STOP_COMM,
    "hw_error": ExitCode.STOP_HW_ERROR,
    "region": ExitCode.STOP_REGION,
    "limit": ExitCode.STOP_LIMIT,
}

@dataclass(frozen=True)
class StopReason:
    """Why the executor stops."""

    kind: StopKind
    message: str
    """Operator message: what happened, where, and what to do."""
    t: float
    """Detection time since the run's first deadline, s."""
    k: int
    """Cycle of detection."""

    @property
    def exit_code(self) -> ExitCode:
        return EXIT_CODES[self.kind]


def _vec(v: F, digits: int = 2) -> str:
    return "[" + ", ".join(f"{float(x):.{digits}f}" for x in np.ravel(v)) + "]"


_EMULATED_HINT = ("on the emulated bus: an injected fault, or this machine did not run the emulated "
                  "servos in time (`spm-console latency` measures how late it wakes them)")
_SIMULATED_HINT = ("on the emulated bus in simulated time, where no reply can be late: an injected "
                   "fault, or the emulated servos' process is gone")


class SafetyMonitor:
    """Stateful checks: tracking, region, servo limits, communication, hardware errors."""

    def __init__(self, profile: Profile, certified: CertifiedSet | None = None, *,
                 emulated: bool = False, simulated_time: bool = False) -> None:
        self.cfg = profile.safety
        self.emulated = emulated
        """The emulated bus: a lost reply is then an injected fault or this machine's doing."""
        self.simulated_time = simulated_time
        """The emulated bus in simulated time: a lost reply is an injected fault or a gone
        emulator, never lateness."""
        self.certified = certified
        """The workspace's certified set: where a planned motion's measured position must stay."""
        self.region_half_width_deg = 0.0
        if certified is not None:
            # the margin relaxes the grid criterion (cube half-width Δ − margin), never
            # below the Δ/2 that still needs a feasible node on every axis
            step = certified.step_deg
            self.region_half_width_deg = step - min(self.cfg.region_margin_deg, 0.45 * step)
        self.lo, self.hi = servo_limits_deg(profile)
        self.ids = [j.id for j in profile.bus.joints]
        self.protocol = profile.bus.protocol
        self.comm_streak = 0
        """Consecutive failed cycles."""
        self.comm_failed_cycles = 0
        self.comm_retries = 0
        self.max_tracking_error_deg = 0.0

    def comm(self, ok: bool, retries: int, t: float, k: int, detail: str = "") -> StopReason | None:
        """Count one cycle's bus outcome; stop after ``comm_failures`` failed cycles in a row."""
        self.comm_retries += retries
        if ok:
            self.comm_streak = 0
            return None
        self.comm_streak += 1
        self.comm_failed_cycles += 1
        n = self.cfg.comm_failures
        if self.comm_streak >= n:
            return StopReason(
                "comm",
                f"communication lost: {n} consecutive bus cycles without a valid reply "
                f"(last: {detail or 'no status packet'}); " + (
                    (_SIMULATED_HINT if self.simulated_time else _EMULATED_HINT) if self.emulated
                    else "check the cable, power and port"),
                t, k,
            )
        return None

    def position(
        self, measured: F, predicted: F, in_workspace: bool, t: float, k: int
    ) -> StopReason | None:
        """Servo limits, then (``in_workspace``: a planned segment) the certified set with
        the region margin, then tracking error against the model."""
        out = (measured < self.lo) | (measured > self.hi)
        if out.any():
            i = int(np.argmax(out))
            return StopReason(
                "limit",
                f"joint {i + 1} measured at {measured[i]:.2f}° is outside its servo limits "
                f"[{self.lo[i]:.1f}, {self.hi[i]:.1f}]° (θ = {_vec(measured)}°)",
                t, k,
            )
        if in_workspace and self.certified is not None and not bool(
                self.certified.contains(measured, self.region_half_width_deg)):
            return StopReason(
                "region",
                f"position θ = {_vec(measured)}° left the workspace's certified feasible set "
                f"(region margin {self.cfg.region_margin_deg:.2f}°: no infeasible grid node "
                f"within {self.region_half_width_deg:.2f}°)",
                t, k,
            )
        err = np.abs(measured - predicted)
        e = float(err.max())
        self.max_tracking_error_deg = max(self.max_tracking_error_deg, e)
        if e > self.cfg.tracking_error_deg:
            i = int(np.argmax(err))
            return StopReason(
                "tracking",
                f"tracking error on joint {i + 1}: measured {measured[i]:.2f}° vs model "
                f"{predicted[i]:.2f}° ({e:.2f}° > {self.cfg.tracking_error_deg:.2f}°); "
                "the joint is blocked, overloaded or the servo model is wrong",
                t, k,
            )
        return None

    def hardware(self, errors: list[int], t: float, k: int) -> StopReason | None:
        """Any non-zero Hardware Error Status stops."""
        bad = [(i, e) for i, e in enumerate(errors) if e]
        if not bad:
            return None
        parts = [f"joint {i + 1} (id {self.ids[i]}): {describe_hardware_error(e, self.protocol)} (0x{e:02X})"
                 for i, e in bad]
        return StopReason(
            "hw_error",
            "servo hardware error: " + "; ".join(parts)
            + ". The servo must be rebooted (its goal reseeded to the measured position) "
            "before torque can come back",
            t, k,
        )

    @staticmethod
    def estop(reason: str, t: float, k: int) -> StopReason:
        return StopReason("estop", f"E-stop: {reason}", t, k)
