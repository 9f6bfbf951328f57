"""Joint angle (degrees) ↔ servo ticks, per joint, from the profile's bus wiring.

ticks = tick_offset + direction · θ · ticks_per_turn / 360. A tick reading is
mapped back to the θ nearest the middle of the joint's software limits (the
offset is given modulo one turn). Limits are never clamped: a target outside
[min_deg, max_deg] or outside the servo's 0..ticks_per_turn−1 range is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

from spm_console.config.schema import Profile


@dataclass(frozen=True)
class JointMap:
    """Tick mapping of one joint."""

    joint: int
    """1-based joint number."""
    id: int
    """Servo id."""
    tick_offset: float
    """Ticks at θ = 0: a profile's ``tick_offset`` plus its ``tick_trim`` (a horn's offset is
    continuous; so is the emulator's truth of a wrist as built)."""
    direction: int
    min_deg: float
    max_deg: float
    ticks_per_turn: int = 4096

    @property
    def ticks_per_deg(self) -> float:
        return self.ticks_per_turn / 360.0

    def to_ticks(self, theta_deg: float) -> float:
        """Unrounded tick value of a joint angle (deg)."""
        return self.tick_offset + self.direction * theta_deg * self.ticks_per_deg

    def to_deg(self, ticks: float) -> float:
        """Joint angle (deg) of a tick reading, unwrapped near the middle of the limits."""
        raw = self.direction * (ticks - self.tick_offset) / self.ticks_per_deg
        mid = 0.5 * (self.min_deg + self.max_deg)
        return raw - 360.0 * round((raw - mid) / 360.0)

    def in_limits(self, theta_deg: float) -> bool:
        return self.min_deg <= theta_deg <= self.max_deg

    def goal_ticks(self, theta_deg: float) -> int | None:
        """Rounded goal ticks, or None when θ is outside the limits or the servo range."""
        if not self.in_limits(theta_deg):
            return None
        t = round(self.to_ticks(theta_deg))
        if not 0 <= t < self.ticks_per_turn:
            return None
        return int(t)


def joint_maps(profile: Profile) -> list[JointMap]:
    """The three joints' mappings, in joint order."""
    tpt = profile.bus.ticks_per_turn
    return [
        JointMap(i + 1, j.id, j.tick_offset + j.tick_trim, j.direction, j.min_deg, j.max_deg, tpt)
        for i, j in enumerate(profile.bus.joints)
    ]
