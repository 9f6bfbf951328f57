"""Plans across several convex regions: a route on the region graph, then the QP.

The regions (a cover of the feasible set, each certified like P) and their overlaps form
a graph. A route from start to goal is a shortest path through *waypoints*: the start,
the goal and one point deep inside every overlap (its Chebyshev centre). Two waypoints
are joined when one region holds both (the straight move between them then stays in
that region, which is convex); a hop costs its largest joint move (the time a
speed-bounded move needs) plus a small Euclidean tie-break (the region graph's search,
:func:`~spm_console.core.polytope.graph.waypoint_paths`, with :func:`hop_cost`). Consecutive hops in one
region merge, so the route is a sequence of regions and the waypoints where it changes
region.

The plan then assigns every interval to one region of the sequence: the switch samples
are placed in proportion to the route's length at its waypoints
(:func:`~spm_console.core.regions.route.spread`), and the QP (30) — each sample inside the
regions of its intervals — finds the optimal references for that assignment. For the
minimum-velocity-norm plan, the switch samples are then improved by a local search (each
moved while the cost falls). Angles in degrees.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.active_set import WorkingSet
from spm_console.core.planning.mvn import finish, run_qp, solved_qp
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.qp_build import Equalities, Pool
from spm_console.core.planning.result import PlanResult
from spm_console.core.planning.screening import QpOutcome
from spm_console.core.polytope.graph import waypoint_paths
from spm_console.core.polytope.region import Region
from spm_console.core.regions.route import RegionRoute, spread
from spm_console.errors import InfeasibleError, Issue, SolverError

F = NDArray[np.float64]

#: Weight of the Euclidean length beside the largest joint move in a hop's cost.
EUCLID_WEIGHT = 1e-3
#: Most QPs the switch-sample search may add to the first one.
MAX_SWITCH_QPS = 4
#: The first move of a switch sample in the search, samples.
FIRST_SWITCH_STEP = 3


@dataclass(frozen=True)
class RouteChoice:
    """A sequence of regions joining two configurations, with its waypoints."""

    regions: tuple[int, ...]
    """Indices of the regions, in order."""
    waypoints_deg: F
    """(len(regions) + 1, 3): start, the switch points, goal."""
    length_deg: float
    """Sum over the hops of their largest joint move, deg."""

    def fractions(self) -> list[float]:
        """Where each switch point lies along the route, as a fraction of its length."""
        hops = np.abs(np.diff(self.waypoints_deg, axis=0)).max(axis=1)
        total = float(hops.sum())
        if total <= 0:
            return [(i + 1) / len(self.regions) for i in range(len(self.regions) - 1)]
        return [float(x) for x in np.cumsum(hops)[:-1] / total]

    def route(self, all_regions: Sequence[Region], N: int,
              labels: Sequence[str] = ()) -> RegionRoute:
        """The :class:`RegionRoute` of this choice for a plan of N steps."""
        regs = tuple(all_regions[i] for i in self.regions)
        names = tuple(labels[i] for i in self.regions) if labels else ()
        return RegionRoute(regs, spread(self.fractions(), N) if len(regs) > 1 else (), names)


def hop_cost(p_deg: F, q_deg: F) -> F:
    """Cost of the straight hops between the points (m, 3) and (m, 3), deg: the largest
    joint move, a small Euclidean tie-break and 1e-9 (every hop costs something)."""
    d = np.asarray(p_deg, float) - np.asarray(q_deg, float)
    return np.asarray(np.abs(d).max(-1) + EUCLID_WEIGHT * np.linalg.norm(d, axis=-1) + 1e-9)


def find_route(regions: Sequence[Region], overlap_points_deg: F, start_deg: F,
               goal_deg: F) -> RouteChoice | None:
    """The shortest route (see module docstring) from start to goal through ``regions``
    whose overlaps are represented by ``overlap_points_deg`` (m, 3); None when no sequence
    of overlapping regions joins them (or an end lies in none of the regions)."""
    s = np.asarray(start_deg, float).reshape(3)
    g = np.asarray(goal_deg, float).reshape(3)
    pts = np.vstack([s[None], g[None], np.asarray(overlap_points_deg, float).reshape(-1, 3)])
    paths, member = waypoint_paths(regions, pts, hop_cost, 0)
    if not member[0].any() or not member[1].any():
        return None
    path = paths.path(0, 1)
    if path is None:
        return None
    # one region per stretch of hops: keep the current one while it holds the next hop,
    # else switch (at the hop's first waypoint) to the region holding the most hops ahead
    seq: list[int] = []
    switches: list[F] = []
    h = 0
    while h < len(path) - 1:
        cands = np.flatnonzero(member[path[h]] & member[path[h + 1]])
        reach = [_reach(member, path, h, int(c)) for c in cands]
        r = int(cands[int(np.argmax(reach))])
        if seq:
            switches.append(pts[path[h]])
        seq.append(r)
        h += max(reach)
    waypoints = np.vstack([s[None], *(w[None] for w in switches), g[None]])
    length = float(np.abs(np.diff(waypoints, axis=0)).max(axis=1).sum())
    return RouteChoice(tuple(seq), waypoints, length)


def _reach(member: NDArray[np.bool_], path: list[int], h: int, r: int) -> int:
    """How many consecutive hops from hop h region r holds."""
    n = 0
    while h + n < len(path) - 1 and member[path[h + n], r] and member[path[h + n + 1], r]:
        n += 1
    return n


@dataclass(frozen=True)
class RoutePlan:
    """An MVN plan across regions and how it was found."""

    result: PlanResult
    choice: RouteChoice
    qps: int
    """QPs solved (first assignment + switch search)."""
    first_cost: float
    """Cost with the switch samples first placed, (deg/s)²: ½zᵀPz of that QP's answer (the
    measure the switch search compares)."""
    seconds: float


def improve_switches(problem: PlanProblem, eq: Equalities, first: QpOutcome, t0: float,
                     max_qps: int = MAX_SWITCH_QPS, pool: Pool | None = None) -> tuple[PlanResult, int]:
    """Move each switch sample while the MVN cost falls, at most ``max_qps`` extra QPs, from
    ``first``, the solved QP of ``problem``'s own assignment; the best plan and the QPs spent.

    Each switch is moved by a line search along the samples (:func:`_line_search`): the cost
    of a route as a function of one switch sample is smooth and has one minimum in the cases
    measured (docs/decisions/solver-choice.md), often tens of samples away, so steps grow
    while the cost falls and shrink once it rises.

    Candidates are compared by the cost of their certified QP solution (½zᵀPz, exact to
    round-off); only the one kept is simulated and verified (:func:`finish`), and the
    first assignment's answer only when no candidate is kept or the kept one fails.
    ``pool``: ``problem``'s, when the caller has it."""
    assert problem.route is not None and first.z is not None
    warm = WorkingSet(first.active, first.side) if first.certified else None
    pool = Pool(problem) if pool is None else pool  # each candidate's: this one, other bounds
    if warm is not None and not _holds_region_rows(pool, warm):
        # the first optimum holds no region row: it is optimal for the problem without any
        # region row, which every switch assignment only restricts further — no candidate
        # can cost less
        return finish(problem, eq, first, t0), 0
    search = _SwitchSearch(problem, eq, pool, first.z, qp_cost(eq, first.z), warm, max_qps)
    for i in range(len(problem.regions.switch)):
        if not any(_line_search(search, i, sign, FIRST_SWITCH_STEP) for sign in (1, -1)):
            for sign in (1, -1):  # neither way by the first step: the samples beside it
                if _line_search(search, i, sign, 1):
                    break
    if search.kept is not None:
        try:
            return finish(*search.kept, t0), search.qps
        except SolverError:  # the kept switch does not verify: the first assignment decides
            pass
    return finish(problem, eq, first, t0), search.qps


@dataclass
class _SwitchSearch:
    """The state of a route's switch search: the best assignment so far and its answer."""

    problem: PlanProblem
    eq: Equalities
    """``problem``'s equalities: every candidate's (only the switch samples differ)."""
    pool: Pool
    guess: F
    cost: float
    warm: WorkingSet | None
    max_qps: int
    qps: int = 0
    kept: tuple[PlanProblem, Equalities, QpOutcome] | None = None
    tried: set[tuple[int, ...]] = field(default_factory=set)
    """The assignments solved (and the first one)."""

    def __post_init__(self) -> None:
        self.tried.add(tuple(int(x) for x in self.problem.regions.switch))

    @property
    def route(self) -> RegionRoute:
        """The best assignment so far."""
        return self.problem.regions if self.kept is None else self.kept[0].regions

    @property
    def spent(self) -> bool:
        """Whether the search has solved all the QPs it may."""
        return self.qps >= self.max_qps

    def at(self, i: int) -> int:
        """Switch ``i``'s sample in the best assignment."""
        return int(self.route.switch[i])

    def bounds(self, i: int) -> tuple[int, int]:
        """The samples switch ``i`` may take, the others where they are (each region keeps
        at least one interval)."""
        sw = self.route.switch
        return (sw[i - 1] + 1 if i else 1,
                sw[i + 1] - 1 if i + 1 < len(sw) else self.problem.N - 1)

    def better(self, i: int, sample: int) -> bool:
        """Solve with switch ``i`` at ``sample`` clipped to its range (one QP, none for an
        assignment tried before: it cost no less than a best that only falls since); True,
        and kept, when it costs less than the best."""
        lo, hi = self.bounds(i)
        switch = tuple(min(max(sample, lo), hi) if j == i else int(x)
                       for j, x in enumerate(self.route.switch))
        if switch in self.tried or self.spent:
            return False
        self.tried.add(switch)
        cand = self.problem.with_route(replace(self.route, switch=switch))
        pool = self.pool.switched(cand)
        if not self.frees_a_held_row(pool):
            return False  # it cannot cost less than the best: no QP
        self.qps += 1
        c_eq, out = run_qp(cand, self.guess, warm=self.warm, pool=pool, eq=self.eq)
        if out.status != "solved" or out.z is None or not out.certified:
            return False  # infeasible, or no certified answer
        c = qp_cost(c_eq, out.z)
        if c >= self.cost - 1e-9 * max(1.0, self.cost):
            return False  # only a certified optimum that costs less replaces the best
        self.cost, self.kept = c, (cand, c_eq, out)
        self.warm, self.guess = WorkingSet(out.active, out.side), out.z
        return True


    def frees_a_held_row(self, pool: Pool) -> bool:
        """Whether the assignment of ``pool`` frees a row the best optimum holds (its bound
        is +∞ there: the sample or interval left that row's region). When it frees none, the
        best optimum and its multipliers meet the KKT conditions of the assignment's problem
        less the rows it frees, and the assignment's problem only adds rows to that one: it
        cannot cost less than the best. True when the best's working set is not known."""
        if self.warm is None:
            return True
        held = self.warm.rows[self.warm.side > 0]
        return bool((~np.isfinite(pool.hi[held])).any())


def _line_search(search: _SwitchSearch, i: int, sign: int, step: int) -> bool:
    """Move switch ``i`` from the best assignment, while the budget lasts: first the way
    ``sign``, the step doubling while the cost falls; then, around the best sample, a step
    each way, halved whenever neither costs less, down to one sample. Whether the switch
    moved. A move past the switch's range goes halfway to its end instead (:func:`_toward`)."""
    moved = False
    while search.better(i, _toward(search, i, sign, step)):
        moved = True
        step *= 2
    if not moved:
        return False
    step //= 2
    while step >= 1 and not search.spent:
        if not any(search.better(i, _toward(search, i, way, step)) for way in (sign, -sign)):
            step //= 2
    return True


def _toward(search: _SwitchSearch, i: int, sign: int, step: int) -> int:
    """The sample ``step`` from switch ``i``'s best one the way ``sign``; past the end of its
    range, halfway from the best sample to that end. At the end a region keeps one interval:
    often infeasible (the goal's region must hold the last approach), and an infeasible QP
    costs about two feasible ones (its certificate), while the cost's minimum lies inside."""
    at = search.at(i)
    end = search.bounds(i)[1 if sign > 0 else 0]
    target = at + sign * step
    if (target - end) * sign <= 0:
        return target
    return at + sign * max(1, abs(end - at) // 2)


def qp_cost(eq: Equalities, z: F) -> float:
    """½zᵀPz, the MVN cost Σ θ̇ᵀθ̇ of a QP answer (P is 2 on every θ̇), (deg/s)²."""
    return float(z @ (eq.P @ z)) / 2.0


def _holds_region_rows(pool: Pool, working: WorkingSet) -> bool:
    """Whether the certified working set ``working`` of ``pool``'s problem holds a region row
    (at a sample or between samples: pool families 0 and 1)."""
    return bool(np.isin(pool.family[working.rows], (0, 1)).any())


def solve_route_mvn(problem: PlanProblem, regions: Sequence[Region], choice: RouteChoice,
                    labels: Sequence[str] = (), improve: bool = True) -> RoutePlan:
    """The MVN plan of ``problem`` (its region is ignored) along ``choice``."""
    t0 = time.perf_counter()
    if len(choice.regions) > problem.N:
        raise InfeasibleError(f"N = {problem.N} steps are too few for a route through "
                              f"{len(choice.regions)} regions; use more steps", Issue.TOO_FEW_STEPS)
    route = choice.route(regions, problem.N, labels)
    pb = problem.with_route(route)
    pool = Pool(pb)
    eq, first = solved_qp(pb, pool=pool)
    first_cost = qp_cost(eq, first.z) if first.z is not None else np.inf
    best, extra = (improve_switches(pb, eq, first, t0, pool=pool) if improve and route.count > 1
                   else (finish(pb, eq, first, t0), 0))
    seconds = time.perf_counter() - t0
    # the plan reports every QP its switch search solved, and their time, not the last one's
    best = replace(best, solve_seconds=seconds, qp_count=first.qp_count + extra)
    return RoutePlan(best, choice, 1 + extra, first_cost, seconds)
