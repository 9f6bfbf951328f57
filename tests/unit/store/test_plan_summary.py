"""One summary of a plan (:class:`~spm_console.core.plan.PlanSummary`), whoever shows it.

The CLI's ``plan`` record, a plan file's header, a run log's record of its plans, a script's
plan step and the console's plan text all render the same object: the figures they share
have one set of names and one value each, and the text forms show those values.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, cast

import numpy as np
import pytest

from spm_console.cli.plan import _human, summary
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.servo.model import discretize
from spm_console.jsonutil import to_jsonable
from spm_console.motion.plans import plan_summary, synthetic_plan
from spm_console.scripting.runner import ScriptRunner
from spm_console.scripting.steps import PlanStep, Script
from spm_console.services.plan_store import PlanInfo
from spm_console.services.session import Session
from spm_console.store.plan_file import plan_to_dict
from spm_console.tui.screens.plan_words import plan_text
from tests.support.planning_cases import GOAL, START, polytope

FIGURES = ("kind", "Ts", "N", "duration_s", "cost", "solve_seconds", "qp_count")


@pytest.fixture(scope="module", params=["mvn", "synthetic"])
def plan(request: pytest.FixtureRequest, agile: Profile) -> Plan:
    if request.param == "synthetic":
        return synthetic_plan(agile, np.array([130.0, 135.0, 140.0]),
                              np.array([120.0, 128.0, 131.0]), 0.5)
    sv = agile.servo
    res = solve_mvn(discretize(sv.p, sv.ts_s, sv.discretization), START, GOAL, 60, polytope())
    return res.to_plan("mvn", "hash")


def _script_record(plan: Plan) -> tuple[dict[str, Any], str]:
    """What a script's plan step reports, the session solving to ``plan``."""
    step = PlanStep.model_validate({"do": "plan", "start": "home", "goal": "home"})
    session = SimpleNamespace(wrist=SimpleNamespace(workspace=object()), theta_deg=None,
                              plans=SimpleNamespace(solve=lambda *args: plan))
    runner = ScriptRunner(Script(step=(step,)), cast(Session, session))
    return runner._step_plan(step)


def test_every_record_of_a_plan_names_its_figures_alike(plan: Plan) -> None:
    s = plan.summary()
    want = to_jsonable(s.figures())
    assert tuple(s.figures()) == FIGURES
    cli = to_jsonable(summary(s, None, "P"))
    records = {"cli": cli, "plan file": plan_to_dict(plan),
               "run log": to_jsonable(plan_summary(plan)),
               "script": to_jsonable(_script_record(plan)[0])}
    for where, rec in records.items():
        assert {k: rec[k] for k in FIGURES} == want, where
    # the plan's ends: the model's θ(0), θ(N) where a front end shows them
    assert cli["start_deg"] == list(s.start_deg) == plan.position_deg[0].tolist()
    assert cli["goal_deg"] == list(s.goal_deg) == plan.position_deg[-1].tolist()
    script = records["script"]
    assert script["start_deg"] == pytest.approx(s.start_deg, abs=1e-6)
    assert script["goal_deg"] == pytest.approx(s.goal_deg, abs=1e-6)
    assert script["max_speed_degps"] == s.max_speed_degps
    assert s.max_speed_degps == float(np.abs(plan.velocity_degps).max())
    # a run log records the ends of the references sent
    assert records["run log"]["first_reference_deg"] == plan.reference_deg[0].tolist()
    assert records["run log"]["last_reference_deg"] == plan.reference_deg[-1].tolist()
    assert "start_deg" not in records["run log"]  # θ*(0) is not the start θ(0)


def test_the_text_forms_show_the_summarys_values(plan: Plan) -> None:
    s = plan.summary()
    cli = _human(s, None, s.stored_region())
    assert cli.startswith(f"{s.kind}: N = {s.N} ({s.duration_s:.2f} s), cost {s.cost:.6g}")
    assert f"region: stored in the plan ({s.halfspaces} half-spaces)" in cli
    tui = plan_text(plan, PlanInfo.of_file(plan, "plan.json"))
    assert f"N = {s.N} × {s.Ts:g} s = {s.duration_s:.2f} s" in tui
    assert f"max |dθ/dt| {s.max_speed_degps:.1f}°/s at samples" in tui
    assert f"({s.qp_count} QP)" in tui
    if s.verified is not None:
        assert ("constraints verified" if s.verified else "constraints NOT verified") in tui
    _, script = _script_record(plan)
    assert script == (f"{s.kind} N = {s.N} ({s.duration_s:.2f} s), solved in "
                      f"{s.solve_seconds:.2f} s")
