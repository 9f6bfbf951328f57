"""The one small interface between orchestration (executor, homing, UI) and a servo bus.

Implemented by the real Dynamixel bus over a serial port (real hardware or the
emulator's pseudo-terminal) or the emulator's socket. Angles are joint angles θ in degrees (the profile's
tick mapping is applied inside the bus); times in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from spm_console.errors import BusError

F = NDArray[np.float64]


class CommError(Exception):
    """One bus transaction failed (timeout; corrupted, missing or stale status packet).

    Not an operator error by itself: the executor counts and retries these and
    stops after the profile's number of consecutive failures.
    """


@dataclass(frozen=True)
class ServoStatus:
    """What a ping / status read says about one servo."""

    id: int
    model_number: int
    firmware: int | None = None
    hardware_error: int = 0
    """Hardware Error Status bits (0 = fine)."""
    temperature_c: float | None = None
    voltage_v: float | None = None
    extra: dict[str, float] = field(default_factory=dict)


@runtime_checkable
class ServoBus(Protocol):
    """Three servos driving joints 1..3 (order of the profile's ``bus.joints``)."""

    def ping_all(self) -> list[ServoStatus]:
        """Ping every joint's servo; raises BusError if one is absent or of the wrong model."""
        ...

    def set_torque(self, on: bool) -> None:
        """Torque Enable on all three servos."""
        ...

    def write_goal_deg(self, theta_deg: F) -> None:
        """Sync-write Goal Position for the three joints (deg); refuses targets outside limits."""
        ...

    def read_position_deg(self) -> F:
        """Sync-read (2.0) / bulk-read (1.0) Present Position of the three joints (deg).

        Raises CommError when a reply is missing or corrupt.
        """
        ...

    def hardware_errors(self) -> list[int]:
        """Hardware Error Status of each joint's servo (0 = fine)."""
        ...

    def drain_input(self, quiet_s: float) -> int:
        """Discard late replies until the line is quiet for ``quiet_s``; bytes discarded."""
        ...

    def close(self) -> None:
        ...


#: Quiet time on the line before a set-up read is retried.
SETUP_QUIET_S = 0.02


def read_position_settled(bus: ServoBus, attempts: int) -> F:
    """Present Position for set-up, never for the real-time loop: up to ``attempts`` tries,
    the line drained between them, so a late reply to a failed try is not taken for the
    next one's. Raises the last CommError/OSError when every try failed."""
    for k in range(attempts):
        try:
            return np.asarray(bus.read_position_deg(), float)
        except (CommError, OSError):
            if k == attempts - 1:
                raise
            bus.drain_input(SETUP_QUIET_S)
    raise AssertionError("unreachable")


def read_position_checked(bus: ServoBus, attempts: int) -> F:
    """:func:`read_position_settled` for operators: every try failed → BusError (exit 10)
    that says what to check. The one set-up read of the runtime (homing, execution, the
    console's 'read')."""

    try:
        return read_position_settled(bus, attempts)
    except (CommError, OSError) as exc:
        last = str(exc) or type(exc).__name__
    raise BusError(f"no position reply from the servos after {attempts} tries ({last}); "
                   "check power, wiring, baud rate and ids (`spm-console servo ping`)")
