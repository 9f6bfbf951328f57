"""A run's transactions on the servo bus: :class:`BusLoop`, the base of the executor.

Before the first cycle: the hardware error status, the Bus Watchdog armed, the goal seeded at
the measured position and torque on (:meth:`BusLoop._preflight`; set-up transactions are
retried on isolated losses). Every cycle: θ*(k) written, θ(k) read with retries (a cycle whose
reads all fail counts as a communication failure), the hardware error status polled. After
the run: the Bus Watchdog off. Each transaction is logged in the run log. Degrees and seconds.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.devices.base import SETUP_QUIET_S, CommError, ServoBus, read_position_checked
from spm_console.errors import BusError
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.safety import SafetyMonitor, StopReason

F = NDArray[np.float64]
BusFailure = (CommError, OSError, BusError)
"""What counts as one failed bus transaction (a serial exception is an OSError; a status
packet carrying an error number raises BusError)."""


class BusLoop:
    """The bus side of a servo loop: its transactions, timed on ``clock`` and logged in ``log``
    (times since :attr:`t0`)."""

    def __init__(self, profile: Profile, bus: ServoBus, *, log: RunLog | None, read_retries: int,
                 clock: Callable[[], float]) -> None:
        self.profile = profile
        self.bus = bus
        self.log = log
        self.read_retries = read_retries
        self.clock = clock
        self.t0 = 0.0
        """perf_counter time of the first deadline (t = 0 of the samples)."""
        self._torque_on = False
        self._watchdog_armed = False

    def _now(self) -> float:
        return self.clock() - self.t0

    def _event(self, name: str, /, **data: Any) -> None:
        if self.log is not None:
            self.log.event(name, self._now(), **data)

    def read_initial(self, attempts: int = 5) -> F:
        """Measured position before any motion; BusError if the servos stay silent."""
        return read_position_checked(self.bus, attempts)

    def _release_watchdog(self) -> None:
        """After the run: Bus Watchdog off, so the servos keep their last goal (done or hold).

        If the bus does not answer, the watchdog stays armed and stops the servos itself.
        """
        set_watchdog = getattr(self.bus, "set_watchdog", None)
        if set_watchdog is None or not self._watchdog_armed:
            return
        try:
            set_watchdog(0)
            self._event("watchdog", ms=0, units=0)
        except BusFailure as exc:
            self._event("watchdog_left_armed", error=str(exc))

    def _retry(self, what: str, fn: Callable[[], Any], attempts: int = 10) -> Any:
        """A set-up transaction, retried on isolated losses; BusError when all fail."""
        last: Exception | None = None
        for _ in range(attempts):
            try:
                return fn()
            except BusFailure as exc:
                last = exc
                self._event("comm_retry", op=what, error=str(exc))
                self.bus.drain_input(SETUP_QUIET_S)
        raise BusError(f"cannot {what} after {attempts} tries: {last}; nothing moved")

    def _preflight(self, theta0: F) -> StopReason | None:
        """Hardware errors before motion; watchdog; seed the goal at θ0 and torque on."""
        hw = self._retry("read the hardware error status", self.bus.hardware_errors)
        reason = SafetyMonitor(self.profile).hardware(hw, 0.0, 0)
        if reason is not None:
            self._event("fault", kind=reason.kind, message=reason.message, errors=hw)
            return reason
        watchdog_ms = self.profile.safety.watchdog_ms
        set_watchdog = getattr(self.bus, "set_watchdog", None)
        if set_watchdog is not None and watchdog_ms > 0:
            # also clears a watchdog tripped after an earlier run (2.0; no-op on 1.0)
            units = self._retry("set the Bus Watchdog", lambda: set_watchdog(watchdog_ms))
            self._watchdog_armed = bool(units)
            self._event("watchdog", ms=watchdog_ms, units=units)
        elif watchdog_ms == 0 and self.profile.safety.watchdog_off_reason:
            self._event("watchdog_off", reason=self.profile.safety.watchdog_off_reason)
        # reseed the goal before torque on: no lunge (a sync write has no reply to confirm)
        self._retry("write the goal", lambda: self.bus.write_goal_deg(theta0))
        self._torque_on = True  # from here on a failure must apply the stop action
        self._retry("enable torque", lambda: self.bus.set_torque(True))
        self._event("torque_on", goal_deg=theta0)
        return None

    def _cycle_io(self, ref: F) -> tuple[F | None, int, str, float]:
        """Write θ*(k), read θ(k) with retries.

        Returns (θ or None, failed attempts, last error, clock time the good read was sent).
        """
        detail = ""
        try:
            self.bus.write_goal_deg(ref)
        except BusFailure as exc:
            detail = f"write failed: {exc}"
            self._event("comm_retry", op="write", error=str(exc))
        failed = 0
        for _ in range(1 + self.read_retries):
            try:
                t_read = self.clock()
                return np.asarray(self.bus.read_position_deg(), float), failed, "", t_read
            except BusFailure as exc:
                failed += 1
                detail = str(exc) or type(exc).__name__
                self._event("comm_retry", op="read", error=detail)
        self._event("comm_fail", error=detail, attempts=failed)
        return None, failed, detail, float("nan")

    def _alerted(self) -> bool:
        """The alert flag of the last status packets, when the bus exposes it (``alerts``)."""
        alerts = getattr(self.bus, "alerts", None)
        return isinstance(alerts, dict) and any(alerts.values())

    def _poll_hw(self, safety: SafetyMonitor, t: float, k: int) -> StopReason | None:
        try:
            errors = self.bus.hardware_errors()
        except BusFailure as exc:
            self._event("comm_retry", op="hardware_errors", error=str(exc))
            return None
        return safety.hardware(errors, t, k)
