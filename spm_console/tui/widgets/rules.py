"""What the console's number fields accept: θ within the servo limits, roll/pitch/yaw that
IK reaches, N within the documented bounds, v_max within (0, the lower of the servo's rated
speed and the profile's planning limit]. The bounds are the CLI's and scripts'
(:mod:`spm_console.input_rules`); the words are the console's. Degrees and deg/s throughout."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from spm_console.config.models import servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.core.bounds import MX106_NO_LOAD_SPEED_DEGPS
from spm_console.errors import SpmError
from spm_console.input_rules import (
    INTERSAMPLE,
    RPY_FIELD,
    STEPS,
    servo_limit_bounds,
    vmax_bound,
)
from spm_console.tui.widgets.number import NumberRule

if TYPE_CHECKING:
    from spm_console.services.session import Session

#: A check of three accepted values as a whole: the reason they are refused, or "".
TripleCheck = Callable[[Sequence[float]], str]

THETA_NAMES = ("θ1", "θ2", "θ3")
RPY_NAMES = ("roll", "pitch", "yaw")


def theta_rules(profile: Profile, prefix: str = "") -> list[NumberRule]:
    """θ1..θ3 (deg), each within its servo's software limits."""
    return [NumberRule.of(bound, f"{prefix}{name}", "a number of degrees", "°",
                          limits="the servo limits")
            for bound, name in zip(servo_limit_bounds(profile), THETA_NAMES, strict=True)]


def rpy_rules(prefix: str = "") -> list[NumberRule]:
    """Roll, pitch, yaw from home (deg), each within ±RPY_FIELD_LIMIT_DEG (IK is checked
    apart)."""
    return [NumberRule.of(RPY_FIELD, f"{prefix}{name}", "a number of degrees", "°")
            for name in RPY_NAMES]


def steps_rule() -> NumberRule:
    """The horizon N: a whole number of intervals in STEPS_MIN..N_MAX."""
    return NumberRule.of(STEPS, "steps N", "a whole number of steps", "")


def intersample_rule() -> NumberRule:
    """K: also bound speed and region at K−1 instants inside each interval (1 = samples only)."""
    return NumberRule.of(INTERSAMPLE, "intersample K", "a whole number", "")


def vmax_rule(profile: Profile) -> NumberRule:
    """The speed bound (deg/s): above 0, at most the servo's rated no-load speed and the
    profile's planning limit (plans faster than that are refused before execution)."""
    bound = vmax_bound(profile)
    if bound.hi < MX106_NO_LOAD_SPEED_DEGPS:
        why = f"the profile's planning limit {bound.hi:g}°/s (limits.vmax_degps)"
    else:
        why = f"the servo's rated speed {MX106_NO_LOAD_SPEED_DEGPS:g}°/s (MX-106, 12 V)"
    return NumberRule.of(bound, "v_max", "a speed in °/s", "°/s", hi_reason=why)


def ik_check(session: Session, prefix: str = "") -> TripleCheck:
    """Refuse an orientation IK cannot reach, or whose motor angles leave the servo limits."""
    bounds = servo_limit_bounds(session.profile)

    def check(rpy_deg: Sequence[float]) -> str:
        try:
            theta = session.wrist.ik(list(rpy_deg))
        except SpmError as exc:
            return f"{prefix}roll/pitch/yaw: IK fails: {exc.message}"
        for i, (t, b) in enumerate(zip(theta, bounds, strict=True)):
            if not b.contains(t):
                return (f"{prefix}roll/pitch/yaw: IK gives θ{i + 1} = {t:.2f}°, outside the "
                        f"servo limits {b.lo:g}…{b.hi:g}°")
        return ""

    return check


#: A goal away from home that suits the default profile (Agile Wrist), deg.
AGILE_GOAL_DEG = (95.0, 110.0, 105.0)


def default_theta_deg(profile: Profile) -> tuple[float, float, float]:
    """The θ a form starts with: :data:`AGILE_GOAL_DEG` when it lies inside this profile's
    servo limits, else the profile's home (every profile's home does)."""
    lo, hi = servo_limits_deg(profile)
    g = np.asarray(AGILE_GOAL_DEG)
    if np.all(g >= lo) and np.all(g <= hi):
        return AGILE_GOAL_DEG
    a, b, c = (float(x) for x in profile.home.theta_deg)
    return (a, b, c)
