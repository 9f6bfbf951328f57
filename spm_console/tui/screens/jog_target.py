"""The live jog's target (no Textual here): where the arrow keys put it, in roll/pitch/yaw
from home (IK in the home working mode) or per joint, by a chosen step; and the thread that
hands each new target to the runtime in order, off the console's event loop.

Degrees throughout.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.follow.tolerance import FOLLOW_TOL_DEG
from spm_console.errors import SpmError
from spm_console.formatting import fmt_deg

F = NDArray[np.float64]

JogMode = Literal["rpy", "joint"]

#: The steps the operator chooses from with + and -, deg.
JOG_STEPS_DEG: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0)
#: The step a jog starts with (an index into :data:`JOG_STEPS_DEG`).
DEFAULT_STEP_INDEX = 1
#: Which axis each pair of keys moves (← →, ↑ ↓, PgUp PgDn): in roll/pitch/yaw mode yaw,
#: pitch, roll (indices into [roll, pitch, yaw]) …
RPY_AXES = (2, 1, 0)
#: … per joint θ1, θ2, θ3.
JOINT_AXES = (0, 1, 2)
RPY_NAMES = ("roll", "pitch", "yaw")


def axis_name(mode: JogMode, slot: int) -> str:
    """What the key pair ``slot`` (0: ← →, 1: ↑ ↓, 2: PgUp PgDn) moves in ``mode``."""
    return RPY_NAMES[RPY_AXES[slot]] if mode == "rpy" else f"θ{JOINT_AXES[slot] + 1}"


class JogTarget:
    """The target the wrist follows while jogging: motor angles θ (deg), and the same pose
    as roll/pitch/yaw from home (deg) when known.

    ``ik(rpy_deg) -> θ_deg`` (home working mode; raises SpmError when unreachable),
    ``outside(θ_deg) -> deg`` how far a target lies outside every region the follower plans
    in, or the servo limits (0 inside).
    A key press that would take a target already outside farther out is refused: the
    follower holds the projection of the first one anyway, and a target wound up far out
    would need as many presses to come back.
    """

    def __init__(self, theta_deg: F, rpy_deg: F | None, ik: Callable[[F], F],
                 outside: Callable[[F], float]) -> None:
        self.theta_deg = np.asarray(theta_deg, float).copy()
        self.rpy_deg = None if rpy_deg is None else np.asarray(rpy_deg, float).copy()
        self.mode: JogMode = "rpy" if rpy_deg is not None else "joint"
        self.step_index = DEFAULT_STEP_INDEX
        self._ik = ik
        self._outside = outside
        self.outside_deg = outside(self.theta_deg)

    @property
    def step_deg(self) -> float:
        return JOG_STEPS_DEG[self.step_index]

    def coarser(self) -> bool:
        """One step up (False: already the largest)."""
        if self.step_index + 1 >= len(JOG_STEPS_DEG):
            return False
        self.step_index += 1
        return True

    def finer(self) -> bool:
        """One step down (False: already the smallest)."""
        if self.step_index == 0:
            return False
        self.step_index -= 1
        return True

    def toggle_mode(self, rpy_of: Callable[[F], F | None]) -> str:
        """Switch between roll/pitch/yaw and per-joint jogging; "" or why not.
        ``rpy_of(θ_deg)``: the orientation from home of θ (None: none in the home working
        mode), asked only when the target was moved per joint."""
        if self.mode == "rpy":
            self.mode = "joint"
            return ""
        if self.rpy_deg is None:
            rpy = rpy_of(self.theta_deg)
            if rpy is None:
                return (f"θ = {fmt_deg(self.theta_deg)} has no roll/pitch/yaw in the home "
                        "working mode: jog per joint back toward home first")
            self.rpy_deg = np.asarray(rpy, float)
        self.mode = "rpy"
        return ""

    def nudge(self, slot: int, sign: int) -> str:
        """Move the key pair ``slot``'s axis by ± the step; "" when the target moved, else why
        it did not."""
        d = sign * self.step_deg
        if self.mode == "rpy":
            assert self.rpy_deg is not None
            rpy = self.rpy_deg.copy()
            rpy[RPY_AXES[slot]] += d
            try:
                theta = np.asarray(self._ik(rpy), float)
            except SpmError as exc:
                return f"roll/pitch/yaw = {fmt_deg(rpy)}: {exc.message}"
            if theta.shape != (3,) or not np.all(np.isfinite(theta)):
                return f"roll/pitch/yaw = {fmt_deg(rpy)} has no IK solution"
        else:
            rpy = None
            theta = self.theta_deg.copy()
            theta[JOINT_AXES[slot]] += d
        out = self._outside(theta)
        if self.outside_deg > FOLLOW_TOL_DEG and out > self.outside_deg + FOLLOW_TOL_DEG:
            return (f"the target is already {self.outside_deg:.2f}° outside every region (the "
                    "wrist holds at the edge): step back, or along the edge")
        self.theta_deg, self.rpy_deg, self.outside_deg = theta, rpy, out
        return ""

    def describe(self) -> str:
        """Mode and step, with what each key pair moves."""
        pairs = ", ".join(f"{k} {axis_name(self.mode, i)}"
                          for i, k in enumerate(("←→", "↑↓", "PgUp/PgDn")))
        how = ("roll/pitch/yaw from home (IK, home working mode)" if self.mode == "rpy"
               else "per joint")
        return f"mode: {how} · step {self.step_deg:g}° · {pairs}"


class TargetSender:
    """Sends targets, then at most one end, in the order given, from its own thread (a pipe
    send may wait; the console's event loop must not). ``set_target(θ_deg) -> bool`` and
    ``end() -> bool`` are the session's; an exception (the motion process gone) is kept in
    :attr:`error` and ends the thread (the motion's worker reports the failure)."""

    def __init__(self, set_target: Callable[[F], bool], end: Callable[[], bool]) -> None:
        self._set_target = set_target
        self._end = end
        self._queue: queue.SimpleQueue[F | Literal["end", "stop"]] = queue.SimpleQueue()
        self.sent = 0
        """Targets the runtime took (set_target returned True)."""
        self.dropped = 0
        """Targets sent when nothing followed any more."""
        self.ended = False
        """No more targets are taken (an end was asked, or the sender was closed)."""
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, daemon=True, name="spm-jog-send")
        self._thread.start()

    def put(self, theta_deg: F) -> None:
        if not self.ended:
            self._queue.put(np.asarray(theta_deg, float).copy())

    def end(self) -> None:
        """End the following after every target put before (once)."""
        if not self.ended:
            self.ended = True
            self._queue.put("end")

    def close(self, wait_s: float = 1.0) -> None:
        """Stop the thread, without ending a following (the run is over already)."""
        self.ended = True
        self._queue.put("stop")
        self._thread.join(wait_s)

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            try:
                if isinstance(item, str):
                    if item == "end":
                        self._end()
                    return
                if self._set_target(item):
                    self.sent += 1
                else:
                    self.dropped += 1
            except BaseException as exc:  # the motion's worker says what went wrong
                self.error = exc
                return
