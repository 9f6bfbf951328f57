"""The convex region P: inside P', no redundant rows, ≤ 64 rows, coverage, containment."""

from __future__ import annotations

import warnings

import cvxpy as cp
import numpy as np
import pytest

from spm_console.core.polytope.iris import closest_on_boxes
from spm_console.core.polytope.region import Region
from spm_console.core.regions.choice import choose_region, region_containing
from spm_console.core.regions.p_build import build_region
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.segment_check import check_segment
from spm_console.errors import InfeasibleError
from tests.support.ws_helpers import MINTIME_START, MVN_GOAL, MVN_START, agile_workspace


@pytest.fixture(scope="module")
def ws() -> Workspace:
    return agile_workspace()


def open_cubes_hit(region: Region, centers: np.ndarray, half: float) -> np.ndarray:
    """Separating-axis test (exact for convex polytopes): True where P meets the open
    cube of half-width ``half`` around a centre. Independent of how P was built."""
    V = region.vertices()
    An = region.normalized()
    tight = np.abs(V @ An.A.T - An.b) < 1e-7
    edges = []
    for i in range(len(V)):
        for j in range(i + 1, len(V)):
            if (tight[i] & tight[j]).sum() >= 2 and np.linalg.norm(V[i] - V[j]) > 1e-9:
                edges.append(V[j] - V[i])
    axes = [*An.A, *np.eye(3)]
    for e in edges:
        for k in range(3):
            c = np.cross(e, np.eye(3)[k])
            if np.linalg.norm(c) > 1e-9:
                axes.append(c / np.linalg.norm(c))
    separated = np.zeros(len(centers), bool)
    for n in axes:
        p = V @ n
        c = centers @ n
        r = half * np.abs(n).sum()
        separated |= (p.max() <= c - r + 1e-9) | (p.min() >= c + r - 1e-9)
    return ~separated


def assert_inside_p_prime(region: Region, ws: Workspace) -> None:
    th = ws.theta_deg()
    bad = th[~ws.feasible]
    hit = open_cubes_hit(region, bad, ws.step_deg)
    assert not hit.any(), f"P meets the cube of infeasible node {bad[np.argmax(hit)]}"
    lo, hi = ws.range_deg()
    V = region.vertices()
    assert V.min() >= lo - 1e-7 and V.max() <= hi + 1e-7


def test_sat_detects_a_hit(ws: Workspace) -> None:
    """The checker itself can fail: the grid box meets infeasible cubes."""
    box = Region.box(*ws.range_deg())
    assert open_cubes_hit(box, ws.theta_deg()[~ws.feasible], ws.step_deg).any()


def test_default_region(ws: Workspace) -> None:
    P = ws.region
    assert_inside_p_prime(P, ws)
    assert P.halfspaces <= 64
    assert P.redundant_rows() == []  # LP check, independent of the facet test used to build
    feas = ws.theta_deg()[ws.feasible]
    cov = float(np.all(feas @ P.A.T <= P.b + 1e-7, axis=1).mean())
    assert cov >= 0.85
    assert cov == pytest.approx(ws.coverage())
    for t in ((135.0, 135.0, 135.0), MVN_START, MINTIME_START):
        assert P.contains(np.array(t)), t


def test_region_containing_start_and_goal(ws: Workspace) -> None:
    a, b = np.array(MVN_START), np.array(MVN_GOAL)
    assert not ws.region.contains(b)  # the goal is outside the default P
    R = region_containing(ws, a, b)
    assert R.contains(np.stack([a, b]), tol=1e-7).all()
    assert_inside_p_prime(R, ws)
    assert R.halfspaces <= 64
    assert R.redundant_rows() == []
    # the whole segment is inside (convexity) and so is a fair share of the workspace
    s = np.linspace(0, 1, 50)[:, None]
    assert R.contains(a + s * (b - a), tol=1e-7).all()
    feas = ws.theta_deg()[ws.feasible]
    assert R.contains(feas, tol=1e-7).mean() > 0.6


def test_region_containing_returns_cached_p(ws: Workspace) -> None:
    R = region_containing(ws, np.array(MVN_START), np.array(MINTIME_START))
    assert R is ws.region


def test_region_containing_refuses_infeasible_segment(ws: Workspace) -> None:
    with pytest.raises(InfeasibleError) as e:
        region_containing(ws, np.array(MVN_START), np.array([150.0, 70.0, 70.0]))
    msg = e.value.message
    assert "leaves the feasible set at θ ≈" in msg
    assert "singular (ζ =" in msg or "links collide" in msg or "unreachable" in msg
    with pytest.raises(InfeasibleError, match="outside the workspace grid"):
        region_containing(ws, np.array(MVN_START), np.array([100.0, 100.0, 170.0]))


def test_halfspace_cap_is_honoured(ws: Workspace) -> None:
    res = build_region(ws, max_halfspaces=24)
    assert res.region.halfspaces <= 24
    assert_inside_p_prime(res.region, ws)
    assert res.region.contains(ws.theta_deg()[ws.home_index])
    assert res.coverage > 0.85


def test_closest_point_on_boxes_matches_qp() -> None:
    rng = np.random.default_rng(4)
    L = rng.normal(size=(3, 3))
    M = L @ L.T + 0.2 * np.eye(3)
    c = rng.normal(size=3)
    lo = rng.uniform(-3, 3, (150, 3))
    hi = lo + rng.uniform(0.0, 2.0, (150, 3))
    xb, val = closest_on_boxes(M, c, lo, hi)
    x = cp.Variable(3)
    lo_p, hi_p = cp.Parameter(3), cp.Parameter(3)
    prob = cp.Problem(cp.Minimize(cp.quad_form(x - c, M)), [x >= lo_p, x <= hi_p])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(len(lo)):
            lo_p.value, hi_p.value = lo[k], hi[k]
            prob.solve(solver=cp.CLARABEL)
            assert val[k] == pytest.approx(prob.value, abs=1e-6, rel=1e-6)
    assert np.all(xb >= lo - 1e-12) and np.all(xb <= hi + 1e-12)


def test_region_helpers() -> None:
    box = Region.box(0.0, 2.0)
    assert box.volume() == pytest.approx(8.0)
    c, r = box.chebyshev()
    assert np.allclose(c, 1.0) and r == pytest.approx(1.0)
    extra = Region(np.vstack([box.A, [[1.0, 1.0, 1.0]], box.A[:1] * 3]),
                   np.r_[box.b, 10.0, box.b[:1] * 3])
    assert sorted(extra.redundant_rows()) in ([6, 7], [0, 6])
    assert extra.without_redundant().halfspaces == 6
    assert extra.without_redundant(method="lp").halfspaces == 6


def test_facet_rows_agree_with_one_lp_per_row_with_copies_and_touching_planes() -> None:
    """The vertex-based facet test keeps exactly the rows the LP test cannot remove, one per
    copy, on random polytopes with redundant rows, exact copies (scaled rows) and planes that
    touch the polytope at a vertex only."""
    rng = np.random.default_rng(11)
    for _ in range(12):
        N = rng.normal(size=(int(rng.integers(6, 30)), 3))
        N /= np.linalg.norm(N, axis=1)[:, None]
        base = Region(np.vstack([N, np.eye(3), -np.eye(3)]),
                      np.r_[rng.uniform(0.5, 1.5, len(N)), np.full(6, 1.2)])
        V = base.vertices()
        far = rng.normal(size=(3, 3))
        touch_a = far / np.linalg.norm(far, axis=1)[:, None]
        touch_b = (V @ touch_a.T).max(0)  # supporting planes: they touch, cut nothing
        k = int(rng.integers(0, base.halfspaces))
        reg = Region(np.vstack([base.A, touch_a, 2.5 * base.A[k:k + 1], base.A[:2]]),
                     np.r_[base.b, touch_b, 2.5 * base.b[k:k + 1], base.b[:2] + 0.3])
        facets = reg.facet_rows()
        lp_kept = sorted(set(range(reg.halfspaces)) - set(reg.redundant_rows()))
        assert len(facets) == len(lp_kept)
        assert np.allclose(Region(reg.A[facets], reg.b[facets]).normalized().vertices().max(0),
                           reg.vertices().max(0))


def test_mintime_pair_is_refined_on_the_2deg_grid(ws: Workspace) -> None:
    """[70, 90, 80]° → goal: on the 2° grid the segment passes within Δ of a singular
    node, though every point of it is feasible (the grid check says both); the region is
    then grown with the grid refined near the segment (certified in tests/unit/core/test_refine.py)."""
    start, goal = np.array(MINTIME_START), np.array(MVN_GOAL)
    with pytest.raises(InfeasibleError) as e:
        check_segment(ws, start, goal)
    assert "singular" in e.value.message
    assert "Checked exactly, the segment itself is feasible" in e.value.message
    choice = choose_region(ws, start, goal)
    assert choice.kind == "refined" and choice.resolution_deg == ws.step_deg / 4
    assert choice.region.contains(np.array([start, goal]), tol=1e-7).all()
    assert "refined resolution h = 0.5°" in choice.describe()


@pytest.mark.slow
def test_mintime_pair_on_the_1deg_grid() -> None:
    from spm_console.config.models import build_workspace
    from tests.support.ws_helpers import agile_profile, with_step

    ws1 = build_workspace(with_step(agile_profile(), 1.0))
    assert ws1.coverage() >= 0.85 and ws1.region.halfspaces <= 64
    for start in (MINTIME_START, MVN_START):
        R = region_containing(ws1, np.array(start), np.array(MVN_GOAL))
        assert R.contains(np.array([start, MVN_GOAL]), tol=1e-7).all()
        assert_inside_p_prime(R, ws1)
        assert R.halfspaces <= 64
