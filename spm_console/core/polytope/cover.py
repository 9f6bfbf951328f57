"""The region cover's data: convex regions {θ : A θ ≤ b} (θ in degrees) covering the
feasible set, and their overlap graph. Built by :mod:`spm_console.core.regions.cover`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.graph import RegionGraph, containing
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region

F = NDArray[np.float64]
B = NDArray[np.bool_]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class RegionCover:
    """Convex regions {θ : A θ ≤ b} (θ in degrees) covering the feasible set, and the
    graph of their overlaps. ``regions[0]`` is the workspace's P."""

    regions: tuple[Region, ...]
    """The regions, θ in degrees, unit-norm rows; ``regions[0]`` is P."""
    seeds_deg: F
    """(k, 3) a feasible grid node inside each region (P: the home node), deg."""
    edges: I64
    """(m, 2) pairs (i, j), i < j, whose intersection holds a ball of radius
    ≥ ``min_overlap_deg``; sorted lexicographically."""
    edge_points_deg: F
    """(m, 3) Chebyshev centre of each intersection, deg."""
    edge_radius_deg: F
    """(m,) inscribed-ball radius of each intersection, deg."""
    min_overlap_deg: float
    """Radius threshold of an edge, deg."""
    covered: float
    """Fraction of the workspace's feasible nodes inside at least one region."""
    seconds: float = 0.0
    """Wall time of the build (refinement + regions + graph), s."""
    resolution_deg: float | None = None
    """Fine resolution h of the refined obstacles the regions avoid (None: the grid's)."""
    refined_cells: int = 0
    """Grid cells refined for the build."""
    fine_nodes: int = 0
    """Fine nodes of those cells (checked exactly, memoized)."""
    refine_seconds: float = 0.0
    """Wall time of the refinement alone, s."""

    @property
    def size(self) -> int:
        return len(self.regions)

    def containing(self, theta_deg: F, tol: float = INSIDE_TOL_DEG) -> list[int]:
        """Indices of the regions holding θ (deg, one point), ascending."""
        return containing(self.regions, theta_deg, tol)

    def graph(self) -> RegionGraph:
        """The regions and their overlaps as a :class:`RegionGraph`."""
        return RegionGraph(self.regions, self.edges, self.edge_points_deg)

    def neighbours(self, i: int) -> list[int]:
        """Regions sharing an edge with region ``i``, ascending."""
        e = self.edges
        out = np.r_[e[e[:, 0] == i, 1], e[e[:, 1] == i, 0]]
        return sorted(int(j) for j in out)

    def overlap(self, i: int, j: int) -> tuple[F, float] | None:
        """(Chebyshev centre deg, radius deg) of the edge between ``i`` and ``j``, or None."""
        a, b = min(i, j), max(i, j)
        hit = np.flatnonzero((self.edges[:, 0] == a) & (self.edges[:, 1] == b))
        if len(hit) == 0:
            return None
        k = int(hit[0])
        return self.edge_points_deg[k].copy(), float(self.edge_radius_deg[k])

    def member(self, points_deg: F, tol: float = INSIDE_TOL_DEG) -> B:
        """(n,) True where a point (n, 3), deg, lies in at least one region."""
        p = np.asarray(points_deg, float).reshape(-1, 3)
        inside = np.zeros(len(p), bool)
        for r in self.regions:
            rest = ~inside
            if not rest.any():
                break
            inside[rest] = r.contains(p[rest], tol=tol)
        return inside

    def coverage(self, points_deg: F, tol: float = INSIDE_TOL_DEG) -> float:
        """Fraction of the points (n, 3), deg, inside at least one region (0 if none)."""
        inside = self.member(points_deg, tol)
        return float(inside.mean()) if len(inside) else 0.0

    def components(self) -> I64:
        """Connected component label per region; label 0 is P's component."""
        from scipy.sparse import coo_matrix  # here: scipy.sparse.csgraph costs ~0.15 s to import
        from scipy.sparse.csgraph import connected_components

        k = self.size
        e = self.edges
        g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(k, k)) if len(e) else \
            coo_matrix((k, k))
        _, lab = connected_components(g, directed=False)
        lab = np.asarray(lab, np.int64)
        # renumber so that P's component is 0
        p = lab[0]
        return np.where(lab == p, 0, np.where(lab == 0, p, lab))

    @property
    def connected(self) -> bool:
        """True when every region is joined to P through the graph."""
        return bool((self.components() == 0).all())

    def describe(self) -> str:
        """One line: regions, coverage, edges, connectivity."""
        comps = len(np.unique(self.components()))
        conn = "connected" if comps == 1 else f"{comps} components"
        regions = "P alone" if self.size == 1 else f"{self.size} regions"
        m = len(self.edges)
        overlaps = f"{m} overlap{'' if m == 1 else 's'}"
        return (f"cover: {regions}, {100 * self.covered:.1f} % of feasible nodes, "
                f"{overlaps} ≥ {self.min_overlap_deg:g}° ({conn})")
