"""Live following across the workspace's region cover: which region the follower plans in
now, and where it heads inside it.

Every re-plan lies in one convex region (certified like P). When the target lies in another
region of the cover, the follower heads for the overlap with the next region on the shortest
path of the overlap graph (fewest regions, then the shortest way between overlap centres),
and plans in that next region once the wrist's predicted state is inside it — so the switch
happens inside the overlap, where both regions hold it, exactly as a plan across regions
switches at a sample inside two regions. A target in no region of the cover is projected
into the current region (the solver reports it as clamped).

A wrist that stands where no cover region reaches — a plan through a region grown around its
end left it on the boundary of the certified set — starts in a region grown around its own
position, as the planner grows one around a plan's end (:func:`~spm_console.core.regions.cover.
connected_graph`: the cover's obstacles, so certified alike), computed by the runtime from
its own workspace and joined to the cover through its overlaps. The path is the region graph's
search (:meth:`~spm_console.core.polytope.graph.RegionGraph.region_paths`) with :func:`hop_costs`.
Degrees.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.follow.tolerance import FOLLOW_TOL_DEG
from spm_console.core.polytope.graph import RegionGraph
from spm_console.core.regions.connect import connected_graph
from spm_console.errors import BadInputError, InfeasibleError
from spm_console.formatting import fmt_deg

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]

#: Weight of one region change against the way between overlap centres (deg) in the path.
HOP_COST_DEG = 1000.0


def _where(theta_deg: F) -> str:
    return f"θ = {fmt_deg(np.asarray(theta_deg, float))}"


#: What to do about a start no certified region holds (the console's and the CLI's advice).
MOVE_IN = "move the wrist inside the workspace first (plan a motion there, or home it)"


def _beyond_grid(ws: Workspace, th: F) -> str:
    """Where ``th`` leaves the workspace's grid, as a clause ('' when inside it): a plan that
    ended on the grid's edge can settle a servo tick beyond it."""
    out = []
    for j, (axis, x) in enumerate(zip(ws.axes_deg, th, strict=True)):
        lo, hi = float(axis[0]), float(axis[-1])
        if not lo <= x <= hi:
            out.append(f"θ{j + 1} is {min(abs(x - lo), abs(x - hi)):.2f}° beyond the grid's "
                       f"{lo:g}…{hi:g}°")
    return f" ({'; '.join(out)})" if out else ""


def follow_start(ws: Workspace, theta0_deg: F, tolerance_deg: float, inset_deg: float) -> F:
    """Where following plans from, deg: ``theta0_deg`` itself, or — when it lies beyond the
    workspace grid's box by at most ``tolerance_deg`` on every axis (a plan that ended on the
    grid's edge settles a servo tick beyond it, where no region reaches) — the point
    ``inset_deg`` inside the faces it crossed (the other axes unchanged), which the follower
    first moves to. ``inset_deg``: one servo tick, so that the servo's nearest tick lies in
    the box."""
    th = np.asarray(theta0_deg, float).reshape(3)
    lo = np.array([float(a[0]) for a in ws.axes_deg])
    hi = np.array([float(a[-1]) for a in ws.axes_deg])
    beyond = (th < lo) | (th > hi)
    if not beyond.any():
        return th
    inner = np.where(beyond, np.clip(th, lo + inset_deg, hi - inset_deg), th)
    return inner if float(np.abs(inner - th).max()) <= tolerance_deg else th


def follow_regions(ws: Workspace, theta0_deg: F) -> RegionGraph:
    """The workspace's cover (P alone without one) and, when none of its regions holds
    ``theta0_deg``, a region grown around it and joined to the cover (``grown``: 0 or 1).
    BadInputError, with the reason, when the start cannot be held by a certified region."""
    th = np.asarray(theta0_deg, float).reshape(3)
    cover = ws.cover
    if cover is None:
        if not bool(ws.region.contains(th, tol=FOLLOW_TOL_DEG)):
            raise BadInputError(f"the wrist is at {_where(th)}{_beyond_grid(ws, th)}, outside the "
                                f"workspace's region P (this workspace has no region cover): "
                                f"{MOVE_IN}")
        return RegionGraph((ws.region,), np.zeros((0, 2), np.int64), np.zeros((0, 3)))
    if cover.containing(th, tol=FOLLOW_TOL_DEG):
        return cover.graph()
    try:
        graph = connected_graph(ws, cover, th[None])
    except InfeasibleError as exc:
        raise BadInputError(f"the wrist is at {_where(th)}{_beyond_grid(ws, th)}, outside the "
                            f"workspace's certified set ({exc.message}): no region to follow "
                            f"in; {MOVE_IN}") from None
    if not graph.grown or not bool(graph.regions[-1].contains(th, tol=FOLLOW_TOL_DEG)):
        raise BadInputError(f"the wrist is at {_where(th)}{_beyond_grid(ws, th)}: no certified "
                            f"region grown around it holds it; {MOVE_IN}")
    if len(graph.edges) == len(cover.edges):
        raise BadInputError(f"the wrist is at {_where(th)}: the region grown around it overlaps "
                            f"no region of the cover, so following could not leave it; {MOVE_IN}")
    return graph


def hop_costs(graph: RegionGraph) -> F:
    """The follower's cost (m,) of the overlaps (rows of ``graph.edges``): :data:`HOP_COST_DEG`
    per region change plus the largest joint move from each of the two regions' Chebyshev
    centres to the overlap's switch point, deg (fewest regions, then the shortest way between
    centres)."""
    if not len(graph.edges):
        return np.zeros(0)
    centres = np.array([np.asarray(r.chebyshev()[0], float) for r in graph.regions])
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    p = np.asarray(graph.points_deg, float)
    return np.asarray(HOP_COST_DEG + (np.abs(centres[i] - p).max(1) + np.abs(centres[j] - p).max(1)))


class RegionHopper:
    """The follower's current region in ``graph.regions`` (see :func:`follow_regions`)."""

    def __init__(self, graph: RegionGraph, theta0_deg: F) -> None:
        self.graph = graph
        self.regions = graph.regions
        self.points: dict[tuple[int, int], F] = {}
        for (i, j), p in zip(graph.edges, graph.points_deg, strict=True):
            self.points[(int(i), int(j))] = self.points[(int(j), int(i))] = np.asarray(p)
        self.paths = graph.region_paths(hop_costs(graph))
        inside = self.containing(theta0_deg)
        if not inside:
            raise ValueError("the start lies in no region")
        self.current = inside[0]
        """Index of the region the follower plans in."""
        self.switches = 0

    def containing(self, theta_deg: F) -> list[int]:
        return self.graph.containing(theta_deg, tol=FOLLOW_TOL_DEG)

    def _next_hop(self, goal: int) -> int:
        """The region after the current one on the shortest path to ``goal``."""
        path = self.paths.path(self.current, goal)
        assert path is not None and len(path) > 1
        return path[1]

    def aim(self, state_deg: F, target_deg: F) -> tuple[int, F | None]:
        """(region to plan in, intermediate target — None: head for the target itself),
        switching to the next region first when the state is already inside it."""
        goals = self.containing(target_deg)
        for _ in range(len(self.regions)):
            if not goals or self.current in goals:
                return self.current, None
            reachable = [g for g in goals if np.isfinite(self.paths.cost(self.current, g))]
            if not reachable:
                return self.current, None  # no way there through the cover: projected here
            goal = min(reachable, key=lambda g: self.paths.cost(self.current, g))
            nxt = self._next_hop(goal)
            # inside the next region by the solver's tolerance (not on it): the next region's
            # solver accepts the state for sure
            if bool(self.regions[nxt].contains(np.asarray(state_deg, float), tol=-FOLLOW_TOL_DEG)):
                self.current = nxt  # inside the overlap: plan in the next region from now on
                self.switches += 1
                continue
            return self.current, self.points[(self.current, nxt)]
        return self.current, None
