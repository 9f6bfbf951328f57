"""Commissioning's zero without a jig: once the map is known, each leg alone swings from
+1.8° to −1.8° about where the wrist rests (inside the nudges' 2° ball), the IMU on the
platform measuring the rotation between the two ends;
:func:`~spm_console.core.commissioning.rest.fit_rest` finds the joint angles at rest that
explain the three rotations, and each tick offset follows from the servo's ticks at rest.

The zero is known to a few tenths of a degree to about a degree (its standard errors are
reported; the encoder's tick at each end of a swing is most of it); the IMU stage then refines
it across the region P, its poses kept three standard errors inside P so that the wrist's
true path stays there. A zero known worse than :data:`MAX_ZERO_STD_DEG` is refused: zero on
the jig.

Degrees at the interface.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.rest import RestFit, fit_rest
from spm_console.errors import BusError, SolverError
from spm_console.motion.nudge import NudgeResult
from spm_console.services.commissioning.leg_map import LegMatch, rotation_vector

F = NDArray[np.float64]

#: Each end of a leg's swing, deg of the servo's own counting (inside the 2° ball).
SWING_DEG = 1.8
#: Wait at each end of a swing before the IMU is read, s (the platform still).
SETTLE_S = 0.4
#: Fused quaternions averaged at each end of a swing.
SWING_SAMPLES = 100
#: Noise of one fused orientation sample of the BNO055, deg per axis (1σ): the floor the
#: zero's standard errors assume (the residuals of nine numbers for six unknowns say little).
FUSED_NOISE_DEG = 0.05
#: How far a link arc as built may be from the profile's, deg (1σ): the zero's standard errors
#: include it (0.4° off arcs bias the angles at rest by about 0.6°).
ARC_STD_DEG = 0.3
#: The largest standard error of a zero at rest the IMU stage takes, deg: its poses then keep
#: 3σ inside P (the true path stays there), which leaves enough of P to design them in.
MAX_ZERO_STD_DEG = 2.0


class QuaternionSource(Protocol):
    """The IMU's fused orientation (w, x, y, z), averaged."""

    def __call__(self, n: int) -> F: ...


@dataclass(frozen=True)
class Swing:
    """One leg's swing: the measured rotation between its ends and where they were."""

    rotation_rad: F
    """From the + end to the − end, in the IMU's frame, rad."""
    rest_ticks: dict[int, int]
    """Every servo's ticks at rest, by id (where the nudging began)."""
    ends_ticks: tuple[dict[int, int], dict[int, int]]
    """Every servo's ticks at the + and the − end, by id (the others held where they were:
    friction leaves them a few ticks from their rest)."""


@dataclass(frozen=True)
class RestZero:
    """The zero found at rest."""

    fit: RestFit
    offsets: tuple[int, int, int]
    """Tick offsets (whole ticks)."""
    trims: tuple[float, float, float]
    """The fraction of a tick beyond each (−0.5..0.5)."""


def swing(ident: int, nudge: Callable[[int, float], NudgeResult],
          quaternion: QuaternionSource) -> Swing:
    """Leg ``ident``'s servo to +:data:`SWING_DEG`, then −, then back to rest (each a nudge of
    its own), the IMU read at each end."""
    out = nudge(ident, SWING_DEG)
    time.sleep(SETTLE_S)
    q_plus = quaternion(SWING_SAMPLES)
    back = nudge(ident, -SWING_DEG)
    time.sleep(SETTLE_S)
    q_minus = quaternion(SWING_SAMPLES)
    nudge(ident, 0.0)
    return Swing(rotation_vector(q_plus, q_minus), dict(zip(out.ids, out.rest_ticks, strict=True)),
                 (dict(zip(out.ids, out.reached_ticks, strict=True)),
                  dict(zip(back.ids, back.reached_ticks, strict=True))))


def zero_at_rest(profile: Profile, legs: Sequence[LegMatch], swings: Sequence[Swing],
                 noise_deg: float) -> RestZero:
    """The tick offsets that read the joint angles the swings' rotations put the wrist at
    (``legs``: the map; ``swings``: per leg 1..3; ``noise_deg``: of one measured rotation's
    component). BusError when the rotations do not determine the zero well enough for the
    IMU stage's poses."""
    tpd = profile.bus.ticks_per_turn / 360.0
    d = np.array([m.direction for m in legs], float)
    ids = [m.id for m in legs]
    rest = np.array([swings[0].rest_ticks[i] for i in ids], float)
    plus = np.array([[s.ends_ticks[0][i] for i in ids] for s in swings], float)
    minus = np.array([[s.ends_ticks[1][i] for i in ids] for s in swings], float)
    lo = np.array([j.min_deg for j in profile.bus.joints], float)
    hi = np.array([j.max_deg for j in profile.bus.joints], float)
    try:
        fit = fit_rest(model_of(profile), np.array([s.rotation_rad for s in swings]),
                       d * (plus - rest) / tpd, d * (minus - rest) / tpd, lo, hi, noise_deg,
                       ARC_STD_DEG)
    except SolverError as exc:
        raise BusError(f"commission: the zero at rest: {exc.message}; is the IMU fixed to the "
                       "platform? Else zero on the home jig (--jig). Nothing was written") from None
    worst = max(fit.theta_std_deg)
    if worst > MAX_ZERO_STD_DEG:
        raise BusError(f"commission: the zero at rest is known to ±{worst:.2f}° (1σ), more than "
                       f"{MAX_ZERO_STD_DEG:g}°. Zero on the home jig (--jig). Nothing was written")
    zeros = [float(r) - m.direction * th * tpd for r, m, th in zip(rest, legs, fit.theta_deg,
                                                                  strict=True)]
    offsets, trims = ticks_and_trims(zeros, profile.bus.ticks_per_turn)
    return RestZero(fit, offsets, trims)


def ticks_and_trims(zeros: Sequence[float], ticks_per_turn: int
                    ) -> tuple[tuple[int, int, int], tuple[float, float, float]]:
    """Three zeros in (fractional) ticks as the profile holds them: the nearest whole tick,
    modulo one turn (``tick_offset``), and the rest (``tick_trim``, −0.5..0.5, to 0.001)."""
    whole = [round(float(z)) for z in zeros]
    trims = [round(float(z) - w, 3) for z, w in zip(zeros, whole, strict=True)]
    return ((whole[0] % ticks_per_turn, whole[1] % ticks_per_turn, whole[2] % ticks_per_turn),
            (trims[0], trims[1], trims[2]))


def rotation_noise_deg(samples: int = SWING_SAMPLES) -> float:
    """One component of the rotation between two averaged readings, deg (1σ)."""
    return FUSED_NOISE_DEG * math.sqrt(2.0 / samples)
