"""One region graph (issue 26): the planner's route and the follower's region hopper search the
same graph with the same search, and every "is this point in this region" uses one tolerance
unless a named rule says otherwise."""

from __future__ import annotations

import subprocess
import sys
from typing import Any

import numpy as np
import pytest

import spm_console.core.polytope.graph as graph_module
from spm_console.core.planning.route_search import find_route
from spm_console.core.polytope.graph import RegionGraph, cheapest_paths, containing, members
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.core.regions.cover_refine import CLEAR_TOL_DEG
from spm_console.motion.follow.regions import RegionHopper


def _box(lo: tuple[float, float], hi: tuple[float, float]) -> Region:
    """[lo, hi] in (θ1, θ2) × [0, 4] in θ3, deg."""
    A = np.vstack([np.eye(3), -np.eye(3)])
    return Region(A, np.r_[hi[0], hi[1], 4.0, -lo[0], -lo[1], 0.0])


#: Two ways from B0 to B2: the short lane B1, or the long way round B3, B4, B5.
BOXES = (_box((0, 0), (4, 4)), _box((3, 0), (11, 4)), _box((10, 0), (14, 4)),
         _box((0, 3), (4, 20)), _box((0, 16), (14, 20)), _box((10, 3), (14, 20)))
#: The overlaps' centres (one edge each).
OVERLAPS = {(0, 1): (3.5, 2, 2), (1, 2): (10.5, 2, 2), (0, 3): (2, 3.5, 2),
            (3, 4): (2, 18, 2), (4, 5): (12, 18, 2), (2, 5): (12, 3.5, 2)}
START = np.array([1.0, 1.0, 2.0])  # in B0 only
GOAL = np.array([13.0, 1.0, 2.0])  # in B2 only


def _graph(without: int | None = None) -> RegionGraph:
    keys = [k for k in OVERLAPS if without not in k]
    return RegionGraph(BOXES, np.array(keys, np.int64).reshape(-1, 2),
                       np.array([OVERLAPS[k] for k in keys], float).reshape(-1, 3))


@pytest.mark.parametrize(("without", "way"), [(None, (0, 1, 2)), (1, (0, 3, 4, 5, 2))])
def test_the_planner_and_the_follower_take_the_same_way(without: int | None,
                                                        way: tuple[int, ...]) -> None:
    g = _graph(without)
    choice = find_route(g.regions, g.points_deg, START, GOAL)
    assert choice is not None and choice.regions == way
    hopper = RegionHopper(g, START)
    assert hopper.current == 0
    assert tuple(hopper.paths.path(0, 2) or ()) == way
    region, aim = hopper.aim(START, GOAL)  # heads for the overlap with the route's next region
    assert region == 0 and aim is not None
    np.testing.assert_array_equal(aim, OVERLAPS[(0, way[1])])


def test_the_planner_and_the_follower_search_with_the_region_graphs_search(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Both go through :func:`cheapest_paths` of the region graph module: a search written
    again in either place would not be seen here."""
    calls: list[int] = []
    real = graph_module.cheapest_paths

    def spy(n: int, pairs: Any, cost: Any, sources: Any = None) -> graph_module.Paths:
        calls.append(n)
        return real(n, pairs, cost, sources)

    monkeypatch.setattr(graph_module, "cheapest_paths", spy)
    g = _graph()
    assert find_route(g.regions, g.points_deg, START, GOAL) is not None
    assert calls == [2 + len(OVERLAPS)]  # the planner: start, goal and the overlaps' centres
    RegionHopper(g, START)
    assert calls == [2 + len(OVERLAPS), len(BOXES)]  # the follower: the regions


def test_cheapest_paths() -> None:
    pairs = np.array([[0, 1], [1, 2], [0, 2], [3, 4]], np.int64)
    paths = cheapest_paths(5, pairs, np.array([1.0, 1.0, 3.0, 1.0]))
    assert paths.path(0, 2) == [0, 1, 2] and paths.cost(0, 2) == 2.0
    assert paths.path(2, 0) == [2, 1, 0]
    assert paths.path(0, 4) is None and np.isinf(paths.cost(0, 4))
    assert cheapest_paths(5, pairs, np.array([1.0, 1.0, 1.5, 1.0]), [0]).path(0, 2) == [0, 2]
    with pytest.raises(ValueError, match="positive"):
        cheapest_paths(3, pairs[:2], np.array([1.0, 0.0]))


def test_one_membership_tolerance() -> None:
    """A point outside a face by half the tolerance is inside for every membership test, one
    outside by twice the tolerance for none of them."""
    box = BOXES[0]
    near = np.array([-0.5 * INSIDE_TOL_DEG, 1.0, 1.0])
    far = np.array([-2.0 * INSIDE_TOL_DEG, 1.0, 1.0])
    assert bool(box.contains(near)) and not bool(box.contains(far))
    assert containing([box], near) == [0] and containing([box], far) == []
    assert members([box], np.stack([near, far])).tolist() == [[True], [False]]
    assert _graph().containing(near) == [0] and _graph().containing(far) == []
    assert find_route([box], np.zeros((0, 3)), near, START) is not None
    assert find_route([box], np.zeros((0, 3)), far, START) is None


def test_the_named_tolerances_that_are_not_membership() -> None:
    # a box is clear of a region when the region reaches into it no deeper than a point
    # counted inside the region may lie outside it
    assert CLEAR_TOL_DEG == INSIDE_TOL_DEG
    # the follower's tolerance has one name (FOLLOW_TOL_DEG), which the runtime and the
    # console read without loading a solver
    code = ("import sys; import spm_console.core.planning.follow.tolerance, "
            "spm_console.motion.follow.regions, spm_console.tui.screens.jog_target; "
            "print(sorted(m for m in ('osqp', 'clarabel', 'cvxpy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.strip() == "[]"
