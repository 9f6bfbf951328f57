"""The runtime's plan verification and safety monitor with the refined certification: the
paper's minimum-time pair plans and verifies on the 2° grid (the grid alone refuses its
motion); the runtime computes its own fine verdicts and still refuses what neither criterion
certifies."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

from spm_console.config.models import servo_limits_deg, servo_model_of
from spm_console.core.planning.mintime import solve_mintime_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.regions.choice import choose_region
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.refine import RefinedCertifiedSet
from spm_console.errors import PlanRefusedError
from spm_console.motion.plan_check import PlanVerifier, verify_plan
from spm_console.motion.plans import synthetic_plan
from spm_console.motion.safety import SafetyMonitor
from spm_console.motion.segments import Segment
from spm_console.store.plan_file import plan_hash
from tests.support.ws_helpers import MINTIME_START, MVN_GOAL, agile_profile, agile_workspace


@pytest.fixture(scope="module")
def ws() -> Workspace:
    return agile_workspace()


def test_the_paper_mintime_pair_plans_and_verifies_on_the_2deg_grid(ws: Workspace) -> None:
    prof = agile_profile()
    start, goal = np.array(MINTIME_START, float), np.array(MVN_GOAL, float)
    choice = choose_region(ws, start, goal)  # the single-region planner (reproduce uses it)
    assert choice.kind == "refined"
    lo, hi = servo_limits_deg(prof)
    plan = solve_mintime_problem(PlanProblem(
        servo_model_of(prof), start, goal, 2, choice.region, 50.0, ref_lo_deg=lo,
        ref_hi_deg=hi)).to_plan("mintime", plan_hash(prof))
    # the lower bound: joint 2 travels 65° at ≤ 50°/s (1.30 s = 65 samples)
    assert plan.N >= 65
    assert plan.certificate is not None
    check = verify_plan(prof, ws, plan)
    assert check.points > plan.N
    # a fresh verifier (its own fine verdicts) accepts it; the grid criterion alone does not
    PlanVerifier(prof, ws).verify([Segment("plan", plan)])
    coarse_only = PlanVerifier(prof, replace(ws, model=None, links=None))
    assert not isinstance(coarse_only.certified, RefinedCertifiedSet)
    with pytest.raises(PlanRefusedError, match="does not certify"):
        coarse_only.verify([Segment("plan", plan)])


def test_motion_toward_a_singular_fine_node_is_refused(ws: Workspace) -> None:
    """From a feasible grid node straight toward a singular fine node 0.5° away."""
    prof = agile_profile()
    start = np.array([155.0, 107.0, 71.0])
    plan = synthetic_plan(prof, start, start - np.array([0.0, 1.5, 0.0]), 1.0)
    with pytest.raises(PlanRefusedError, match=re.escape("within h = 0.5° of a fine node")):
        verify_plan(prof, ws, plan)


def test_the_safety_monitor_shares_the_refined_set(ws: Workspace) -> None:
    prof = agile_profile()
    v = PlanVerifier(prof, ws)
    mon = SafetyMonitor(prof, v.certified)
    a, b = np.array(MINTIME_START), np.array(MVN_GOAL)
    # the point of the paper's segment closest to the singular grid node [65, 153, 127]°
    seg = a + (b - a) * np.linspace(0, 1, 4001)[:, None]
    p = seg[np.argmin(np.abs(seg - np.array([65.0, 153.0, 127.0])).max(1))]
    assert mon.position(p, p, True, 0.0, 0) is None
    bad = np.array([155.0, 106.0, 71.0])  # 1° from the singular grid node [155, 105, 71]°
    stop = mon.position(bad, bad, True, 0.0, 0)
    assert stop is not None and stop.kind == "region"
