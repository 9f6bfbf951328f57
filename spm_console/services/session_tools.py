"""The session's servo tools (``session.tools``, a part of
:class:`~spm_console.services.session.Session`): live
health, torque per joint, reboot, and a one-joint jog.

Every call goes to the motion process, which owns the port and refuses all of them while a
motion runs. A jog is an ordinary motion: a straight line plan from the measured θ,
executed by the runtime with the homed rule, its verification and its run log. Torque off
and a reboot un-home the wrist (the joint can then be moved by hand). Degrees, seconds.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.errors import BadInputError, Issue, RefusedError
from spm_console.motion.servo_tools import ServoHealth, jog_target
from spm_console.refusals import Refusal

if TYPE_CHECKING:
    from spm_console.core.plan import Plan
    from spm_console.motion.sample import Sample
    from spm_console.motion.segments import ExecutionResult
    from spm_console.services.client import MotionClient

F = NDArray[np.float64]


class MotionHost(Protocol):
    """What the session's tools need of the session that owns the bus: its profile, the last
    θ measured (deg), one motion at a time and its planned duration (s), and its execution
    of a plan (:meth:`Session.execute <spm_console.services.session.Session.execute>`)."""

    profile: Profile
    theta_deg: F | None
    moving: threading.Event
    motion_total_s: float

    @property
    def homed(self) -> bool: ...

    def require_bus(self) -> MotionClient: ...

    def read_position(self) -> F: ...

    def run_motion(self, fn: Callable[[], ExecutionResult]) -> ExecutionResult: ...

    def execute(self, plan: Plan, on_sample: Callable[[Sample], None] | None = None,
                skip_homing: str = "", source: str | None = None) -> ExecutionResult: ...


class ServoTools:
    """The servo tools of the session ``host`` (``session.tools``)."""

    def __init__(self, host: MotionHost) -> None:
        self.host = host
        self.health: ServoHealth | None = None
        """The last health read (None before the first or after disconnecting)."""

    # ------------------------------------------------------------------ helpers
    def _idle(self, what: str) -> MotionClient:
        client = self.host.require_bus()
        if self.host.moving.is_set():
            raise BadInputError(f"{what}: refused, the wrist is moving", Issue.MOVING)
        return client

    @staticmethod
    def _joint(joint: int) -> int:
        if not isinstance(joint, int) or not 1 <= joint <= 3:
            raise BadInputError(f"joint {joint!r}: expected 1, 2 or 3")
        return joint

    def _took(self, health: ServoHealth) -> ServoHealth:
        self.health = health
        pos = health.position_deg
        if pos is not None:
            self.host.theta_deg = pos
        return health

    # ------------------------------------------------------------------ tools
    def servo_status(self) -> ServoHealth:
        """Every joint's position, current/load, temperature, voltage, torque and hardware
        error; the measured θ follows. Refused while moving."""
        return self._took(self._idle("servo status").status())

    def set_torque(self, joint: int, on: bool) -> ServoHealth:
        """Torque Enable of one joint (1-based). On: its goal becomes its present position
        first, so it holds where it is. Off: the wrist is no longer homed. Refused while
        moving. Returns the health read after it."""
        client = self._idle(f"torque {'on' if on else 'off'}")
        self._joint(joint)
        return self._took(client.set_torque(joint, on))  # off: the motion process un-homes

    def reboot_servo(self, joint: int) -> ServoHealth:
        """REBOOT one joint's servo to clear a latched hardware error (Protocol 2.0), then
        read every joint again. The servo comes back with torque off: the wrist is no
        longer homed. Refused while moving."""
        client = self._idle("reboot")
        self._joint(joint)
        return self._took(client.reboot(joint))

    def jog_plan_target(self, joint: int, step_deg: float) -> tuple[F, F]:
        """(measured θ, jog target) in deg, or BadInputError (not homed, moving, a step that
        is zero or above ``servo_tools.JOG_MAX_STEP_DEG``, a target outside the joint's
        servo limits). Nothing moves."""
        self._idle("jog")
        self._joint(joint)
        if not self.host.homed:  # the motion process's flag: nothing is planned for a refused jog
            raise RefusedError(Refusal.NOT_HOMED)
        theta0 = self.host.read_position()
        return theta0, jog_target(theta0, joint, step_deg, servo_limits_deg(self.host.profile))

    def jog(self, joint: int, step_deg: float,
            on_sample: Callable[[Sample], None] | None = None) -> ExecutionResult:
        """Move one joint (1-based) by ``step_deg`` (deg, signed) in a straight line at the
        homing speed, the others held: a motion of the runtime like any other (only when
        homed; verified against the workspace before torque-on, logged, E-stop and deadman
        apply). Refused, with nothing moved, as :meth:`jog_plan_target` says."""
        from spm_console.motion.plans import line_plan

        theta0, target = self.jog_plan_target(joint, step_deg)
        profile = self.host.profile
        plan = line_plan(profile, theta0, target, profile.safety.home_speed_degps, kind="jog")
        source = (f"jog: joint {joint} by {step_deg:+g}° "
                  f"({theta0[joint - 1]:.2f}° to {target[joint - 1]:.2f}°)")
        return self.host.execute(plan, on_sample, source=source)
