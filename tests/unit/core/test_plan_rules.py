"""One set of plan rules for the executor's gate before torque-on and the live follower's
check of every re-planned horizon (:mod:`spm_console.core.plan_rules`): the same violating
references are refused by both and a good plan is accepted by both; the
follower's deliberate differences (its speed floor, its rule set) are pinned down too."""

from __future__ import annotations

import functools
import re

import numpy as np
import pytest

from spm_console.config.models import servo_model_of
from spm_console.core.plan_rules import (
    BETWEEN_SPEED_ALLOWANCE,
    EXECUTE_RULES,
    FOLLOW_RULES,
    LIMIT_TOL_DEG,
    MAX_REFERENCE_STEP_DEG,
    POINTS_PER_INTERVAL,
    Rule,
    check_motion,
)
from spm_console.core.planning.follow.result import FollowResult
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.planning.verify import BETWEEN_POINTS
from spm_console.core.regions.choice import region_containing
from spm_console.errors import PlanRefusedError
from spm_console.motion.follow.loop import Follower
from spm_console.motion.plan_check import PlanVerifier
from spm_console.motion.plans import plan_from_references, synthetic_plan
from spm_console.motion.segments import Segment
from tests.support.fake_bus import FakeBus, SimClock
from tests.support.ws_helpers import MVN_GOAL, MVN_START, agile_profile, agile_workspace

F = np.ndarray


@functools.lru_cache(maxsize=1)
def _follower() -> Follower:
    prof = agile_profile()
    return Follower(prof, FakeBus(np.array(MVN_START), clock=SimClock()), workspace=agile_workspace())


def _as_follow_plan(ref: F) -> FollowResult:
    """``ref`` as a re-planned horizon: θ*(0..H−1) = ref, held at its last row (θ(H))."""
    pos = np.vstack([ref, ref[-1:]])
    return FollowResult("tracking", ref, pos, np.zeros_like(pos), ref[-1], ref[-1], False, 0.0,
                        0.0, 0.0, 0.0, 0, False)


def _follow_rule(ref: F) -> Rule | None:
    """The follower's verdict on ``ref`` from rest at ref[0] (the executor's initial state)."""
    f = _follower()
    res, theta = _as_follow_plan(ref), ref[0]
    check = f._plan_check(res, theta, np.zeros(3), theta)
    assert f._plan_ok(res, theta, np.zeros(3), theta) == check.ok
    return None if check.violation is None else check.violation.rule


def _executor_refusal(ref: F) -> str | None:
    prof = agile_profile()
    plan = plan_from_references(prof, ref, "synthetic")
    try:
        PlanVerifier(prof, agile_workspace()).verify([Segment("plan", plan)])
    except PlanRefusedError as e:
        return str(e)
    return None


def _paper_mvn() -> F:
    ws = agile_workspace()
    start, goal = np.array(MVN_START), np.array(MVN_GOAL)
    plan = solve_mvn(servo_model_of(agile_profile()), start, goal, 150,
                     region_containing(ws, start, goal)).to_plan("mvn")
    return np.asarray(plan.reference_deg, float)


def _jump() -> F:
    ref = np.repeat(np.array([MVN_START]), 60, axis=0)
    ref[30:, 1] += MAX_REFERENCE_STEP_DEG + 2.0
    return ref


def _past_limit() -> F:
    ref = np.repeat(np.array([[150.0, 120.0, 120.0]]), 60, axis=0)
    ref[:, 0] = np.minimum(150.0 + 0.5 * np.arange(60), 160.0)
    ref[40:, 0] = 160.0 + 1e3 * LIMIT_TOL_DEG
    return ref


def _too_fast() -> F:
    prof = agile_profile()
    return synthetic_plan(prof, np.array([120.0, 100.0, 110.0]), np.array([140.0, 125.0, 95.0]),
                          0.4).reference_deg


def _uncertified() -> F:
    return synthetic_plan(agile_profile(), np.array([100.0, 100.0, 110.0]),
                          np.array([73.0, 65.5, 113.0]), 2.0).reference_deg


def _not_finite() -> F:
    ref = np.repeat(np.array([MVN_START]), 30, axis=0)
    ref[10, 2] = np.nan
    return ref


@pytest.mark.parametrize(("make", "rule", "words"), [
    (_jump, Rule.STEP, "jumps 12.00°"),
    (_past_limit, Rule.REFERENCE_LIMIT, "outside the servo limits"),
    (_too_fast, Rule.SPEED_BETWEEN, "model speed of joint"),
    (_uncertified, Rule.NOT_CERTIFIED, "does not certify"),
    (_not_finite, Rule.NOT_FINITE, "finite"),
], ids=["step", "servo limit", "too fast", "not certified", "not finite"])
def test_the_executor_and_the_follower_refuse_the_same_plans(make, rule, words) -> None:  # type: ignore[no-untyped-def]
    ref = make()
    refusal = _executor_refusal(ref)
    assert refusal is not None and re.search(words, refusal), refusal
    assert _follow_rule(ref) is rule


def test_the_executor_and_the_follower_accept_a_good_plan() -> None:
    ref = _paper_mvn()
    assert _executor_refusal(ref) is None
    assert _follow_rule(ref) is None


def test_a_joint_already_too_fast_may_go_on_but_not_faster() -> None:
    """The follower's speed floor: from a predicted state faster than the bound, a plan that
    slows down is accepted; the same motion is above the bound for the executor's rules."""
    f, prof = _follower(), agile_profile()
    cap = prof.limits.vmax_degps * (1.0 + BETWEEN_SPEED_ALLOWANCE)
    theta = np.array(MVN_START)
    omega = np.array([1.2 * cap, 0.0, 0.0])
    ref = np.repeat(theta[None] + np.array([[1.0, 0.0, 0.0]]), 30, axis=0)
    assert f._plan_ok(_as_follow_plan(ref), theta, omega, ref[0])
    x0 = np.column_stack([theta, omega])
    executed = check_motion(prof.servo.p, prof.servo.ts_s, x0, ref, f.lo, f.hi,
                            prof.limits.vmax_degps, f.verifier.certified, rules=EXECUTE_RULES)
    assert executed.violation is not None and executed.violation.rule is Rule.SPEED_AT_SAMPLE
    faster = check_motion(prof.servo.p, prof.servo.ts_s, x0, ref + np.array([8.0, 0.0, 0.0]),
                          f.lo, f.hi, prof.limits.vmax_degps, f.verifier.certified,
                          rules=FOLLOW_RULES, previous_reference_deg=ref[0],
                          speed_floor_degps=np.abs(omega))
    assert faster.violation is not None and faster.violation.rule is Rule.SPEED_BETWEEN
    assert faster.violation.bound == pytest.approx(1.2 * cap)


def test_the_follower_counts_the_step_from_the_reference_in_use() -> None:
    f, ref = _follower(), _paper_mvn()[:50]
    prev = ref[0] - np.array([0.0, MAX_REFERENCE_STEP_DEG + 1.0, 0.0])
    check = f._plan_check(_as_follow_plan(ref), ref[0], np.zeros(3), prev)
    assert check.violation is not None and check.violation.rule is Rule.STEP
    assert check.violation.index == -1 and check.violation.joint == 1


def test_the_planners_report_simulates_between_samples_at_least_as_finely() -> None:
    assert BETWEEN_POINTS >= POINTS_PER_INTERVAL
