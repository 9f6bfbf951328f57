"""Targets for live following: a timed list (a CSV file) and/or live updates from any thread.

The follower asks, once per servo period, for the target at the next period and — for a timed
list — a preview of the targets over its horizon (so the re-planned references anticipate the
steps). Live updates (a UDP client, the console's jog keys) replace the target at once; a
**deadman** turns a silent live feed into a hold: when no update arrived for ``deadman_s``
since following started (:meth:`TargetFeed.arm`), the target becomes the position the wrist
had then, until updates resume. Degrees, seconds.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.follow.timed import TimedTargets, check_target_angles
from spm_console.errors import BadInputError

F = NDArray[np.float64]

class TargetFeed:
    """What the follower follows (thread-safe). ``timed``: a fixed list; otherwise live
    updates through :meth:`set`, ended by :meth:`end`. ``deadman_s`` (live feeds): hold when
    no update arrives for that long (None: never)."""

    def __init__(self, timed: TimedTargets | None = None, initial_deg: Sequence[float] | None = None,
                 deadman_s: float | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        if timed is None and initial_deg is None:
            raise BadInputError("a live target feed needs an initial target")
        if deadman_s is not None and not (np.isfinite(deadman_s) and 0.0 < deadman_s <= 60.0):
            raise BadInputError(f"deadman must be in (0, 60] s, got {deadman_s}")
        self.timed = timed
        self.deadman_s = deadman_s
        self.clock = clock
        self._lock = threading.Lock()
        self._live = None if initial_deg is None else np.asarray(initial_deg, float).reshape(3)
        self._last_update = clock()
        self._armed = False  # the deadman counts only once following started (:meth:`arm`)
        self._ended = False
        self._held: F | None = None
        self.updates = 0
        """Live updates received."""
        self.deadman_trips = 0
        """Times the deadman turned the target into a hold."""

    @property
    def live(self) -> bool:
        return self.timed is None

    def set(self, theta_deg: Sequence[float] | F) -> None:
        """A new live target (deg), from any thread; resumes following after a deadman hold."""
        th = np.asarray(theta_deg, float).reshape(3)
        if not np.all(np.isfinite(th)):
            raise BadInputError("a target must be three finite angles in degrees")
        check_target_angles(th)
        with self._lock:
            self._live = th
            self._last_update = self.clock()
            self._held = None
            self.updates += 1

    def arm(self) -> None:
        """Following starts now: the deadman counts silence from here (or from the last
        update, if later); before, it never trips. The time spent before — homing, finding
        the regions, the first solve — is not the source's silence."""
        with self._lock:
            self._armed = True
            self._last_update = max(self._last_update, self.clock())

    def end(self) -> None:
        """The live source is done: the follower settles on the current target and ends."""
        with self._lock:
            self._ended = True

    def targets(self, t_run: float, ts: float, horizon: int, wrist_deg: F) -> tuple[F, bool]:
        """(targets (horizon, 3) for t_run + ts·(1..horizon), deadman holding now).
        ``wrist_deg``: where the wrist is (the hold target when the deadman trips)."""
        if self.timed is not None:
            t = np.asarray(t_run + ts * np.arange(1, horizon + 1), float)
            return self.timed.at(t), False
        with self._lock:
            silent = (self.deadman_s is not None and self._armed and not self._ended
                      and self.clock() - self._last_update > self.deadman_s)
            if silent and self._held is None:
                self._held = np.asarray(wrist_deg, float).copy()
                self.deadman_trips += 1
            tgt = self._held if self._held is not None else self._live
            assert tgt is not None
            return np.tile(tgt, (horizon, 1)), self._held is not None

    def now(self, t_run: float, wrist_deg: F) -> F:
        """The target asked for at ``t_run`` (before any projection into the region)."""
        if self.timed is not None:
            return np.asarray(self.timed.at(np.array([t_run]))[0])
        return np.asarray(self.targets(t_run, 0.0, 1, wrist_deg)[0][0], float)

    def finished(self, t_run: float) -> bool:
        """No target will change any more (the timed list is over, or the live source ended)."""
        if self.timed is not None:
            return t_run >= self.timed.end_s
        with self._lock:
            return self._ended

    def final(self, wrist_deg: F) -> F:
        """The target the run settles on once :meth:`finished`."""
        if self.timed is not None:
            return np.asarray(self.timed.theta_deg[-1])
        with self._lock:
            tgt = self._held if self._held is not None else self._live
        return np.asarray(wrist_deg if tgt is None else tgt, float)
