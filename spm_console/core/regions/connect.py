"""The cover's region graph joined to configurations the cover does not hold.

A plan's end or a follower's start on the boundary of the certified set may lie in no cover
region: :func:`connected_graph` grows a small region around it (like cover regions, against
the same obstacles, so certified alike) and joins it to the others by its overlaps.

What does not depend on the point is computed once per workspace and cover and kept
(:class:`_CoverAid`): the grid's obstacles and feasible nodes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.cover import RegionCover
from spm_console.core.polytope.graph import RegionGraph, containing
from spm_console.core.polytope.iris import Frame
from spm_console.core.polytope.region import Region
from spm_console.core.regions import p_build as rb
from spm_console.core.regions.cover import COVER_HALFSPACES, COVER_ITERS
from spm_console.core.regions.cover_grow import Grower

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Half-width, in grid steps, of the neighbourhood whose feasible nodes a connector
#: region (grown around a plan's end outside the cover) tries to hold.
CONNECTOR_REACH_STEPS = 8


@dataclass(frozen=True)
class _CoverAid:
    """What :func:`connected_graph` needs of one workspace and cover, whatever the points."""

    ws: Workspace
    cover: RegionCover
    grower: Grower
    feasible_deg: F

    @classmethod
    def of(cls, ws: Workspace, cover: RegionCover, iters: int) -> _CoverAid:
        lo, hi = ws.range_deg()
        frame = Frame(np.full(3, 0.5 * (lo + hi)), 0.5 * (hi - lo))
        theta = ws.theta_deg()
        grower = Grower(frame, frame.to_x(rb.obstacle_nodes(ws.feasible, theta)),
                        ws.step_deg / frame.s, COVER_HALFSPACES, iters, ws.step_deg)
        return cls(ws, cover, grower, theta[ws.feasible])


_AIDS: list[_CoverAid] = []
#: Workspaces and covers whose aid is kept (the console's and a sweep's few).
_AID_CACHE = 4


def _aid(ws: Workspace, cover: RegionCover, iters: int) -> _CoverAid:
    for a in _AIDS:
        if a.ws is ws and a.cover is cover and a.grower.iters == iters:
            return a
    a = _CoverAid.of(ws, cover, iters)
    _AIDS.insert(0, a)
    del _AIDS[_AID_CACHE:]
    return a


def connected_graph(ws: Workspace, cover: RegionCover, points_deg: F,
                    iters: int = COVER_ITERS) -> RegionGraph:
    """The cover's region graph with a region grown (like cover regions, same obstacles, so
    certified alike) around each of ``points_deg`` (k, 3) that no cover region (nor one grown
    before it) holds — a configuration on the boundary of the certified set — joined to the
    others by its overlaps (radius ≥ the cover's ``min_overlap_deg``). The grown regions
    (``grown`` of them) come after the cover's. Grown on demand for a plan's ends or a
    follower's start; never stored. InfeasibleError when a point sits inside an obstacle cube
    (it is not certified)."""
    aid = _aid(ws, cover, iters)
    new: list[Region] = []
    for p in np.asarray(points_deg, float).reshape(-1, 3):
        if cover.containing(p) or containing(new, p):
            continue
        # the heuristics' objective: the feasible nodes around the point (a connector only
        # has to reach into the cover, and the whole grid makes each step 10× slower)
        feas = aid.feasible_deg
        near = feas[np.abs(feas - p).max(axis=1) <= CONNECTOR_REACH_STEPS * ws.step_deg]
        new.append(aid.grower.grow(p, near))
    pairs, pts = _connector_overlaps(aid, new)
    return RegionGraph((*cover.regions, *new), np.vstack([cover.edges, pairs]),
                       np.vstack([cover.edge_points_deg, pts]), grown=len(new))


def _connector_overlaps(aid: _CoverAid, new: list[Region]) -> tuple[I64, F]:
    """The overlaps (inscribed radius ≥ the cover's ``min_overlap_deg``) of each region of
    ``new`` with the cover's regions and the regions of ``new`` before it: (m, 2) pairs
    (i, j), i < j, indexing ``(*cover.regions, *new)``, and their Chebyshev centres (m, 3)."""
    cover = aid.cover
    pairs: list[tuple[int, int]] = []
    pts: list[F] = []
    n = len(cover.regions)
    for k, r in enumerate(new):
        for i, other in enumerate((*cover.regions, *new[:k])):
            both = Region(np.vstack([r.A, other.A]), np.r_[r.b, other.b])
            c, rad = both.chebyshev()
            if rad >= cover.min_overlap_deg:
                pairs.append((i, n + k))
                pts.append(c)
    return np.asarray(pairs, np.int64).reshape(-1, 2), np.asarray(pts, float).reshape(-1, 3)
