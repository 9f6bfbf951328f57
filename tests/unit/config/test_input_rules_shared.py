"""One definition of each input bound, whichever front end takes the value.

For a grid of values on and around every bound, the CLI's rule (:mod:`spm_console.input_rules`,
which scripts apply too) and the console's number field (:mod:`spm_console.tui.widgets.rules`)
accept and refuse alike; only their words differ. A bound changed on one side only fails here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable

import pytest
from pydantic import ValidationError

from spm_console.config.schema import Profile
from spm_console.core.bounds import MX106_NO_LOAD_SPEED_DEGPS, N_MAX
from spm_console.errors import BadInputError
from spm_console.input_rules import (
    ANGLE_SLACK_DEG,
    INTERSAMPLE,
    RPY,
    STEPS,
    Bound,
    count_in,
    rpy_angles,
    theta_in_servo_limits,
    vmax_arg,
)
from spm_console.scripting.steps import PlanStep
from spm_console.tui.widgets.number import NumberRule
from spm_console.tui.widgets.rules import (
    intersample_rule,
    rpy_rules,
    steps_rule,
    theta_rules,
    vmax_rule,
)


def _accepts(check: Callable[..., object], *args: object) -> bool:
    try:
        check(*args)
    except BadInputError:
        return False
    return True


def _field_accepts(rule: NumberRule, value: float) -> bool:
    """The field's verdict on ``value`` typed in full (the field's length limit is a matter
    of its width, not of the rule)."""
    return dataclasses.replace(rule, max_chars=64).reason(repr(value)) == ""


def _around(*edges: float) -> list[float]:
    """Values on, just inside, just outside and far from each edge."""
    out: list[float] = []
    for e in edges:
        out += [e - 1.0, e - 2 * ANGLE_SLACK_DEG, e - ANGLE_SLACK_DEG / 2, e,
                e + ANGLE_SLACK_DEG / 2, e + 2 * ANGLE_SLACK_DEG, e + 1.0]
    return [*out, -1e6, 0.0, 1e6]


def _fast(agile: Profile) -> Profile:
    return agile.model_copy(update={"limits": agile.limits.model_copy(
        update={"vmax_degps": 1000.0})})


def _same(values: Iterable[float], cli: Callable[[float], object], rule: NumberRule) -> None:
    for v in values:
        assert _accepts(cli, v) == _field_accepts(rule, v), (rule.name, v)


def test_theta_in_the_servo_limits_is_one_rule(agile: Profile) -> None:
    rules = theta_rules(agile)
    for i, j in enumerate(agile.bus.joints):
        mid = [(jj.min_deg + jj.max_deg) / 2 for jj in agile.bus.joints]

        def cli(v: float, i: int = i, mid: list[float] = mid) -> object:
            return theta_in_servo_limits([*mid[:i], v, *mid[i + 1:]], "--start", agile)

        _same(_around(j.min_deg, j.max_deg), cli, rules[i])


@pytest.mark.parametrize("fast", [False, True], ids=["planning limit", "rated speed"])
def test_the_speed_bound_is_one_rule(agile: Profile, fast: bool) -> None:
    profile = _fast(agile) if fast else agile
    prof = profile.limits.vmax_degps
    values = [*_around(0.0, prof, MX106_NO_LOAD_SPEED_DEGPS), 1e-9, -1e-9]
    _same(values, lambda v: vmax_arg(v, profile), vmax_rule(profile))


@pytest.mark.parametrize(("what", "bound", "rule"), [
    ("--steps", STEPS, steps_rule()), ("--intersample", INTERSAMPLE, intersample_rule())],
    ids=["steps N", "intersample K"])
def test_whole_numbers_are_one_rule(what: str, bound: Bound, rule: NumberRule) -> None:
    lo, hi = int(rule.lo), int(rule.hi)
    for n in (-1, 0, lo - 1, lo, lo + 1, hi - 1, hi, hi + 1, 10**6):
        assert _accepts(count_in, n, what, bound) == (rule.reason(str(n)) == ""), (what, n)


def test_a_scripts_steps_are_the_clis(agile: Profile) -> None:
    for n in (STEPS.lo - 1, STEPS.lo, N_MAX, N_MAX + 1):
        try:
            PlanStep.model_validate({"do": "plan", "goal": "home", "steps": int(n)})
            script = True
        except ValidationError:
            script = False
        assert script == STEPS.holds(n), n


def test_the_consoles_orientations_are_ones_the_cli_takes() -> None:
    """The console's roll/pitch/yaw fields stop at ±180° (beyond, the same orientation has a
    smaller name); the CLI takes one turn either way. What the console accepts, the CLI does."""
    rules = rpy_rules()
    for v in _around(-RPY.hi, -180.0, 180.0, RPY.hi):
        if _field_accepts(rules[0], v):
            assert _accepts(rpy_angles, [v, 0.0, 0.0], "--rpy"), v
