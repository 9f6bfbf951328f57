"""Settling at the goal after a planned motion (profile ``[settle]``).

The MX-106's firmware closes a P-only position loop (Position I Gain 0 by default): at rest
the shaft stops where the drive's torque balances friction and the links' weight, a few encoder
ticks from the goal, on either side depending on the approach and the pose. The runtime reads
that offset and shifts the goal it sends by a fraction of it every period (a slow integral
outside the servo, active only at rest, after the plan): c ← c + κ·(goal − θ) for each joint
outside the tolerance (one within it keeps its shift), κ halved at each of a joint's
overshoots (friction and the encoder's ticks would make a fixed κ hunt), each joint's shift
bounded by ``max_correction_deg``. The goal itself is a reference, in the workspace's
certified set like every reference; a shifted goal is sent only where the safety monitor lets
the measured position be (the certified set relaxed by the region margin, less the
tolerance and a tick, and the servo limits): the shift only brings the wrist onto a goal
that is in the set, so at a goal on the set's face (the paper's θ2 = 155°, the grid's edge)
a joint resting short of it is pushed onto it. When a shift would leave that band, the
joints whose new shift keeps it inside take theirs (as many as can), the others keep the
previous one. Settled once every joint is
within ``tolerance_deg`` of the goal for :data:`SETTLED_PERIODS` periods; otherwise the
settling ends after ``duration_s``. Degrees.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Settle

F = NDArray[np.float64]

#: Fraction of the measured offset added to the goal's shift each period (κ): about three
#: periods to take up an offset, slow beside the servo's own response, so the shift never
#: chases its motion.
GAIN = 0.3
#: A joint whose offset changes sign (its shift carried it past the goal) goes on with half
#: its gain, down to this fraction of :data:`GAIN`: the drive's friction and the encoder's
#: ticks make a fixed gain hunt across a tolerance of a tick or less.
MIN_GAIN_FRACTION = 1.0 / 8.0
#: Periods within the tolerance that end the settling.
SETTLED_PERIODS = 5


@dataclass
class Settling:
    """One settling at ``goal`` (deg, (3,)); :meth:`reference` is what to send each period."""

    law: Settle
    goal: F
    allowed: Callable[[F], bool]
    """Whether a goal may be sent (inside the certified set and the servo limits)."""
    shift: F | None = None
    within: int = 0
    refused: int = 0
    """Shifts not taken because the shifted goal was not allowed."""
    gain: F | None = None
    """Each joint's κ now (:data:`GAIN`, halved at each of its overshoots)."""
    side: F | None = None
    """Each joint's side of the goal when last outside the tolerance (+1 short, −1 past, 0
    not yet)."""

    def __post_init__(self) -> None:
        self.goal = np.asarray(self.goal, float)
        if self.shift is None:
            self.shift = np.zeros(3)
        self.gain = np.full(3, GAIN)
        self.side = np.zeros(3)

    @property
    def reference(self) -> F:
        """The goal to send now, deg."""
        assert self.shift is not None
        return np.asarray(self.goal + self.shift)

    @property
    def settled(self) -> bool:
        return self.within >= SETTLED_PERIODS

    def update(self, measured: F | None) -> None:
        """Take one period's measurement (None or NaN: a failed read, nothing changes)."""
        assert self.shift is not None
        if measured is None or not np.all(np.isfinite(measured)):
            return
        error = self.goal - np.asarray(measured, float)
        if float(np.abs(error).max()) <= self.law.tolerance_deg:
            self.within += 1
            return
        self.within = 0
        assert self.gain is not None and self.side is not None
        outside = np.abs(error) > self.law.tolerance_deg
        side = np.sign(error)
        crossed = outside & (side * self.side < 0)
        self.gain = np.where(crossed, np.maximum(self.gain / 2, GAIN * MIN_GAIN_FRACTION),
                             self.gain)
        self.side = np.where(outside, side, self.side)
        # a joint within the tolerance keeps its shift: moving it would only move it out
        bound = self.law.max_correction_deg
        shift = np.clip(self.shift + np.where(outside, self.gain * error, 0.0), -bound, bound)
        taken = self._allowed_part(shift)
        if taken is None or not np.array_equal(taken, shift):
            self.refused += 1
        if taken is not None:
            self.shift = taken

    def _allowed_part(self, shift: F) -> F | None:
        """``shift``, or where the goal it moves is not allowed, the most of its joints' new
        components with which it is (the others keep their previous shift: a joint at a face
        of the certified set leaves the others free to settle); None when none is."""
        assert self.shift is not None
        for size in (3, 2, 1):
            for joints in combinations(range(3), size):
                take = np.isin(np.arange(3), joints)
                cand = np.where(take, shift, self.shift)
                if self.allowed(self.goal + cand):
                    return np.asarray(cand, float)
        return None


def settle_periods(law: Settle, ts_s: float) -> int:
    """Most periods a settling may take."""
    return max(1, round(law.duration_s / ts_s))
