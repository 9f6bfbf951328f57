"""A run's stops: :class:`StoppableLoop`, E-stop requests, the deadline waits they interrupt
and the profile's stop action applied and logged.

Any stop applies ``safety.stop_action`` at once (:func:`~spm_console.motion.stop_action.apply_stop_action`:
hold, the measured position clipped to the servo limits written now and again at the next
deadline; or torque_off); its instants (detected, issued, done) go to the run log. Degrees and
seconds.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.devices.base import ServoBus
from spm_console.motion.cycle.transactions import BusLoop
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.safety import StopReason
from spm_console.motion.stop_action import apply_stop_action

F = NDArray[np.float64]


class StoppableLoop(BusLoop):
    """A servo loop that stops: :meth:`request_estop` may be called from any thread."""

    def __init__(self, profile: Profile, bus: ServoBus, *, log: RunLog | None, read_retries: int,
                 spin_s: float, clock: Callable[[], float],
                 sleep: Callable[[float], None] | None) -> None:
        super().__init__(profile, bus, log=log, read_retries=read_retries, clock=clock)
        self.spin_s = spin_s
        self.sleep = sleep
        """Replaces the real waiting when given (tests drive a simulated clock with it)."""
        self.lo, self.hi = servo_limits_deg(profile)
        self._estop = threading.Event()
        self._estop_reason = ""
        self._estop_by_signal = False
        self._estop_clock: float | None = None
        """Clock time of the first E-stop request (logged with the stop as ``requested_t``)."""

    def request_estop(self, reason: str = "operator request", at_clock: float | None = None,
                      by_signal: bool = False) -> None:
        """Thread-safe: stop at once (wakes the loop if it is waiting for a deadline).
        ``at_clock``: when the request was made (this executor's clock), if earlier than now;
        ``by_signal``: a terminating signal asked (before the first reference, the run is then
        an interruption, exit 130, as a signal before any motion always is)."""
        if not self._estop.is_set():
            self._estop_clock = self.clock() if at_clock is None else at_clock
            self._estop_by_signal = by_signal
        self._estop_reason = reason
        self._estop.set()

    def _wait_until(self, deadline: float) -> None:
        """Sleep (interruptible by E-stop), then spin the last ``spin_s`` for precision."""
        while True:
            rem = deadline - self.clock()
            if rem <= 0.0 or self._estop.is_set():
                return
            if self.sleep is not None:
                self.sleep(rem)
            elif rem > self.spin_s:
                self._estop.wait(rem - self.spin_s)
            else:
                time.sleep(0)

    def _hold_target(self, measured: F) -> F:
        return np.clip(measured, self.lo, self.hi)

    def _apply_stop(self, stop: StopReason, hold: F, deadline: float | None) -> None:
        """The profile's stop action, issued now (and the hold goal again at ``deadline``)."""
        self._event("fault", kind=stop.kind, message=stop.message, detected_t=stop.t, k=stop.k)
        action = self.profile.safety.stop_action
        repeat = None if deadline is None else (lambda: self._wait_until_plain(deadline))
        done = apply_stop_action(self.bus, action, hold, self._now, repeat, stop.kind == "comm")
        t_issue, t_done, notes = done.issued_t, done.done_t, done.notes
        requested = None if self._estop_clock is None else self._estop_clock - self.t0
        self._event("stop", kind=stop.kind, requested_t=requested if stop.kind == "estop" else None,
                    action=action, hold_deg=hold if action == "hold"
                    else None, detected_t=stop.t, issued_t=t_issue, done_t=t_done, notes=notes,
                    exit_code=int(stop.exit_code))
        self.stop_timing = (t_issue, t_done)

    def _wait_until_plain(self, deadline: float) -> None:
        while (rem := deadline - self.clock()) > 0:
            (self.sleep or time.sleep)(min(rem, 0.002))
