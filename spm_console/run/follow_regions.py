"""Live following across the workspace's region cover: which region the follower plans in
now, and where it heads inside it.

Every re-plan lies in one convex region (certified like P). When the target lies in another
region of the cover, the follower heads for the overlap with the next region on the shortest
path of the overlap graph (fewest regions, then the shortest way between overlap centres),
and plans in that next region once the wrist's predicted state is inside it — so the switch
happens inside the overlap, where both regions hold it, exactly as a plan across regions
switches at a sample inside two regions. A target in no region of the cover is projected
into the current region (the solver reports it as clamped). Degrees.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from spm_console.core.cover import RegionCover
from spm_console.core.region import Region

F = NDArray[np.float64]

#: A point lies in a region when it violates no half-space by more than this, deg.
INSIDE_TOL_DEG = 1e-6
#: Weight of one region change against the way between overlap centres (deg) in the path.
HOP_COST_DEG = 1000.0


class RegionHopper:
    """The follower's current region in ``regions`` (the cover's, or P alone)."""

    def __init__(self, regions: tuple[Region, ...], cover: RegionCover | None, theta0_deg: F) -> None:
        self.regions = regions
        self.cover = cover
        n = len(regions)
        self.points: dict[tuple[int, int], F] = {}
        rows: list[int] = []
        cols: list[int] = []
        w: list[float] = []
        if cover is not None:
            centres = np.array([self._centre(i) for i in range(n)])
            for (i, j), p in zip(cover.edges, cover.edge_points_deg, strict=True):
                self.points[(int(i), int(j))] = self.points[(int(j), int(i))] = np.asarray(p)
                rows.append(int(i))
                cols.append(int(j))
                w.append(HOP_COST_DEG + float(np.abs(centres[i] - p).max() + np.abs(centres[j] - p).max()))
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
