"""The session's live following (``session.following``, a part of
:class:`~spm_console.services.session.Session`).

A following is an ordinary motion of the runtime: the motion process runs it (homed rule,
run log, E-stop, deadman of the client), re-planning every period
(:mod:`spm_console.motion.follow.loop`). Targets come as a timed list, or live through
:meth:`FollowTools.set_target` from any thread (a UDP bridge, the console's jog keys) until
:meth:`FollowTools.end_follow`. Degrees, seconds.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.errors import BadInputError
from spm_console.services.session_tools import MotionHost

if TYPE_CHECKING:
    from spm_console.core.planning.follow.timed import TimedTargets
    from spm_console.motion.follow.run import FollowOutcome
    from spm_console.motion.sample import Sample
    from spm_console.motion.segments import ExecutionResult

F = NDArray[np.float64]


class FollowTools:
    """The live following of the session ``host`` (``session.following``)."""

    def __init__(self, host: MotionHost) -> None:
        self.host = host

    def follow(self, timed: TimedTargets | None = None, initial_deg: F | None = None,
               deadman_s: float | None = None,
               on_sample: Callable[[Sample], None] | None = None, skip_homing: str = "",
               source: str | None = None) -> FollowOutcome:
        """Follow ``timed`` targets, or live targets from ``initial_deg`` on (sent with
        :meth:`set_target`), until finished and settled; refused unless homed (or overridden
        with a reason)."""
        if timed is None and initial_deg is None:
            raise BadInputError("live following needs an initial target")
        client = self.host.require_bus()
        self.host.motion_total_s = float("nan") if timed is None else float(timed.end_s)
        got: list[FollowOutcome] = []

        def run() -> ExecutionResult:
            out = client.follow(timed, None if initial_deg is None else np.asarray(initial_deg),
                                deadman_s, on_sample, skip_homing, source)
            got.append(out)
            return out.execution

        self.host.run_motion(run)
        return got[0]

    def set_target(self, theta_deg: F) -> bool:
        """A new live target (deg) for the following under way; False when nothing follows."""
        if not self.host.moving.is_set():
            return False
        self.host.require_bus().set_target(theta_deg)
        return True

    def end_follow(self) -> bool:
        """End a live following (it settles on the current target first)."""
        if not self.host.moving.is_set():
            return False
        self.host.require_bus().end_follow()
        return True
