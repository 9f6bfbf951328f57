"""Contacts between the legs of the emulated physical wrist: MuJoCo's own distance between
their envelope capsules (:class:`LegContacts`), checked as the wrist steps."""

from __future__ import annotations

import threading
from collections.abc import Callable

import mujoco
import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.links import LinkModel
from spm_console.description.mjcf import envelope_name
from spm_console.devices.emulator.contacts import Collision

F = NDArray[np.float64]

CONTACT_CHECK_S = 0.002
"""How often the legs' envelopes are checked for contact, s of simulated time."""
CONTACT_DISTMAX_M = 0.01
"""Distances beyond this are not computed exactly (only their sign matters), m."""


class LegContacts:
    """Contact between two legs' envelope capsules, told once when it begins: MuJoCo's
    capsule–capsule distance (``mj_geomDistance``), independent of the workspace's own
    segment distances. Only the pairs whose bounding spheres meet are asked (MuJoCo's
    ``geom_rbound`` about the geom's centre: a capsule's half-length plus its radius): two whose
    centres are farther apart than the sum cannot touch (most pairs, most of the time)."""

    def __init__(self, mj: mujoco.MjModel, links: LinkModel | None) -> None:
        self.mj = mj
        self.pairs: list[tuple[int, int, int, str, int, str]] = []
        """(geom, geom, leg i, segment, leg j, segment) for every checked pair."""
        if links is not None:
            for i, s1, j, s2 in links.pairs():
                self.pairs.append((mj.geom(envelope_name(i, s1)).id,
                                   mj.geom(envelope_name(j, s2)).id, i, s1, j, s2))
        first = np.array([p[0] for p in self.pairs], np.int64)
        second = np.array([p[1] for p in self.pairs], np.int64)
        self._first, self._second = first, second
        ball = mj.geom_rbound  # each geom's bounding sphere (a capsule's: half-length + radius)
        self._reach2 = (ball[first] + ball[second]) ** 2
        """Squared distance between centres beyond which a pair cannot touch, m²."""
        self.touching: set[int] = set()
        self.events: list[Collision] = []
        """Contacts begun and not yet taken (:meth:`take`)."""
        self.lock = threading.Lock()

    def near(self, data: mujoco.MjData) -> list[int]:
        """The pairs whose bounding spheres meet (the only ones that may touch)."""
        gap = data.geom_xpos[self._first] - data.geom_xpos[self._second]
        return np.flatnonzero(np.einsum("ij,ij->i", gap, gap) <= self._reach2).tolist()

    def check(self, data: mujoco.MjData, t: float, theta_rad: Callable[[], F]) -> None:
        """Tell the contacts begun at time ``t`` (s); ``theta_rad()``: the joint angles then,
        rad (asked only when a contact begins)."""
        fromto = np.zeros(6)
        now: set[int] = set()
        for k in self.near(data):
            g1, g2, i, s1, j, s2 = self.pairs[k]
            d = mujoco.mj_geomDistance(self.mj, data, g1, g2, CONTACT_DISTMAX_M, fromto)
            if d < 0.0:
                now.add(k)
                if k not in self.touching:
                    th = tuple(float(x) for x in np.degrees(theta_rad()))
                    with self.lock:
                        self.events.append(Collision(t, (i, j), (s1, s2), 1000.0 * d,
                                                     (th[0], th[1], th[2])))
        self.touching = now

    def take(self) -> list[Collision]:
        """The contacts begun since the last call (thread-safe)."""
        with self.lock:
            out, self.events = self.events, []
        return out
