"""The profile's stop action on the bus: hold the measured position (the goal written twice,
the second time at the next deadline) or switch the torque off (up to three tries); and the
E-stop the motion process holds for the motion it is meant for (:class:`PendingStop`).

Used by the executor for every stop (E-stop, tracking, communication, hardware error,
region, limits). A failed write is noted, never raised: the stop must go on, and with the
link down the servos' Bus Watchdog stops them. Degrees, seconds.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.devices.base import CommError, ServoBus
from spm_console.errors import BusError, SpmError

F = NDArray[np.float64]


@dataclass(frozen=True)
class StopActionDone:
    issued_t: float
    done_t: float
    notes: list[str]
    """Writes that failed, and what still stops the servos then."""


def apply_stop_action(bus: ServoBus, action: Literal["hold", "torque_off"], hold_deg: F,
                      now: Callable[[], float], wait_for_repeat: Callable[[], None] | None,
                      comm_lost: bool) -> StopActionDone:
    """Issue ``action`` now; ``wait_for_repeat`` waits until the hold goal's second write."""
    t_issue = now()
    notes: list[str] = []
    if action == "hold":
        for attempt in range(2):
            try:
                bus.write_goal_deg(np.asarray(hold_deg, float))
            except (CommError, OSError, BusError, SpmError) as exc:
                notes.append(f"hold write {attempt + 1} failed: {exc}")
            if attempt == 0 and wait_for_repeat is not None:
                wait_for_repeat()
    else:
        for attempt in range(3):
            try:
                bus.set_torque(False)
                break
            except (CommError, OSError, BusError, SpmError) as exc:
                notes.append(f"torque off {attempt + 1} failed: {exc}")
    t_done = now()
    if notes and comm_lost:
        notes.append("the servos' Bus Watchdog stops them if the link is down")
    return StopActionDone(t_issue, t_done, notes)


class Stoppable(Protocol):
    """What an E-stop reaches: the executor of the motion under way."""

    def request_estop(self, reason: str = ..., at_clock: float | None = ...,
                      by_signal: bool = ...) -> None: ...


@dataclass
class PendingStop:
    """The E-stop the motion process holds (any thread; one lock).

    An E-stop is for the motion under way, or for the next one when it comes between two (the
    front end marks the wrist moving before its request is sent, so an E-stop can arrive first).
    Each E-stop says ``after``: the id of the last motion whose result its sender had. One that
    comes when a later motion has ended was meant for that motion, which ended first: it stops
    nothing and is not kept, so it never stops an unrelated motion later. One that comes as a
    motion closes is that motion's, and goes with it."""

    reason: str = ""
    """The first reason pressed ("" while none is held)."""
    clock: float | None = None
    """When it was sent (the sender's clock), if known."""
    by_signal: bool = False
    last_ended: int = 0
    """Id of the last motion that ended in this process (0: none yet)."""
    running: int | None = None
    """Id of the motion under way (from its acceptance to its end), None between motions."""
    _target: Stoppable | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def request(self, reason: str, clock: float | None = None, by_signal: bool = False,
                after: int | None = None) -> bool:
        """Hold an E-stop and pass it to the motion under way; False, holding nothing, when it
        was meant for a motion that has ended (``after`` below :attr:`last_ended`). ``after``
        None: this process's own E-stop (a signal, the deadman), only for a motion under way."""
        with self._lock:
            late = (self.running is None) if after is None else (after < self.last_ended)
            if late:
                return False
            if not self.reason:
                self.reason, self.clock, self.by_signal = reason, clock, by_signal
            if self._target is not None:
                self._target.request_estop(self.reason, self.clock, self.by_signal)
            return True

    def begin(self, motion_id: int) -> None:
        """Motion ``motion_id`` is accepted (before its thread starts)."""
        with self._lock:
            self.running = motion_id

    def attach(self, target: Stoppable) -> None:
        """The motion's executor from now on (a motion may run several): it gets the E-stop
        held, if any."""
        with self._lock:
            self._target = target
            if self.reason:
                target.request_estop(self.reason, self.clock, self.by_signal)

    def ended(self, motion_id: int) -> None:
        """Motion ``motion_id`` has ended: what it held goes with it."""
        with self._lock:
            self.last_ended = max(self.last_ended, motion_id)
            self.running = self._target = None
            self.reason, self.clock, self.by_signal = "", None, False
