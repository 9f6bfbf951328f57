"""Planning bounds: horizon and problem-size caps, a minimum-time search that refuses at once
when the horizon cannot suffice, references put exactly on a servo limit they pass by
round-off only, and the executor's 1e-9° tolerance on that boundary."""

from __future__ import annotations

import time

import numpy as np
import pytest

from spm_console.core.bounds import MAX_INSTANTS, N_MAX
from spm_console.core.planning import PlanProblem, solve_mintime
from spm_console.core.planning.mvn import ROUND_OFF_DEG, clamp_round_off
from spm_console.core.region import Region
from spm_console.errors import BadInputError, InfeasibleError
from spm_console.run.plans import plan_from_references
from spm_console.run.segments import LIMIT_TOL_DEG, Segment, check_segments
from tests.planning_cases import GOAL, MODEL, START, START_MT, polytope

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
    """At these speeds the solver meets θ* ≤ 160° only to ~5e-12°; the plan is put on it."""
    res = solve_mintime(MODEL, START, GOAL, polytope(), vmax, ref_lo_deg=LO, ref_hi_deg=HI)
    ref = res.plan.reference_deg
    assert ref.max() == 160.0 and ref.min() >= 60.0
    assert res.plan.check.ok


def test_clamp_touches_round_off_only() -> None:
    pb = PlanProblem(MODEL, START, GOAL, 10, polytope(), None, 1, True, LO, HI)
    ref = np.array([[160.0 + 5e-12, 60.0 - ROUND_OFF_DEG, 100.0],
                    [160.0 + 2e-6, 59.0, 160.0]])
    out = clamp_round_off(pb, ref)
    np.testing.assert_array_equal(out, [[160.0, 60.0, 100.0], [160.0 + 2e-6, 59.0, 160.0]])


def test_executor_accepts_the_limit_within_1e_9(agile) -> None:  # type: ignore[no-untyped-def]
    ref = np.tile([100.0, 159.0, 100.0], (5, 1))
    ref[2, 1] = 160.0 + 0.5 * LIMIT_TOL_DEG
    ok = Segment("move", plan_from_references(agile, ref, "synthetic"))
    check_segments([ok], agile.servo.ts_s, LO, HI)
    assert ok.plan.reference_deg[2, 1] == 160.0  # put on the limit: the bus refuses past it
    assert ref[2, 1] > 160.0  # the caller's array is not written to
    ref[2, 1] = 160.0 + 1e-7
    bad = Segment("move", plan_from_references(agile, ref, "synthetic"))
    with pytest.raises(BadInputError, match=r"θ2\(2\) = 160\.000000° is outside the servo limits"):
        check_segments([bad], agile.servo.ts_s, LO, HI)


def test_a_plan_on_the_limit_by_round_off_runs_to_the_end(agile, tmp_path,  # type: ignore[no-untyped-def]
                                                          capsys) -> None:
    from spm_console.cli.main import main
    from spm_console.plan_file import save_plan

    ref = np.tile([150.0, 159.9, 150.0], (30, 1))
    ref[5:, 1] = 160.0 + 5e-10
    path = tmp_path / "edge.json"
    save_plan(plan_from_references(agile, ref, "synthetic"), path)
    code = main(["execute", "--sim", "--plan", str(path), "--sim-start", "150", "159.9", "150",
                 "--logs", str(tmp_path / "logs")])
    assert code == 0, capsys.readouterr().err
