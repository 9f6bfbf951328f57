"""Joining a point the cover does not hold to the cover's region graph (core/regions/connect).

Independent references: every overlap between the grown region and each cover region is
tested again by the Chebyshev LP (the graph's edges are exactly those with room for the
cover's overlap ball), and the grown region avoids the grid's obstacles like the cover's
regions (it lies in the certified set: checked on its vertices against the cubes)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from spm_console.core.polytope.region import Region
from spm_console.core.regions import connect as cn
from spm_console.core.regions.p_build import obstacle_nodes
from spm_console.core.workspace.data import Workspace
from tests.support.ws_helpers import agile_workspace


@pytest.fixture(scope="module")
def ws() -> Workspace:
    return agile_workspace()


def _uncovered_boundary_node(ws: Workspace) -> np.ndarray:
    """A feasible node next to an infeasible one that no cover region holds."""
    assert ws.cover is not None
    feas = ws.feasible
    edge = feas & ndimage.binary_dilation(~feas, np.ones((3, 3, 3), bool))
    for th in ws.theta_deg()[edge]:
        if not ws.cover.containing(th):
            return np.asarray(th, float)
    raise AssertionError("every boundary node is covered")


def test_a_point_outside_the_cover_gets_a_region_joined_by_every_overlap(ws: Workspace) -> None:
    cover = ws.cover
    assert cover is not None
    p = _uncovered_boundary_node(ws)
    g = cn.connected_graph(ws, cover, p[None])
    n = len(cover.regions)
    assert g.grown == 1 and len(g.regions) == n + 1
    grown = g.regions[-1]
    assert grown.contains(p[None], tol=1e-7).all()
    new = [tuple(e) for e in g.edges[len(cover.edges):].tolist()]
    expect = []
    for i, other in enumerate(cover.regions):
        _, rad = Region(np.vstack([grown.A, other.A]), np.r_[grown.b, other.b]).chebyshev()
        if rad >= cover.min_overlap_deg:
            expect.append((i, n))
    assert new == expect and expect
    for (i, j), c in zip(g.edges[len(cover.edges):], g.points_deg[len(cover.edges):], strict=True):
        assert g.regions[i].contains(c[None], tol=1e-7).all()
        assert g.regions[j].contains(c[None], tol=1e-7).all()
    # no obstacle cube's centre inside the grown region (it avoids the cubes)
    obst = obstacle_nodes(ws.feasible, ws.theta_deg())
    assert not grown.contains(obst, tol=0.0).any()


def test_a_covered_point_adds_nothing_and_the_aid_is_kept_per_workspace(ws: Workspace) -> None:
    cover = ws.cover
    assert cover is not None
    inside = cover.regions[0].chebyshev()[0]
    g = cn.connected_graph(ws, cover, inside[None])
    assert g.grown == 0 and len(g.regions) == len(cover.regions)
    assert (g.edges == cover.edges).all()
    first = cn._aid(ws, cover, 2)
    assert cn._aid(ws, cover, 2) is first  # kept for the same workspace and cover
