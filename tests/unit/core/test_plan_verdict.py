"""One plan verdict: the planner's report carries the runtime's rules
(:func:`~spm_console.core.plan_rules.check_motion`), and the planner holds the motion to the
runtime's between-sample speed bound at the instants the runtime checks, so what it returns
the runtime accepts without a second solve."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from spm_console.core.plan_rules import BETWEEN_SPEED_ALLOWANCE, POINTS_PER_INTERVAL, Rule, check_motion
from spm_console.core.planning.mintime import solve_mintime_problem
from spm_console.core.planning.mvn import solve_problem
from spm_console.core.planning.problem import PlanProblem, sub_instants
from spm_console.core.planning.verify import check
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import Dynamics, discretize
from spm_console.errors import BadInputError, PlanMismatchError, SolverError
from spm_console.services.plan_request import PlanRequest, precheck
from spm_console.store.plan_file import load_plan, save_plan
from tests.support.exec_helpers import PAPER_GOAL, PAPER_START, paper_mvn
from tests.support.planning_cases import GOAL, START_MT
from tests.support.ws_helpers import agile_profile

BOX = Region.box(65.0, 155.0)
#: A lightly damped servo with a delay (ωn 60 rad/s, ζ 0.4, 10 ms): between samples its
#: speed overshoots the sampled one by more than the runtime's allowance.
UNDERDAMPED = discretize(Dynamics(60.0, 0.4, 0.01), 0.02)
LO, HI = np.full(3, 60.0), np.full(3, 160.0)


def _problem(check_points: int, vmax: float = 50.0, intersample: int = 1) -> PlanProblem:
    return PlanProblem(UNDERDAMPED, PAPER_START, PAPER_GOAL, 110, BOX, vmax, intersample,
                       check_points=check_points)


def test_the_sub_instants_join_intersample_and_the_runtime_check_instants_once() -> None:
    sub = sub_instants(_problem(POINTS_PER_INTERVAL, intersample=5))
    fifths = {Fraction(j, 5) for j in range(1, 5)}
    tenths = {Fraction(j, 10) for j in range(1, 10)}
    assert set(sub.fractions) == fifths | tenths and len(sub.fractions) == len(fifths | tenths)
    assert list(sub.fractions) == sorted(sub.fractions)
    for f, asked, bound in zip(sub.fractions, sub.requested, sub.speed_bound_degps, strict=True):
        assert asked == (f in fifths)
        assert bound == (50.0 if asked else pytest.approx(50.0 * (1 + BETWEEN_SPEED_ALLOWANCE), abs=1e-5))
    assert sub_instants(_problem(1)).count == 0  # (30) as printed


def test_the_planner_holds_the_runtime_between_sample_speed_bound_by_construction() -> None:
    """Minimum time for a lightly damped servo with a delay: solved at the samples
    only, its optimum breaks the runtime's rule 6, and the planner's verdict (the runtime's
    rules) refuses to return it; with the runtime's instants (the default) the plan meets
    every rule the runtime checks, in one solve, and an independent call of the runtime's
    check agrees."""
    def problem(check_points: int) -> PlanProblem:
        return PlanProblem(UNDERDAMPED, START_MT, GOAL, 60, BOX, 50.0, 1, True, LO, HI,
                           check_points=check_points)

    with pytest.raises(SolverError, match="runtime's rules: speed above the bound between"):
        solve_mintime_problem(problem(1))
    res = solve_mintime_problem(problem(POINTS_PER_INTERVAL)).plan
    assert res.check.ok and res.check.runtime_rule == ""
    again = check_motion(UNDERDAMPED.dynamics, 0.02, np.column_stack([START_MT, np.zeros(3)]),
                         res.reference_deg, LO, HI, 50.0, None)
    assert again.ok
    assert 50.0 < again.max_speed_degps <= 50.0 * (1 + BETWEEN_SPEED_ALLOWANCE)  # binding


def test_the_report_names_the_runtime_rule_a_reference_breaks() -> None:
    res = solve_problem(_problem(POINTS_PER_INTERVAL))
    ref = res.reference_deg.copy()
    ref[40, 1] += 12.0  # a step the runtime refuses (more than 10° between samples)
    report, _, _ = check(_problem(POINTS_PER_INTERVAL), ref)
    assert not report.ok and report.runtime_rule == Rule.STEP.value


def test_the_runtime_rule_crosses_a_plan_file(tmp_path: Path) -> None:
    prof = agile_profile()
    plan = paper_mvn(prof)
    assert plan.check is not None and plan.check.runtime_rule == "" and plan.check.ok
    path = tmp_path / "plan.json"
    save_plan(plan, path)
    back = load_plan(path, prof)
    assert back.check is not None and back.check.runtime_rule == "" and back.check.ok

    doc = json.loads(path.read_text())
    check_of = _find_check(doc)
    for bad in ("no such rule", 3, ["x"], {"a": 1}):
        check_of["runtime_rule"] = bad
        path.write_text(json.dumps(doc))
        with pytest.raises(PlanMismatchError, match="runtime_rule"):
            load_plan(path, prof)
    check_of["runtime_rule"] = Rule.SPEED_BETWEEN.value
    check_of["ok"] = False
    path.write_text(json.dumps(doc))
    back = load_plan(path, prof)
    assert back.check is not None and back.check.runtime_rule == Rule.SPEED_BETWEEN.value
    del check_of["runtime_rule"]  # a file from before the field: empty
    path.write_text(json.dumps(doc))
    again = load_plan(path, prof).check
    assert again is not None and again.runtime_rule == ""


def _find_check(doc: object) -> dict[str, object]:
    """The plan file's ``extra.check`` object, wherever the format nests it."""
    if isinstance(doc, dict):
        if "check" in doc and isinstance(doc["check"], dict) and "points_per_interval" in doc["check"]:
            return doc["check"]
        for v in doc.values():
            found = _find_check(v)
            if found:
                return found
    if isinstance(doc, list):
        for v in doc:
            found = _find_check(v)
            if found:
                return found
    return {}


def test_a_speed_bound_above_the_profile_limit_is_refused_before_planning() -> None:
    """The runtime holds every plan to the profile's limits.vmax_degps: a plan asked for
    faster is refused at once, not solved and then refused by the runtime."""
    prof = agile_profile()
    with pytest.raises(BadInputError, match=r"limits\.vmax_degps"):
        precheck(prof, PlanRequest("mintime", PAPER_START, PAPER_GOAL,
                                   vmax_degps=prof.limits.vmax_degps * 4))
    precheck(prof, PlanRequest("mintime", PAPER_START, PAPER_GOAL,
                               vmax_degps=prof.limits.vmax_degps))
