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
connector_regions`: the cover's obstacles, so certified alike), computed by the runtime from
its own workspace and joined to the cover through its overlaps. Degrees.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.region import Region
from spm_console.core.regions.cover import connector_overlaps, connector_regions
from spm_console.errors import BadInputError, InfeasibleError
from spm_console.formatting import fmt_deg

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]
I64 = NDArray[np.int64]

#: A point lies in a region when it violates no half-space by more than this, deg.
INSIDE_TOL_DEG = 1e-6
#: Weight of one region change against the way between overlap centres (deg) in the path.
HOP_COST_DEG = 1000.0


@dataclass(frozen=True)
class FollowRegions:
    """The regions live following plans in and the graph of their overlaps."""

    regions: tuple[Region, ...]
    edges: I64
    """(m, 2) pairs of regions whose overlap holds a switch point."""
    points_deg: F
    """(m, 3) the switch point of each pair (its overlap's Chebyshev centre), deg."""
    grown: int = 0
    """Regions grown around the start (the last ones of ``regions``): 0 or 1."""


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


def follow_regions(ws: Workspace, theta0_deg: F) -> FollowRegions:
    """The workspace's cover (P alone without one) and, when none of its regions holds
    ``theta0_deg``, a region grown around it and joined to the cover. BadInputError, with the
    reason, when the start cannot be held by a certified region."""
    th = np.asarray(theta0_deg, float).reshape(3)
    cover = ws.cover
    if cover is None:
        if not bool(ws.region.contains(th, tol=INSIDE_TOL_DEG)):
            raise BadInputError(f"the wrist is at {_where(th)}{_beyond_grid(ws, th)}, outside the "
                                f"workspace's region P (this workspace has no region cover): "
                                f"{MOVE_IN}")
        return FollowRegions((ws.region,), np.zeros((0, 2), np.int64), np.zeros((0, 3)))
    if any(r.contains(th, tol=INSIDE_TOL_DEG) for r in cover.regions):
        return FollowRegions(cover.regions, cover.edges, cover.edge_points_deg)
    try:
        grown, _ = connector_regions(ws, cover, th[None])
    except InfeasibleError as exc:
        raise BadInputError(f"the wrist is at {_where(th)}{_beyond_grid(ws, th)}, outside the "
                            f"workspace's certified set ({exc.message}): no region to follow "
                            f"in; {MOVE_IN}") from None
    if not grown or not bool(grown[0].contains(th, tol=INSIDE_TOL_DEG)):
        raise BadInputError(f"the wrist is at {_where(th)}{_beyond_grid(ws, th)}: no certified "
                            f"region grown around it holds it; {MOVE_IN}")
    pairs, pts = connector_overlaps(cover, grown)
    if not len(pairs):
        raise BadInputError(f"the wrist is at {_where(th)}: the region grown around it overlaps "
                            f"no region of the cover, so following could not leave it; {MOVE_IN}")
    return FollowRegions((*cover.regions, *grown), np.vstack([cover.edges, pairs]),
                         np.vstack([cover.edge_points_deg, pts]), grown=len(grown))


class RegionHopper:
    """The follower's current region in ``graph.regions`` (see :func:`follow_regions`)."""

    def __init__(self, graph: FollowRegions, theta0_deg: F) -> None:
        self.regions = regions = graph.regions
        n = len(regions)
        self.points: dict[tuple[int, int], F] = {}
        rows: list[int] = []
        cols: list[int] = []
        w: list[float] = []
        if len(graph.edges):
            centres = np.array([self._centre(i) for i in range(n)])
            for (i, j), p in zip(graph.edges, graph.points_deg, strict=True):
                self.points[(int(i), int(j))] = self.points[(int(j), int(i))] = np.asarray(p)
                rows.append(int(i))
                cols.append(int(j))
                w.append(HOP_COST_DEG + float(np.abs(centres[i] - p).max() + np.abs(centres[j] - p).max()))
        from scipy.sparse import csr_matrix  # here: ~0.3 s to import, not before the first screen
        from scipy.sparse.csgraph import shortest_path

        graph = csr_matrix((w, (rows, cols)), shape=(n, n))
        self.dist, self.pred = shortest_path(graph, directed=False, return_predecessors=True)
        inside = self.containing(theta0_deg)
        if not inside:
            raise ValueError("the start lies in no region")
        self.current = inside[0]
        """Index of the region the follower plans in."""
        self.switches = 0

    def _centre(self, i: int) -> F:
        c, _ = self.regions[i].chebyshev()
        return np.asarray(c, float)

    def containing(self, theta_deg: F) -> list[int]:
        t = np.asarray(theta_deg, float).reshape(3)
        return [i for i, r in enumerate(self.regions) if bool(r.contains(t, tol=INSIDE_TOL_DEG))]

    def _next_hop(self, goal: int) -> int:
        """The region after the current one on the shortest path to ``goal``."""
        k = goal
        while int(self.pred[self.current, k]) != self.current:
            k = int(self.pred[self.current, k])
        return k

    def aim(self, state_deg: F, target_deg: F) -> tuple[int, F | None]:
        """(region to plan in, intermediate target — None: head for the target itself),
        switching to the next region first when the state is already inside it."""
        goals = self.containing(target_deg)
        for _ in range(len(self.regions)):
            if not goals or self.current in goals:
                return self.current, None
            reachable = [g for g in goals if np.isfinite(self.dist[self.current, g])]
            if not reachable:
                return self.current, None  # no way there through the cover: projected here
            goal = min(reachable, key=lambda g: self.dist[self.current, g])
            nxt = self._next_hop(goal)
            if bool(self.regions[nxt].contains(np.asarray(state_deg, float), tol=-INSIDE_TOL_DEG)):
                self.current = nxt  # inside the overlap: plan in the next region from now on
                self.switches += 1
                continue
            return self.current, self.points[(self.current, nxt)]
        return self.current, None
