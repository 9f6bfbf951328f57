"""One servo's view of the physical wrist: its joint, in the servo's ticks.

The servo's firmware state (goal, torque, a blocked shaft) goes to the wrist at each change
(:meth:`PlantJoint.command`); the wrist steps all three joints together to the time of a
request (:meth:`PlantJoint.follow`), so every servo's goal is held between its writes.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from spm_console.devices.dynamixel.tick_map import JointMap

if TYPE_CHECKING:  # the physical wrist loads MuJoCo: only an emulator that runs one needs it
    from spm_console.devices.emulator.physical import DriveGains, PhysicalWrist

#: Present Current's unit on the MX-106 (Protocol 2.0), A.
CURRENT_UNIT_A = 0.00336


class PlantJoint:
    """Joint ``index`` of ``wrist``, driven by the servo wired as ``tick_map``."""

    def __init__(self, wrist: PhysicalWrist, index: int, tick_map: JointMap) -> None:
        self.wrist = wrist
        self.index = index
        self.map = tick_map

    def command(self, goal_ticks: float, enabled: bool, blocked: bool,
                gains: DriveGains | None = None) -> None:
        self.wrist.command(self.index, math.radians(self.map.to_deg(goal_ticks)), enabled, blocked,
                           gains)

    def follow(self, t: float) -> tuple[float, float]:
        """Step the wrist to ``t`` (s); (position in ticks, velocity in ticks/s) of this joint."""
        self.wrist.advance(t)
        th = self.wrist.theta()[self.index]
        om = self.wrist.omega()[self.index]
        return (self.map.to_ticks(math.degrees(th)),
                self.map.direction * math.degrees(om) * self.map.ticks_per_deg)

    def overloaded(self) -> bool:
        """The drive has strained against a shaft that does not turn long enough to shut down."""
        return self.wrist.overloaded(self.index)

    def current_units(self) -> int:
        """Present Current (units of 3.36 mA), the winding's current now."""
        amps = self.wrist.current(self.index)
        return max(-32768, min(32767, round(amps / CURRENT_UNIT_A)))

    def pwm(self) -> int:
        """Present PWM (885 = 100 %)."""
        return max(-885, min(885, round(self.wrist.drives[self.index].pwm)))
