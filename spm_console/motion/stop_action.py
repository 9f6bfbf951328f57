"""The profile's stop action on the bus: hold the measured position (the goal written twice,
the second time at the next deadline) or switch the torque off (up to three tries).

Used by the executor for every stop (E-stop, tracking, communication, hardware error,
region, limits). A failed write is noted, never raised: the stop must go on, and with the
link down the servos' Bus Watchdog stops them. Degrees, seconds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

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
