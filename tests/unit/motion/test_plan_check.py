"""The runtime's plan verification: the certified set against a brute-force reference, and
every refusal the executor must make whatever a plan file claims."""

from __future__ import annotations

import itertools
import math
import re

import numpy as np
import pytest

from spm_console.config.models import build_workspace, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.plan_rules import MAX_REFERENCE_STEP_DEG, Rule, Violation, check_motion
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.polytope.region import Region
from spm_console.core.regions.choice import region_containing
from spm_console.core.workspace.certify import CertifiedSet
from spm_console.core.workspace.data import Workspace
from spm_console.errors import InfeasibleError, PlanRefusedError
from spm_console.motion.plan_check import PlanVerifier, verify_plan
from spm_console.motion.plans import plan_from_references, synthetic_plan
from spm_console.motion.segments import Segment
from tests.support.ws_helpers import MVN_GOAL, MVN_START, agile_profile, agile_workspace, with_step


def _brute_force(ws: Workspace, theta: np.ndarray, half: float) -> bool:
    """Every grid node within the open cube of half-width ``half`` exists and is feasible."""
    idx_ranges = []
    for a, t in zip(ws.axes_deg, theta, strict=True):
        near = [k for k in range(len(a)) if abs(a[k] - t) < half]
        lo, hi = a[0], a[-1]
        # a node position within half of θ that is off the grid: uncertified
        for m in range(-3, 4):
            pos = a[0] + (math.floor((t - a[0]) / ws.step_deg) + m) * ws.step_deg
            if abs(pos - t) < half and not (lo - 1e-12 <= pos <= hi + 1e-12):
                return False
        idx_ranges.append(near)
    return all(bool(ws.feasible[i, j, k]) for i, j, k in itertools.product(*idx_ranges))


@pytest.mark.parametrize("half_frac", [1.0, 0.75, 0.55])
def test_certified_set_matches_brute_force(half_frac: float) -> None:
    ws = agile_workspace()
    cs = ws.certified_set()
    rng = np.random.default_rng(7)
    pts = rng.uniform(60.0, 160.0, size=(1500, 3))
    # points on grid planes and nodes, where the open cube shrinks
    nodes = ws.theta_deg().reshape(-1, 3)[rng.integers(0, ws.feasible.size, 300)]
    pts = np.vstack([pts, nodes, nodes + np.array([0.5 * ws.step_deg, 0.0, 0.0])])
    half = half_frac * ws.step_deg
    got = cs.contains(pts, half)
    want = np.array([_brute_force(ws, p, half) for p in pts])
    assert got.sum() > 100 and (~got).sum() > 100
    assert np.array_equal(got, want)


def test_region_p_lies_in_the_certified_set() -> None:
    ws = agile_workspace()
    rng = np.random.default_rng(3)
    lo, hi = ws.range_deg()
    pts = rng.uniform(lo, hi, size=(200_000, 3))
    inside = pts[ws.region.contains(pts)]
    assert len(inside) > 10_000
    assert ws.certified_set().contains(inside).all()


def test_non_finite_points_are_not_certified() -> None:
    cs = CertifiedSet(np.ones((3, 3, 3), bool), np.zeros(3), 1.0)
    got = cs.contains(np.array([[1.0, 1.0, 1.0], [np.nan, 1.0, 1.0], [1.0, np.inf, 1.0]]))
    assert got.tolist() == [True, False, False]


def _paper_mvn(prof: Profile, ws: Workspace) -> Plan:
    region = region_containing(ws, np.array(MVN_START), np.array(MVN_GOAL))
    return solve_mvn(servo_model_of(prof), np.array(MVN_START), np.array(MVN_GOAL), 150,
                     region).to_plan("mvn")


def test_the_paper_mvn_plan_verifies() -> None:
    prof, ws = agile_profile(), agile_workspace()
    check = verify_plan(prof, ws, _paper_mvn(prof, ws))
    assert check.points > 1500 and check.max_speed_degps < prof.limits.vmax_degps


def _with(plan: Plan, **upd: object) -> Plan:
    return type(plan)(**{**plan.__dict__, **upd})


def test_a_reference_jump_is_refused() -> None:
    prof, ws = agile_profile(), agile_workspace()
    ref = np.repeat(np.array([MVN_START]), 60, axis=0)
    ref[30:, 1] += 12.0  # one step larger than the bound
    plan = plan_from_references(prof, ref, "synthetic")
    with pytest.raises(PlanRefusedError, match=f"jumps 12.00° .*at most {MAX_REFERENCE_STEP_DEG:g}°"):
        verify_plan(prof, ws, plan)


def test_a_99_degree_step_is_refused() -> None:
    prof, ws = agile_profile(), agile_workspace()
    ref = np.repeat(np.array([[60.0, 100.0, 100.0]]), 40, axis=0)
    ref[20:, 0] = 60.0 + 99.0  # within the servo limits [60, 160]°
    with pytest.raises(PlanRefusedError, match=re.escape("jumps 99.00°")):
        verify_plan(prof, ws, plan_from_references(prof, ref, "synthetic"))


def test_too_fast_is_refused_at_the_samples() -> None:
    prof, ws = agile_profile(), agile_workspace()
    plan = synthetic_plan(prof, np.array([120.0, 100.0, 110.0]), np.array([140.0, 125.0, 95.0]), 0.7)
    with pytest.raises(PlanRefusedError, match=re.escape("limits.vmax_degps = 50°/s")):
        verify_plan(prof, ws, plan)


def test_a_colliding_goal_is_refused_whatever_the_region() -> None:
    prof, ws = agile_profile(), agile_workspace()
    start, goal = np.array([100.0, 100.0, 110.0]), np.array([73.0, 65.5, 113.0])
    plan = _with(synthetic_plan(prof, start, goal, 2.0), region=Region.box(60.0, 160.0))
    with pytest.raises(PlanRefusedError, match="does not certify"):
        verify_plan(prof, ws, plan)


def test_servo_limit_tolerance_is_1e_9_degrees() -> None:
    prof, ws = agile_profile(), agile_workspace()
    v = PlanVerifier(prof, ws)
    hi = v.hi[1]
    ok = np.array([[100.0, hi + 5e-12, 100.0]])

    def limits(ref: np.ndarray) -> Violation | None:  # the verifier's rules, no certification
        x0 = np.column_stack([ref[0], np.zeros(3)])
        return check_motion(prof.servo.p, prof.servo.ts_s, x0, ref, v.lo, v.hi, v.vmax, None).violation

    assert limits(ok) is None
    bad = limits(ok + np.array([0.0, 1e-6, 0.0]))
    assert bad is not None and bad.rule is Rule.REFERENCE_LIMIT and bad.bound == hi
    with pytest.raises(PlanRefusedError, match="outside the servo limits"):
        verify_plan(prof, ws, plan_from_references(prof, ok + np.array([0.0, 1e-6, 0.0]), "synthetic"))


def test_wrong_ts_and_non_finite_references_are_refused() -> None:
    prof, ws = agile_profile(), agile_workspace()
    plan = _paper_mvn(prof, ws)
    with pytest.raises(PlanRefusedError, match=re.escape("Ts = 0.01")):
        verify_plan(prof, ws, _with(plan, Ts=0.01))
    ref = plan.reference_deg.copy()
    ref[5, 2] = np.nan
    with pytest.raises(PlanRefusedError, match="finite"):
        verify_plan(prof, ws, _with(plan, reference_deg=ref))


@pytest.fixture(scope="module")
def fat_links() -> tuple[Profile, Workspace]:
    """δ = 35 mm: every configuration collides, the workspace has no feasible node."""
    base = with_step(agile_profile(), 5.0)
    prof = base.model_copy(update={"links": base.links.model_copy(update={"delta_mm": 35.0})})
    return prof, build_workspace(prof)


def test_a_workspace_without_feasible_nodes_certifies_nothing(
        fat_links: tuple[Profile, Workspace]) -> None:
    prof, ws = fat_links
    assert ws.counts()["feasible"] == 0
    a, b = np.array([127.53, 83.23, 85.25]), np.array([66.80, 155.00, 131.48])
    with pytest.raises(InfeasibleError, match="no feasible node"):
        region_containing(ws, a, b)
    plan = synthetic_plan(prof, a, a, 0.5)
    with pytest.raises(PlanRefusedError, match="no feasible node"):
        verify_plan(prof, ws, plan)


def test_a_homing_line_through_a_collision_is_refused() -> None:
    prof, ws = agile_profile(), agile_workspace()
    from spm_console.motion.plans import line_plan

    line = line_plan(prof, np.array([73.0, 65.5, 113.0]), np.array(prof.home.theta_deg), 20.0)
    with pytest.raises(PlanRefusedError, match="links collide"):
        PlanVerifier(prof, ws).verify([Segment("homing", line)])
    fine = line_plan(prof, np.array([110.0, 150.0, 125.0]), np.array(prof.home.theta_deg), 20.0)
    PlanVerifier(prof, ws).verify([Segment("homing", fine)])
