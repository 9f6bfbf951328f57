"""Plans across several regions: the route search, the QP with switch samples, checked
against an independent cvxpy formulation and by exact membership of the motion."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.planning.mintime import solve_mintime_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.route_search import find_route, solve_route_mvn
from spm_console.core.polytope.region import Region
from spm_console.core.regions.route import RegionRoute, spread
from spm_console.core.servo.model import simulate_continuous
from spm_console.errors import InfeasibleError
from tests.support.planning_cases import MODEL
from tests.support.reference_qp import solve_reference

# An L: region 0 spans θ1 in 60..110 with θ2 in 60..80; region 1 spans θ1 in 90..110 with
# θ2 in 60..140 (θ3 in 60..100 for both). Their overlap is θ1 90..110, θ2 60..80.
BOX0 = Region(np.vstack([np.eye(3), -np.eye(3)]), np.array([110, 80, 100, -60, -60, -60.0]))
BOX1 = Region(np.vstack([np.eye(3), -np.eye(3)]), np.array([110, 140, 100, -90, -60, -60.0]))
START = np.array([65.0, 70.0, 80.0])  # only in region 0
GOAL = np.array([100.0, 135.0, 80.0])  # only in region 1
OVERLAP = np.array([[100.0, 70.0, 80.0]])

def _in_union(th: np.ndarray) -> np.ndarray:
    return BOX0.contains(th, 1e-6) | BOX1.contains(th, 1e-6)

def test_route_joins_two_regions_whose_union_is_not_convex() -> None:
    assert not _in_union(START + 0.5 * (GOAL - START))  # the straight segment leaves both
    choice = find_route([BOX0, BOX1], OVERLAP, START, GOAL)
    assert choice is not None and choice.regions == (0, 1)
    np.testing.assert_array_equal(choice.waypoints_deg[1], OVERLAP[0])
    assert find_route([BOX0, BOX1], np.zeros((0, 3)), START, GOAL) is None  # no overlap known
    assert find_route([BOX1], OVERLAP, START, GOAL) is None  # the start is in no region

def test_switch_samples_spread_inside_the_horizon() -> None:
    assert spread([0.5], 10) == (5,)
    assert spread([0.0, 0.01, 1.0], 4) == (1, 2, 3)
    with pytest.raises(ValueError):
        spread([0.3, 0.6], 2)
    route = RegionRoute((BOX0, BOX1), (4,))
    m = route.sample_mask(8)
    assert m[4].all() and m[:4, 0].all() and not m[5:, 0].any() and m[5:, 1].all()
    assert route.rescaled(8, 16).switch == (8,)

@pytest.mark.parametrize("vmax", [None, 40.0])
def test_route_mvn_matches_cvxpy_and_the_motion_stays_in_the_union(vmax: float | None) -> None:
    choice = find_route([BOX0, BOX1], OVERLAP, START, GOAL)
    assert choice is not None
    pb = PlanProblem(MODEL, START, GOAL, 150, BOX0, vmax, intersample=4)
    plan = solve_route_mvn(pb, [BOX0, BOX1], choice, labels=("P", "cover 1"))
    res = plan.result
    route = res.problem.route
    assert route is not None and route.count == 2 and res.check.ok
    assert plan.result.cost <= plan.first_cost * (1 + 1e-9)  # the QP's cost, to round-off
    # an independent formulation (cvxpy, Clarabel) of the same assignment: same optimum
    ref = solve_reference(res.problem)
    assert ref.status == "optimal"
    assert res.cost == pytest.approx(ref.cost, rel=1e-4)
    # every sample inside the regions of its intervals; the continuous motion in the union
    k = route.switch[0]
    assert BOX0.contains(res.position_deg[: k + 1], 1e-6).all()
    assert BOX1.contains(res.position_deg[k:], 1e-6).all()
    x0 = np.column_stack([START, np.zeros(3)])
    _, xs = simulate_continuous(MODEL.p, MODEL.ts, x0, res.reference_deg, 40)
    assert _in_union(xs[..., 0]).mean() > 0.999  # intersample K = 4: at most a sliver
    assert res.to_plan().route == route

def test_a_first_optimum_that_holds_no_region_row_ends_the_switch_search(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Wide regions: the first assignment's optimum holds no region row, so no switch sample
    can do better — the search adds no QP, and run anyway it finds nothing cheaper."""
    import spm_console.core.planning.route_search as rs

    wide0 = Region(BOX0.A, BOX0.b + np.array([0, 60, 0, 0, 0, 0.0]))  # θ2 up to 140
    wide1 = Region(BOX1.A, BOX1.b + np.array([0, 0, 0, 30, 0, 0.0]))  # θ1 from 60
    two = rs.RouteChoice((0, 1), np.vstack([START, OVERLAP[0], GOAL]), 0.0)
    pb = PlanProblem(MODEL, START, GOAL, 150, wide0, 40.0)
    plan = solve_route_mvn(pb, [wide0, wide1], two)
    assert plan.qps == 1 and plan.result.working_set is not None
    monkeypatch.setattr(rs, "_holds_region_rows", lambda pool, working: True)
    monkeypatch.setattr(rs._SwitchSearch, "frees_a_held_row", lambda self, pool: True)
    searched = solve_route_mvn(pb, [wide0, wide1], two)
    assert searched.qps > 1
    assert searched.result.cost >= plan.result.cost - 1e-9 * plan.result.cost


@pytest.mark.parametrize("corner", [(109.0, 79.0, 80.0), (91.0, 61.0, 80.0)],
                         ids=["switch-late", "switch-early"])
def test_the_switch_search_finds_the_best_switch_sample(corner: tuple[float, ...]) -> None:
    """A waypoint far from where the motion crosses puts the first switch sample several
    samples off; the search ends at the cheapest switch sample, found independently by
    solving the QP at every sample."""
    from dataclasses import replace

    import spm_console.core.planning.route_search as rs
    from spm_console.core.planning.mvn import run_qp

    N = 60
    choice = rs.RouteChoice((0, 1), np.vstack([START, corner, GOAL]), 0.0)
    pb = PlanProblem(MODEL, START, GOAL, N, BOX0, None)
    plan = solve_route_mvn(pb, [BOX0, BOX1], choice)
    first = pb.with_route(choice.route([BOX0, BOX1], N))
    costs = {}
    for s in range(1, N):
        eq, out = run_qp(first.with_route(replace(first.regions, switch=(s,))))
        if out.status == "solved" and out.z is not None:
            costs[s] = rs.qp_cost(eq, out.z)
    best = min(costs, key=costs.__getitem__)
    assert abs(best - first.regions.switch[0]) >= 4  # the first assignment is off
    assert plan.result.cost == pytest.approx(costs[best], rel=1e-6)


def test_an_assignment_that_frees_no_held_row_costs_no_less_and_is_not_solved() -> None:
    """The search skips a switch sample that frees none of the rows the best optimum holds
    (no QP): solved anyway at every sample, each such assignment costs no less than the
    first one; the samples that can do better all free a held row."""
    from dataclasses import replace

    import spm_console.core.planning.route_search as rs
    from spm_console.core.planning.active_set import WorkingSet
    from spm_console.core.planning.mvn import run_qp
    from spm_console.core.planning.qp_build import Pool

    N = 60
    choice = rs.RouteChoice((0, 1), np.vstack([START, (109.0, 79.0, 80.0), GOAL]), 0.0)
    first = PlanProblem(MODEL, START, GOAL, N, BOX0, None).with_route(
        choice.route([BOX0, BOX1], N))
    eq, out = run_qp(first)
    assert out.certified and out.z is not None
    pool = Pool(first)
    search = rs._SwitchSearch(first, eq, pool, out.z, rs.qp_cost(eq, out.z),
                              WorkingSet(out.active, out.side), max_qps=0)
    skipped = cheaper = 0
    for s in range(1, N):
        cand = first.with_route(replace(first.regions, switch=(s,)))
        c_eq, c_out = run_qp(cand)
        if c_out.status != "solved" or c_out.z is None:
            continue
        cost = rs.qp_cost(c_eq, c_out.z)
        if not search.frees_a_held_row(pool.switched(cand)):
            skipped += 1
            assert cost >= search.cost * (1 - 1e-9), s
        elif cost < search.cost * (1 - 1e-9):
            cheaper += 1
    assert skipped > 0 and cheaper > 0


def test_the_search_solves_no_skipped_assignment_and_none_was_cheaper(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """In the search itself, from first switch samples far off the best one: an assignment
    it skips is never solved, and solved here it costs no less than the best of that
    moment."""
    from dataclasses import replace

    import spm_console.core.planning.route_search as rs
    from spm_console.core.planning.mvn import solved_qp

    solved: list[tuple[int, tuple[int, ...]]] = []
    skipped: list[tuple[PlanProblem, float]] = []
    run_qp, frees = rs.run_qp, rs._SwitchSearch.frees_a_held_row

    def spy_run(problem, *a, **k):  # type: ignore[no-untyped-def]
        solved.append((problem.N, problem.regions.switch))
        return run_qp(problem, *a, **k)

    def spy_frees(self, pool):  # type: ignore[no-untyped-def]
        out = frees(self, pool)
        if not out:
            skipped.append((pool.pb, self.cost))
        return out

    monkeypatch.setattr(rs, "run_qp", spy_run)
    monkeypatch.setattr(rs._SwitchSearch, "frees_a_held_row", spy_frees)
    choice = rs.RouteChoice((0, 1), np.vstack([START, (109.0, 79.0, 80.0), GOAL]), 0.0)
    for N, first in ((60, 12), (60, 48), (100, 90), (150, 15)):
        route = replace(choice.route([BOX0, BOX1], N), switch=(first,))
        pb = PlanProblem(MODEL, START, GOAL, N, BOX0, None).with_route(route)
        eq, out = solved_qp(pb)
        rs.improve_switches(pb, eq, out, 0.0)
    assert skipped
    for pb, best in skipped:
        assert (pb.N, pb.regions.switch) not in solved
        eq, out = run_qp(pb)
        assert out.status != "solved" or out.z is None or rs.qp_cost(eq, out.z) >= best * (1 - 1e-9)


def test_one_region_cannot_and_too_short_a_horizon_is_refused() -> None:
    pb = PlanProblem(MODEL, START, GOAL, 150, BOX0, 40.0)
    with pytest.raises(InfeasibleError):
        pb.check_endpoints()  # the goal is outside region 0
    three = find_route([BOX0, BOX1], OVERLAP, START, GOAL)
    assert three is not None
    with pytest.raises(InfeasibleError, match="too few"):
        solve_route_mvn(PlanProblem(MODEL, START, GOAL, 2, BOX0, 40.0), [BOX0, BOX1, BOX0],
                        type(three)((0, 1, 2), np.zeros((4, 3)), 1.0))

def test_mintime_along_a_route_certifies_its_scope() -> None:
    choice = find_route([BOX0, BOX1], OVERLAP, START, GOAL)
    assert choice is not None
    pb = PlanProblem(MODEL, START, GOAL, 100, BOX0, 50.0)
    mt = solve_mintime_problem(pb.with_route(choice.route([BOX0, BOX1], 100)))
    assert mt.certificate is not None and mt.certificate.valid
    rec = mt.record()
    assert "for this sequence of 2 regions" in rec.describe()
    # the minimum time along the L is longer than the straight distance at v_max allows
    assert mt.N * MODEL.ts > np.abs(GOAL - START).max() / 50.0
    # N* − 1 is infeasible for that assignment: cvxpy agrees
    pb_less = mt.plan.problem.with_steps(mt.N - 1)
    assert solve_reference(pb_less).status == "infeasible"

def test_a_route_plan_file_round_trips_and_edits_are_refused(tmp_path, agile) -> None:  # type: ignore[no-untyped-def]
    import json

    from spm_console.core.servo.model import discretize
    from spm_console.errors import PlanMismatchError
    from spm_console.store.plan_file import load_plan, plan_hash, save_plan

    sv = agile.servo
    model = discretize(sv.p, sv.ts_s, sv.discretization)
    choice = find_route([BOX0, BOX1], OVERLAP, START, GOAL)
    assert choice is not None
    res = solve_route_mvn(PlanProblem(model, START, GOAL, 150, BOX0, 40.0), [BOX0, BOX1], choice,
                          labels=("region A", "region B")).result
    path = tmp_path / "route.json"
    save_plan(res.to_plan("mvn", plan_hash(agile)), path)
    plan = load_plan(path, agile)
    assert plan.route is not None and plan.route.labels == ("region A", "region B")
    assert plan.route.switch == res.problem.regions.switch
    np.testing.assert_array_equal(plan.route.regions[1].b, BOX1.b)
    d = json.loads(path.read_text())
    for edit, why in (
            (lambda d: d["route"].update(switch_samples=[0]), "switch_samples"),
            (lambda d: d["route"].update(switch_samples=[5, 3]), "switch_samples"),
            (lambda d: d["route"]["regions"][0]["b"].__setitem__(0, 111.0), "first region"),
            (lambda d: d["route"]["regions"][1]["b"].__setitem__(1, 100.0), "leave the plan's regions"),
            (lambda d: d.update(route=[1]), "route must be an object")):
        bad = json.loads(json.dumps(d))
        edit(bad)
        (tmp_path / "bad.json").write_text(json.dumps(bad))
        with pytest.raises(PlanMismatchError, match=why):
            load_plan(tmp_path / "bad.json", agile)

@pytest.mark.parametrize("start, goal", [
    ([121.0, 65.0, 87.0], [139.0, 67.0, 107.0]),  # refused by one region: the segment leaves P'
    ([67.0, 129.0, 85.0], [137.0, 69.0, 89.0]),
])
def test_pairs_one_region_refuses_plan_through_the_cover_and_every_point_is_feasible(
        agile, start, goal) -> None:  # type: ignore[no-untyped-def]
    from spm_console.config.models import link_model_of, model_of
    from spm_console.core.workspace.check import check_points
    from spm_console.core.workspace.segment_check import check_segment
    from spm_console.services.plan_request import PlanRequest, plan_motion
    from spm_console.store.workspace_cache import load_or_build

    ws, _ = load_or_build(agile)
    s, g = np.array(start), np.array(goal)
    with pytest.raises(InfeasibleError, match="straight segment"):
        check_segment(ws, s, g)  # the grid's P′ does not hold the straight segment
    planned = plan_motion(agile, ws, PlanRequest("mvn", s, g, 250))  # verified inside
    assert planned.region_kind == "route" and planned.route is not None
    plan = planned.plan
    assert plan.route is not None and plan.route.count >= 2
    assert "route through" in planned.describe_region()
    # independent of the grid: the continuous motion checked exactly (FK in the home modes,
    # ζ ≥ ζ_min, links apart) at 20 points per interval
    x0 = np.column_stack([s, np.zeros(3)])
    _, xs = simulate_continuous(agile.servo.p, agile.servo.ts_s, x0, plan.reference_deg, 20)
    pc = check_points(ws, model_of(agile), link_model_of(agile), xs[..., 0])
    assert pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm).all()


def test_a_switched_pool_is_the_candidates_own_pool() -> None:
    """The switch search reuses the first assignment's pool with other region bounds: row for
    row the pool a candidate would build itself; any other difference is refused."""
    from dataclasses import replace

    from spm_console.core.planning.qp_build import Pool

    choice = find_route([BOX0, BOX1], OVERLAP, START, GOAL)
    assert choice is not None
    pb = PlanProblem(MODEL, START, GOAL, 80, BOX0, 40.0, intersample=4)
    first = pb.with_route(choice.route([BOX0, BOX1], 80))
    cand = first.with_route(replace(first.regions, switch=(first.regions.switch[0] + 3,)))
    own, switched = Pool(cand), Pool(first).switched(cand)
    for name in ("lo", "hi", "scale", "family", "offsets"):
        np.testing.assert_array_equal(getattr(switched, name), getattr(own, name))
    z = np.random.default_rng(1).normal(90.0, 10.0, own.L.n)
    np.testing.assert_array_equal(switched.values(z), own.values(z))
    assert not np.array_equal(switched.hi, Pool(first).hi)  # the switch moved a bound
    with pytest.raises(ValueError, match="only the switch"):
        Pool(first).switched(replace(cand, vmax_degps=45.0))
    with pytest.raises(ValueError, match="only the switch"):
        Pool(first).switched(cand.with_route(RegionRoute((BOX1, BOX0), cand.regions.switch)))


class _CostCurve:
    """What the line search sees of a route with one switch: a cost per switch sample (an
    exact curve here instead of a QP per sample), the best sample, a budget of solves."""

    def __init__(self, cost: dict[int, float], start: int, budget: int, n: int = 150) -> None:
        self.cost, self.best, self.max_qps, self.n = cost, start, budget, n
        self.qps = 0
        self.tried = {start}

    @property
    def spent(self) -> bool:
        return self.qps >= self.max_qps

    def at(self, i: int) -> int:
        return self.best

    def bounds(self, i: int) -> tuple[int, int]:
        return 1, self.n - 1

    def better(self, i: int, sample: int) -> bool:
        s = min(max(sample, 1), self.n - 1)
        if s in self.tried or self.spent:
            return False
        self.tried.add(s)
        self.qps += 1
        if self.cost[s] < self.cost[self.best]:
            self.best = s
            return True
        return False


@pytest.mark.parametrize(("minimum", "budget", "reached"), [
    (20, 4, 21),   # far away: steps of 3, 6, 12, 24 (a walk of 3-sample steps ends at 54)
    (28, 12, 28),  # passed by the growing steps: found back on the other side
    (64, 6, 64),   # passed at the first step: closed in from the other side
])
def test_the_line_search_grows_its_steps_then_closes_in(minimum: int, budget: int,
                                                        reached: int) -> None:
    import spm_console.core.planning.route_search as rs

    curve = _CostCurve({s: float((s - minimum) ** 2) for s in range(1, 150)}, 66, budget)
    if not rs._line_search(curve, 0, -1, rs.FIRST_SWITCH_STEP):  # type: ignore[arg-type]
        rs._line_search(curve, 0, 1, rs.FIRST_SWITCH_STEP)  # type: ignore[arg-type]
    assert curve.best == reached
    assert curve.qps <= budget


def test_a_step_past_the_range_goes_halfway_to_its_end() -> None:
    """The paper pair's shape: the cost falls toward the end of the horizon, where the last
    sample is infeasible (the goal's region keeps one interval). The growing steps go past the
    range; the search goes halfway to the end instead of solving the end, and lands nearer the
    minimum than the end's neighbour it would have reached."""
    import spm_console.core.planning.route_search as rs

    minimum, start, n = 146, 105, 150
    cost = {s: float((s - minimum) ** 2) for s in range(1, n - 1)}
    cost[n - 1] = float("inf")  # infeasible: never better
    curve = _CostCurve(cost, start, 4, n)
    assert rs._line_search(curve, 0, 1, rs.FIRST_SWITCH_STEP)  # type: ignore[arg-type]
    assert n - 1 not in curve.tried
    assert curve.tried == {105, 108, 114, 126, 137}
    assert curve.best == 137
