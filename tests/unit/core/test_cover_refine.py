"""The cover's refined regions: terrace nodes at several levels, certification checked by
dense samples near the boundary against the runtime's certified set and the exact point
checks, the obstacle test, and a plan through a terrace-node region that the runtime accepts."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.polytope.cover import RegionCover
from spm_console.core.polytope.region import Region
from spm_console.core.regions.cover_refine import bad_cells, refine_cells, region_clear
from spm_console.core.workspace.check import check_points
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.refine import FineGrid, RefinedCertifiedSet
from spm_console.services.plan_request import PlanRequest, plan_motion
from tests.support.ws_helpers import agile_profile, agile_workspace_refined, coarse_workspace


@pytest.fixture(scope="module")
def ws() -> Workspace:
    return agile_workspace_refined()


@pytest.fixture(scope="module")
def cover(ws: Workspace) -> RegionCover:
    assert ws.cover is not None
    return ws.cover


def terrace_nodes(ws: Workspace, axis: int, sign: int) -> np.ndarray:
    """Feasible nodes whose face neighbour in direction sign·e_axis is infeasible: (n, 3) index."""
    f = ws.feasible
    nb = np.ones_like(f)  # beyond the box counts as feasible (not a terrace)
    src = [slice(None)] * 3
    dst = [slice(None)] * 3
    if sign > 0:
        src[axis], dst[axis] = slice(1, None), slice(None, -1)
    else:
        src[axis], dst[axis] = slice(None, -1), slice(1, None)
    nb[tuple(dst)] = f[tuple(src)]
    return np.argwhere(f & ~nb)


def boundary_samples(ws: Workspace, cover: RegionCover, n_draw: int, seed: int) -> np.ndarray:
    """Uniform points in random bad grid cells (a corner infeasible) that lie in a cover region
    other than P: the part of the regions only the fine criterion can certify."""
    bad, _ = bad_cells(ws.feasible)
    cells = np.argwhere(bad)
    rng = np.random.default_rng(seed)
    org = np.array([a[0] for a in ws.axes_deg])
    pts = org + (cells[rng.integers(len(cells), size=n_draw)] + rng.random((n_draw, 3))) * ws.step_deg
    inside = np.zeros(n_draw, bool)
    for r in cover.regions[1:]:
        inside |= r.contains(pts, tol=0.0)
    return pts[inside]


def test_regions_hold_terrace_nodes_of_several_levels(ws: Workspace, cover: RegionCover) -> None:
    """On the grid's cubes a region holds terrace nodes of one level per direction only (the
    node lies on a face of its neighbour's cube); refined obstacles lift that."""
    theta = ws.theta_deg()
    best = 0
    for axis in range(3):
        for sign in (1, -1):
            t = terrace_nodes(ws, axis, sign)
            pts = theta[tuple(t.T)]
            for r in cover.regions[1:]:
                levels = np.unique(np.round(pts[r.contains(pts, tol=1e-7), axis], 6))
                best = max(best, len(levels))
    assert best >= 3


def test_boundary_samples_are_certified_and_feasible(ws: Workspace, cover: RegionCover) -> None:
    pts = boundary_samples(ws, cover, 200_000, seed=3)
    assert len(pts) > 5000
    # the runtime's certified set, with its own fresh fine verdicts
    assert RefinedCertifiedSet.of(ws).contains(pts).all()
    # and the exact checks of the samples themselves (FK, ζ, links)
    model, links = ws.exact_models()
    pc = check_points(ws, model, links, pts)
    ok = pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm) & pc.start_feasible
    assert ok.all(), pts[~ok][:3]


def test_region_clear_rejects_a_region_meeting_an_obstacle() -> None:
    ws5 = coarse_workspace()
    obs = refine_cells(ws5, FineGrid(ws5))
    assert obs.refined_cells > 0 and len(obs.centres_deg) > 0
    assert region_clear(ws5.region, obs)
    # a small box around a frontier obstacle's centre meets it
    c = obs.centres_deg[np.argmin(obs.half_deg)]
    box = Region(np.vstack([np.eye(3), -np.eye(3)]), np.r_[c + 0.1, 0.1 - c])
    assert not region_clear(box, obs)


def _terrace_start(ws: Workspace, cover: RegionCover) -> np.ndarray:
    """The terrace node nearest home (L∞) that P does not hold and a cover region does."""
    theta = ws.theta_deg()
    t = np.vstack([terrace_nodes(ws, a, s) for a in range(3) for s in (1, -1)])
    pts = theta[tuple(t.T)]
    pts = pts[~ws.region.contains(pts, tol=1e-7) & cover.member(pts)]
    assert len(pts), "no terrace node in a cover region"
    home = theta[ws.home_index]
    return np.asarray(pts[np.argmin(np.abs(pts - home).max(axis=1))])


def test_a_plan_from_a_terrace_node_passes_the_runtime_checks(ws: Workspace,
                                                             cover: RegionCover) -> None:
    start = _terrace_start(ws, cover)
    home = ws.theta_deg()[ws.home_index]
    # plan_motion ends with the executor's own verification (it raises on refusal)
    pm = plan_motion(agile_profile(), ws, PlanRequest("mvn", start, home, steps=120))
    assert pm.route is not None and pm.route.regions[0] != 0
    assert cover.regions[pm.route.regions[0]].contains(start, tol=1e-7)
    # every sample certified by a fresh runtime certified set, and exactly feasible
    for pts in (np.asarray(pm.plan.reference_deg), np.asarray(pm.plan.position_deg)):
        assert RefinedCertifiedSet.of(ws).contains(pts).all()
        model, links = ws.exact_models()
        pc = check_points(ws, model, links, pts)
        assert (pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm) & pc.start_feasible).all()
