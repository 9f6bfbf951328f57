"""The input rules every front end applies (CLI options, script keys, console fields).

One definition each: a finite number within bounds, an integer within bounds, three angles
(in the grid, in the servo limits, or within one turn for pure computation), a speed bound
under the profile's planning limit. Each refusal is a :class:`~spm_console.errors.BadInputError`
(exit 4) naming what was given (``what``: an option, a script key, a field) and the bound.
The bounds themselves are :class:`Bound` values (:data:`STEPS`, :func:`vmax_bound`, …): the
console's number fields are built from the same ones and word their own refusals.
Degrees and seconds.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np

from spm_console.config.models import servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.core.bounds import MX106_NO_LOAD_SPEED_DEGPS, N_MAX
from spm_console.errors import BadInputError

#: Bound on θ for commands that only compute (fk): one turn either way, deg.
FK_THETA_LIMIT_DEG = 360.0
#: Bound on roll, pitch, yaw given for IK, deg.
RPY_LIMIT_DEG = 360.0
#: Bound on each of roll, pitch, yaw typed in a console field, deg: beyond it the same
#: orientation has a smaller name (the fields show what IK will be asked).
RPY_FIELD_LIMIT_DEG = 180.0
#: Angles within this of a bound count as on it (they may come from arithmetic), deg.
ANGLE_SLACK_DEG = 1e-9
#: Fewest intervals N of a plan.
STEPS_MIN = 2
#: Largest intersample K (speed and region also enforced at K−1 instants per interval).
INTERSAMPLE_MAX = 100


@dataclass(frozen=True)
class Bound:
    """The values one input accepts: ``lo``..``hi`` (an end excluded when open), whole
    numbers only when ``integer``; ``slack`` widens the closed ends (angles)."""

    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    integer: bool = False
    slack: float = 0.0

    def contains(self, v: float) -> bool:
        """``v`` lies in the interval (an infinite ``v`` only under an infinite end)."""
        above = v > self.lo if self.lo_open else v >= self.lo - self.slack
        below = v < self.hi if self.hi_open else v <= self.hi + self.slack
        return above and below

    def holds(self, v: float) -> bool:
        """``v`` is accepted: finite, whole when ``integer``, inside the interval."""
        return (math.isfinite(v) and (not self.integer or float(v).is_integer())
                and self.contains(v))


#: The horizon N of an MVN plan (``--steps``, the console's 'steps N').
STEPS = Bound(STEPS_MIN, N_MAX, integer=True)
#: K (``--intersample``, the console's 'intersample K').
INTERSAMPLE = Bound(1, INTERSAMPLE_MAX, integer=True)
#: Roll, pitch or yaw given for IK (CLI, scripts), deg.
RPY = Bound(-RPY_LIMIT_DEG, RPY_LIMIT_DEG)
#: Roll, pitch or yaw typed in a console field, deg (inside :data:`RPY`).
RPY_FIELD = Bound(-RPY_FIELD_LIMIT_DEG, RPY_FIELD_LIMIT_DEG)


def servo_limit_bounds(profile: Profile) -> tuple[Bound, Bound, Bound]:
    """θ1, θ2, θ3 inside each joint's servo limits [min_deg, max_deg], deg."""
    lo, hi = servo_limits_deg(profile)
    a, b, c = (Bound(float(lo[i]), float(hi[i]), slack=ANGLE_SLACK_DEG) for i in range(3))
    return (a, b, c)


def vmax_bound(profile: Profile) -> Bound:
    """A speed bound, deg/s: above 0, at most the lower of the MX-106's rated no-load speed
    and the profile's planning limit ``limits.vmax_degps``."""
    return Bound(0.0, min(float(profile.limits.vmax_degps), MX106_NO_LOAD_SPEED_DEGPS),
                 lo_open=True)


def _interval(lo: float | None, hi: float | None, lo_open: bool, hi_open: bool) -> str:
    if lo is not None and hi is not None:
        return f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{'>' if lo_open else '≥'} {lo:g}"
    return f"{'<' if hi_open else '≤'} {hi:g}"


def finite_number(value: float, what: str, lo: float | None = None, hi: float | None = None, *,
                  lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """A finite number given on the command line, within [lo, hi] (or open ends).

    NaN and infinities are refused as "must be a finite number" (not as out of range);
    the message names the option (``what``) and the bounds.
    """
    v = float(value)
    if not math.isfinite(v):
        raise BadInputError(f"{what} must be a finite number, got {value}")
    if v != 0.0 and abs(v) < sys.float_info.min:  # as a profile's numbers (config.fields)
        raise BadInputError(f"{what}: {value} is a subnormal number, too small to be a "
                            "measurement (0 or a magnitude of at least 2.2e-308)")
    bound = Bound(-math.inf if lo is None else lo, math.inf if hi is None else hi,
                  lo_open=lo_open, hi_open=hi_open)
    if not bound.holds(v):
        raise BadInputError(f"{what} must be {'in ' if lo is not None and hi is not None else ''}"
                            f"{_interval(lo, hi, lo_open, hi_open)}"
                            f"{(' ' + unit) if unit else ''}, got {v:g}")
    return v


def bounded_int(value: int, what: str, lo: int, hi: int) -> int:
    """An integer option within lo..hi (both included)."""
    if not Bound(lo, hi, integer=True).contains(value):
        shown = str(value) if abs(value) < 10**15 else f"{float(value):.3g}"
        raise BadInputError(f"{what} must be an integer in {lo:,}..{hi:,}, got {shown}")
    return int(value)


def count_in(value: int, what: str, bound: Bound) -> int:
    """An integer option within an integer :class:`Bound` (:data:`STEPS`, :data:`INTERSAMPLE`)."""
    return bounded_int(value, what, int(bound.lo), int(bound.hi))


def finite3(values: list[float] | None, what: str, lo: float | None = None,
            hi: float | None = None, range_name: str = "the range", note: str = "") -> np.ndarray:
    """Validate three finite numbers given on the command line (degrees), optionally each in
    [lo, hi]: "--theta: θ1 = 1e+05° is outside the grid 65..155° (note)"."""
    if values is None or len(values) != 3:
        raise BadInputError(f"{what}: expected three angles in degrees")
    for i, v in enumerate(values):
        if not math.isfinite(v):
            raise BadInputError(f"{what}: θ{i + 1} must be a finite number, got {values}")
    if lo is not None and hi is not None:
        bound = Bound(lo, hi, slack=ANGLE_SLACK_DEG)
        for i, v in enumerate(values):
            if not bound.contains(v):
                raise BadInputError(f"{what}: θ{i + 1} = {v:g}° is outside {range_name} "
                                    f"{lo:g}..{hi:g}°" + (f" ({note})" if note else ""))
    return np.asarray(values, float)


def theta_in_grid(values: list[float] | None, what: str, profile: Profile) -> np.ndarray:
    """θ inside the profile's workspace grid box (checked in O(1), before any FK work)."""
    ws = profile.workspace
    return finite3(values, what, ws.theta_min_deg, ws.theta_max_deg, "the grid",
                   f"profile '{profile.name}', workspace.theta_min_deg..theta_max_deg")


def theta_for_fk(values: list[float] | None, what: str) -> np.ndarray:
    """θ for a pure computation (fk): finite and within one turn either way."""
    return finite3(values, what, -FK_THETA_LIMIT_DEG, FK_THETA_LIMIT_DEG, "the range",
                   "one turn either way")


def theta_in_servo_limits(values: list[float] | None, what: str, profile: Profile) -> np.ndarray:
    """θ inside every joint's servo limits [min_deg, max_deg] of the profile."""
    th = finite3(values, what)
    for i, (j, bound) in enumerate(zip(profile.bus.joints, servo_limit_bounds(profile),
                                       strict=True)):
        if not bound.contains(th[i]):
            raise BadInputError(f"{what}: θ{i + 1} = {th[i]:g}° is outside joint {i + 1}'s servo "
                                f"limits {j.min_deg:g}..{j.max_deg:g}° (profile '{profile.name}')")
    return th


def vmax_arg(value: float | None, profile: Profile, *, default_to_profile: bool = False,
             what: str = "--vmax") -> float | None:
    """A speed bound in (0, limit] deg/s: limit is the profile's limits.vmax_degps (the
    planning limit), and no bound may exceed the MX-106's rated no-load speed. The message
    says which limit was exceeded. ``None`` stays None unless ``default_to_profile``."""
    prof = profile.limits.vmax_degps
    if value is None:
        if not default_to_profile:
            return None
        value, what = prof, f"profile '{profile.name}': limits.vmax_degps ="
    v = finite_number(value, what, 0.0, None, lo_open=True, unit="deg/s")
    if vmax_bound(profile).holds(v):
        return v
    if v > MX106_NO_LOAD_SPEED_DEGPS:
        raise BadInputError(f"{what} {v:g} deg/s is above the MX-106's rated no-load speed "
                            f"{MX106_NO_LOAD_SPEED_DEGPS:g} deg/s (45 rev/min at 12 V)")
    raise BadInputError(
        f"{what} {v:g} deg/s is above the profile's planning limit limits.vmax_degps = "
        f"{prof:g} deg/s (profile '{profile.name}')")


def rpy_angles(values: list[float] | tuple[float, ...], what: str) -> np.ndarray:
    """Roll, pitch, yaw (deg): finite and within one turn either way."""
    if len(values) != 3:
        raise BadInputError(f"{what}: expected roll, pitch, yaw in degrees")
    return np.asarray([finite_number(x, f"{what} {name}", RPY.lo, RPY.hi, unit="deg")
                       for x, name in zip(values, ("roll", "pitch", "yaw"), strict=True)])
