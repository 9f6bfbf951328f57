"""A wrist wired otherwise than its profile says (ids permuted, a servo counting the other way,
horns off by whole degrees), and an operator who watches it and answers commissioning's
questions: shared by the commissioning tests of the runtime and of the console."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import EmulatorHandle

#: The wrist as built: leg 1 driven by id 3, leg 2 by id 1 (counting the other way), leg 3
#: by id 2; true θ at each servo's profile tick offset: these horn offsets, deg.
IDS = (3, 1, 2)
REVERSED = (1, -1, 1)
HORN_DEG = (4.0, -7.0, 11.0)


def as_built(agile: Profile) -> Profile:
    """The profile the emulated servos follow (the truth): at the tick where the profile reads
    home, the true joint angle is home + the horn offset, the servo counting as built (whole
    ticks here)."""
    tpd = agile.bus.ticks_per_turn / 360.0
    joints = []
    for j, ident, d, horn, home in zip(agile.bus.joints, IDS, REVERSED, HORN_DEG,
                                       agile.home.theta_deg, strict=True):
        direction = j.direction * d
        home_tick = j.tick_offset + j.direction * home * tpd
        offset = round(home_tick - direction * (home + horn) * tpd) % agile.bus.ticks_per_turn
        joints.append(j.model_copy(update={"id": ident, "direction": direction,
                                           "tick_offset": offset}))
    bus = agile.bus.model_copy(update={"joints": tuple(joints)})
    return agile.model_copy(update={"bus": bus})


class Operator:
    """An operator at the wrist: watches the true joint angles (the emulator's) and says which
    leg's arm moved and which way its elbow went (the elbow sits on w_i, eq. 2: its height is
    read from the geometry at the angles before and after, not from the product's rule). The
    first nudge is missed: "again"."""

    def __init__(self, em: EmulatorHandle, agile: Profile) -> None:
        self.em = em
        self.geom = model_of(agile).geom
        self.rest = np.asarray(em.joint_deg(), float)
        self.questions: list[str] = []

    def __call__(self, question: str, answers: Sequence[str]) -> str:
        self.questions.append(question)
        if len(self.questions) == 1:
            return "again"  # missed the first nudge: it is made again
        now = np.asarray(self.em.joint_deg(), float)
        moved = int(np.argmax(np.abs(now - self.rest)))
        if "which leg" in question:
            return str(moved + 1)
        before = self.geom.w(np.radians(self.rest))[moved]
        after = self.geom.w(np.radians(now))[moved]
        assert "up or down" in question  # the Agile Wrist's elbows rise and fall
        return "up" if after[2] > before[2] else "down"
