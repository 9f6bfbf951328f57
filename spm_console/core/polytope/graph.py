"""The region graph: convex regions {θ : A θ ≤ b} (θ in degrees), the overlaps that join
them, which regions hold a point, and the one cheapest-path search over them.

A cover's regions (:class:`~spm_console.core.polytope.cover.RegionCover`), possibly with
regions grown around points no cover region holds
(:func:`~spm_console.core.regions.connect.connected_graph`), form a :class:`RegionGraph`: two
regions are joined when their intersection holds a ball (its centre: the switch point).
Both ways of moving across it search it with :func:`cheapest_paths`, each with its own edge
cost:

* a plan (:func:`~spm_console.core.planning.route_search.find_route`) searches its
  *waypoints* — start, goal and the switch points — two of them joined when one region holds
  both (:func:`waypoint_paths`), a hop costing the time a speed-bounded move needs;
* live following (:class:`~spm_console.motion.follow.regions.RegionHopper`) searches the
  regions themselves, joined by their overlaps (:meth:`RegionGraph.region_paths`), a hop
  costing a region change and the way between the regions' centres.

"Holds" is :data:`~spm_console.core.polytope.region.INSIDE_TOL_DEG` unless a caller names
another tolerance. Degrees at this interface.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region

F = NDArray[np.float64]
B = NDArray[np.bool_]
I64 = NDArray[np.int64]


def members(regions: Sequence[Region], points_deg: F, tol: float = INSIDE_TOL_DEG) -> B:
    """(n, k): whether each point (n, 3), deg, lies in each of the k regions."""
    pts = np.asarray(points_deg, float).reshape(-1, 3)
    out = np.zeros((len(pts), len(regions)), bool)
    for j, r in enumerate(regions):
        out[:, j] = r.contains(pts, tol=tol)
    return out


def containing(regions: Sequence[Region], theta_deg: F, tol: float = INSIDE_TOL_DEG) -> list[int]:
    """Indices of the regions holding θ (deg, one point), ascending."""
    t = np.asarray(theta_deg, float).reshape(3)
    return [i for i, r in enumerate(regions) if bool(r.contains(t, tol=tol))]


@dataclass(frozen=True)
class Paths:
    """Cheapest paths from some source nodes of a graph to all of its nodes."""

    sources: tuple[int, ...]
    dist: F
    """(len(sources), n) cost of the cheapest path (inf: none)."""
    pred: I64
    """(len(sources), n) node before each node on that path (negative: none)."""

    def _row(self, source: int) -> int:
        return self.sources.index(source)

    def cost(self, source: int, target: int) -> float:
        return float(self.dist[self._row(source), target])

    def path(self, source: int, target: int) -> list[int] | None:
        """Nodes from ``source`` to ``target`` along the cheapest path; None when none."""
        row = self._row(source)
        if not np.isfinite(self.dist[row, target]):
            return None
        out = [target]
        while out[-1] != source:
            out.append(int(self.pred[row, out[-1]]))
        out.reverse()
        return out


def cheapest_paths(n: int, pairs: I64, cost: F, sources: Sequence[int] | None = None) -> Paths:
    """The cheapest paths (Dijkstra) from ``sources`` (default: every node) over the
    undirected graph of ``n`` nodes whose edges are ``pairs`` (m, 2), each edge once, costing
    ``cost`` (m,), positive: the one search over a region graph."""
    from scipy.sparse import csr_matrix  # here: ~0.3 s to import, not before the console's first screen
    from scipy.sparse.csgraph import dijkstra

    p = np.asarray(pairs, np.int64).reshape(-1, 2)
    w = np.asarray(cost, float).reshape(len(p))
    if not bool((w > 0).all()):
        raise ValueError("edge costs must be positive")
    g = csr_matrix((np.r_[w, w], (np.r_[p[:, 0], p[:, 1]], np.r_[p[:, 1], p[:, 0]])),
                   shape=(n, n))
    src = tuple(range(n)) if sources is None else tuple(int(s) for s in sources)
    dist, pred = dijkstra(g, directed=False, indices=list(src), return_predecessors=True)
    return Paths(src, np.asarray(dist, float).reshape(len(src), n),
                 np.asarray(pred, np.int64).reshape(len(src), n))


def waypoint_paths(regions: Sequence[Region], waypoints_deg: F, cost: Callable[[F, F], F],
                   source: int) -> tuple[Paths, B]:
    """Cheapest paths from waypoint ``source`` over the waypoints (n, 3), deg, two joined when
    one region holds both, a hop between points p and q (rows of (m, 3)) costing
    ``cost(p, q)`` (m,); and which regions hold each waypoint, (n, k)."""
    pts = np.asarray(waypoints_deg, float).reshape(-1, 3)
    member = members(regions, pts)
    share = (member.astype(np.int32) @ member.T.astype(np.int32)) > 0
    pairs = np.argwhere(np.triu(share, 1)).astype(np.int64)
    return cheapest_paths(len(pts), pairs, cost(pts[pairs[:, 0]], pts[pairs[:, 1]]),
                          [source]), member


@dataclass(frozen=True)
class RegionGraph:
    """Convex regions and the overlaps that join them."""

    regions: tuple[Region, ...]
    """The regions, θ in degrees, unit-norm rows."""
    edges: I64
    """(m, 2) pairs (i, j), i < j, of regions whose overlap holds a switch point."""
    points_deg: F
    """(m, 3) the switch point of each pair (its overlap's Chebyshev centre), deg."""
    grown: int = 0
    """Regions grown around given points (the last ones of ``regions``)."""

    def containing(self, theta_deg: F, tol: float = INSIDE_TOL_DEG) -> list[int]:
        """Indices of the regions holding θ (deg, one point), ascending."""
        return containing(self.regions, theta_deg, tol)

    def region_paths(self, cost: F) -> Paths:
        """Cheapest paths between every two regions through their overlaps, the overlap of
        each row of ``edges`` costing the entry of ``cost`` (m,), positive."""
        return cheapest_paths(len(self.regions), self.edges, cost)
