"""Planning bounds: horizon and problem-size caps, a minimum-time search that refuses at once
when the horizon cannot suffice, references put exactly on a servo limit they pass by
round-off only, and the executor's 1e-9° tolerance on that boundary."""

from __future__ import annotations

import time

import numpy as np
import pytest

from spm_console.core.bounds import MAX_INSTANTS, N_MAX
from spm_console.core.plan_rules import LIMIT_TOL_DEG
from spm_console.core.planning.mintime import solve_mintime
from spm_console.core.planning.mvn import ROUND_OFF_DEG, clamp_round_off
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.polytope.region import Region
from spm_console.errors import BadInputError, InfeasibleError, PlanRefusedError
from spm_console.motion.plans import plan_from_references
from spm_console.motion.segments import Segment
from tests.support.planning_cases import GOAL, MODEL, START, START_MT, polytope

LO, HI = np.full(3, 60.0), np.full(3, 160.0)


@pytest.mark.parametrize(("n", "k", "words"), [
    (N_MAX + 1, 1, "2..5000"),
    (1, 1, "2..5000"),
    (N_MAX, 100, f"{MAX_INSTANTS:,}"),
    (2000, 51, "constrained instants"),
])
def test_problem_size_is_capped(n: int, k: int, words: str) -> None:
    with pytest.raises(BadInputError, match=words):
        PlanProblem(MODEL, START, GOAL, n, polytope(), None, k)


@pytest.mark.parametrize("vmax", [0.01, 1e-300, 5e-324])
def test_mintime_refuses_at_once_when_the_horizon_cannot_suffice(vmax: float) -> None:
    t0 = time.perf_counter()
    with pytest.raises(InfeasibleError, match=r"N ≤ 5000 steps .*at least about 0\.65 deg/s"):
        solve_mintime(MODEL, START_MT, GOAL, Region.box(65.0, 155.0), vmax)
    assert time.perf_counter() - t0 < 1.0  # no solve was attempted


def test_mintime_intersample_lowers_the_horizon_limit() -> None:
    with pytest.raises(InfeasibleError, match="N ≤ 1000 steps"):
        solve_mintime(MODEL, START_MT, GOAL, Region.box(65.0, 155.0), 2.0, intersample=100)


@pytest.mark.parametrize("vmax", [500.0, 1000.0])
def test_fast_mintime_references_stay_exactly_inside_the_servo_limits(vmax: float) -> None:
    """At these speeds θ* ≤ 160° is active; the solver meets it only to ~5e-12°, and a
    reference past it by round-off is put on it: none lies beyond."""
    res = solve_mintime(MODEL, START, GOAL, polytope(), vmax, ref_lo_deg=LO, ref_hi_deg=HI)
    ref = res.plan.reference_deg
    assert 160.0 - 1e-9 < ref.max() <= 160.0 and ref.min() >= 60.0
    assert res.plan.check.ok


def test_clamp_touches_round_off_only() -> None:
    pb = PlanProblem(MODEL, START, GOAL, 10, polytope(), None, 1, True, LO, HI)
    ref = np.array([[160.0 + 5e-12, 60.0 - ROUND_OFF_DEG, 100.0],
                    [160.0 + 2e-6, 59.0, 160.0]])
    out = clamp_round_off(pb, ref)
    np.testing.assert_array_equal(out, [[160.0, 60.0, 100.0], [160.0 + 2e-6, 59.0, 160.0]])


def _with_joint2_max(agile, max_deg: float):  # type: ignore[no-untyped-def]
    j = list(agile.bus.joints)
    j[1] = j[1].model_copy(update={"max_deg": max_deg})
    return agile.model_copy(update={"bus": agile.bus.model_copy(update={"joints": tuple(j)})})


def test_executor_accepts_the_limit_within_1e_9(agile, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A reference 5e-10° past a servo limit runs to the end with the goal written exactly on
    the limit (the bus refuses any goal past it); 1e-7° past it is refused before torque-on."""
    from spm_console.motion.executor import Executor
    from tests.support.fake_bus import FakeBus, SimClock
    from tests.support.ws_helpers import agile_workspace

    top = 1593 * 360.0 / 4096  # a limit on a tick (the fake bus measures whole ticks)
    prof = _with_joint2_max(agile, top)
    ref = np.tile([100.0, top - 0.1, 100.0], (30, 1))
    ref[5:, 1] = top + 0.5 * LIMIT_TOL_DEG
    bus = FakeBus(ref[0], clock=SimClock())
    ex = Executor(prof, bus, workspace=agile_workspace(), clock=bus.clock, sleep=bus.clock.sleep,
                  on_start=bus.start_clock)
    res = ex.run([Segment("plan", plan_from_references(prof, ref, "synthetic"))])
    assert res.ok, res.message
    assert max(w[1][1] for w in bus.writes) == top
    ref[5:, 1] = top + 1e-7
    with pytest.raises(PlanRefusedError, match="outside the servo limits"):
        Executor(prof, FakeBus(ref[0], clock=SimClock()), workspace=agile_workspace()).run(
            [Segment("plan", plan_from_references(prof, ref, "synthetic"))])
