"""Certification refined near the boundary (h = Δ/4): fine verdicts, pointwise membership
against a brute-force reference, refined regions certified by dense exact sampling, and the
runtime verifier accepting (only) what the refined criterion certifies."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.polytope.ellipsoid import Ellipsoid
from spm_console.core.polytope.iris import separating_planes
from spm_console.core.polytope.region import Region
from spm_console.core.regions.choice import choose_region
from spm_console.core.regions.refined import refined_region
from spm_console.core.workspace.check import check_points
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.refine import REFINE, FineGrid, RefinedCertifiedSet
from spm_console.core.workspace.segment_check import check_segment
from spm_console.core.workspace.verify import sample_region
from spm_console.errors import InfeasibleError
from tests.support.ws_helpers import MINTIME_START, MVN_GOAL, agile_workspace

#: Pairs of feasible grid nodes within 2 steps of an infeasible node whose straight segment
#: the 2° grid refuses (within Δ of an infeasible node) and the refined criterion plans.
BOUNDARY_PAIRS = [
    ((147.0, 71.0, 101.0), (101.0, 75.0, 155.0)),
    ((69.0, 111.0, 73.0), (87.0, 141.0, 75.0)),
    ((137.0, 79.0, 79.0), (149.0, 65.0, 123.0)),
    ((65.0, 75.0, 111.0), (107.0, 69.0, 149.0)),
]


@pytest.fixture(scope="module")
def ws() -> Workspace:
    return agile_workspace()


def exact_ok(ws: Workspace, pts: np.ndarray) -> np.ndarray:
    model, links = ws.exact_models()
    pc = check_points(ws, model, links, pts)
    return pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm) & pc.start_feasible


def brute_fine_certified(ws: Workspace, theta: np.ndarray) -> bool:
    """Every fine node within L∞ < h of θ, enumerated and checked one by one; θ in the box."""
    h = ws.step_deg / REFINE
    lo, hi = ws.range_deg()
    if np.any(theta < lo) or np.any(theta > hi):
        return False
    base = np.floor((theta - lo) / h)
    k = np.arange(-1, 3)
    cand = lo + h * (base + np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3))
    near = cand[np.abs(cand - theta).max(1) < h]
    return all(bool(exact_ok(ws, p[None])[0]) for p in near)


def near_samples(region: Region, centre_lo: np.ndarray, centre_hi: np.ndarray, n: int,
                 seed: int) -> np.ndarray:
    """n points uniform in ``region`` ∩ the box [centre_lo, centre_hi] (rejection)."""
    rng = np.random.default_rng(seed)
    out: list[np.ndarray] = []
    got = 0
    while got < n:
        p = rng.uniform(centre_lo, centre_hi, size=(4 * n, 3))
        p = p[region.contains(p, tol=0.0)]
        out.append(p)
        got += len(p)
    return np.concatenate(out)[:n]


def test_fine_verdicts_do_not_depend_on_the_batch(ws: Workspace) -> None:
    fg = FineGrid(ws)
    c = np.rint((np.array([65.0, 153.0, 127.0]) - fg.origin_deg) / fg.step_deg).astype(int)
    idx = fg.cubes(fg.theta_deg(c[None]), REFINE + 1)
    # the closed cube of half-width Δ + h, clipped at θ1 = 65° and θ2 = 155°
    assert len(idx) == (REFINE + 2) * (REFINE + 2 + REFINE) * (2 * REFINE + 3)
    together = fg.verdicts(idx)
    assert 0 < together.sum() < len(idx)  # the boundary runs through this cube
    alone = FineGrid(ws)
    rng = np.random.default_rng(0)
    for k in rng.choice(len(idx), 40, replace=False):
        assert bool(alone.verdicts(idx[k][None])[0]) == bool(together[k])
    # grid nodes keep the grid's verdict; repeats are not evaluated again
    n = fg.evaluated
    fg.verdicts(idx)
    assert fg.evaluated == n
    on_grid = np.all(idx % REFINE == 0, axis=1)
    g = idx[on_grid] // REFINE
    assert np.array_equal(together[on_grid], ws.feasible[g[:, 0], g[:, 1], g[:, 2]])


def test_refined_membership_matches_brute_force(ws: Workspace) -> None:
    cs = RefinedCertifiedSet.of(ws)
    coarse = ws.certified_set()
    rng = np.random.default_rng(3)
    node = np.array([65.0, 153.0, 127.0])
    pts = node + rng.uniform(-2.6, 2.6, size=(150, 3))
    got = cs.contains(pts)
    ref = coarse.contains(pts) | np.array([brute_fine_certified(ws, p) for p in pts])
    assert np.array_equal(got, ref)
    assert (got & ~coarse.contains(pts)).any()  # the refinement certifies more
    assert not got.all()


def test_the_paper_mintime_segment_is_certified_refined(ws: Workspace) -> None:
    cs = RefinedCertifiedSet.of(ws)
    a, b = np.array(MINTIME_START), np.array(MVN_GOAL)
    seg = a + (b - a) * np.linspace(0, 1, 2001)[:, None]
    assert cs.contains(seg).all()
    assert not ws.certified_set().contains(seg).all()


def assert_certified(ws: Workspace, region: Region, lo: np.ndarray, hi: np.ndarray,
                     n: int, seed: int) -> None:
    """``n`` uniform samples of the region (whole), and ``n`` of its part in [lo, hi]
    (near the refined nodes): every one exactly feasible and refined-certified."""
    whole = sample_region(region, *ws.range_deg(), n, np.random.default_rng(seed))
    near = near_samples(region, lo, hi, n, seed)
    cs = RefinedCertifiedSet.of(ws)
    for pts in (whole, near):
        ok = exact_ok(ws, pts)
        assert ok.all(), pts[~ok][:3]
        assert cs.contains(pts).all()
    assert not ws.certified_set().contains(near).all()  # the region uses the refinement


def test_the_paper_mintime_region_is_certified(ws: Workspace) -> None:
    a, b = np.array(MINTIME_START), np.array(MVN_GOAL)
    rr = refined_region(ws, a, b)
    assert rr.region.contains(np.array([a, b]), tol=1e-7).all()
    ref = rr.refinement
    assert len(ref.refined) > 0 and ref.evaluated > 0 and len(ref.fine_bad) > 0
    th = ws.theta_deg().reshape(-1, 3)[ref.refined]
    span = ws.step_deg + ref.h_deg
    assert_certified(ws, rr.region, th.min(0) - span, th.max(0) + span, 20_000, 1)


@pytest.mark.parametrize(("start", "goal"), BOUNDARY_PAIRS)
def test_boundary_pairs_plan_refined(ws: Workspace, start: tuple[float, ...],
                                     goal: tuple[float, ...]) -> None:
    a, b = np.array(start), np.array(goal)
    with pytest.raises(InfeasibleError, match="within Δ = 2°"):
        check_segment(ws, a, b)
    choice = choose_region(ws, a, b)
    assert choice.kind == "refined"
    assert choice.region.contains(np.array([a, b]), tol=1e-7).all()
    lo, hi = np.minimum(a, b) - 4.0, np.maximum(a, b) + 4.0
    assert_certified(ws, choice.region, lo, hi, 5_000, 2)


def test_refined_refusal_names_the_fine_node(ws: Workspace) -> None:
    """The start leaves straight toward a singular fine node 0.5° away."""
    with pytest.raises(InfeasibleError) as e:
        choose_region(ws, np.array([155.0, 107.0, 71.0]), np.array([137.0, 77.0, 89.0]))
    msg = e.value.message
    assert "leaves the feasible set from its first configuration" in msg
    assert "within h = 0.5° of fine node [155.00, 106.50, 71.00]°" in msg
    assert "singular (ζ =" in msg


def test_an_exactly_infeasible_segment_is_refused_without_refining(ws: Workspace) -> None:
    with pytest.raises(InfeasibleError, match="outside the workspace grid"):
        choose_region(ws, np.array(MINTIME_START), np.array([100.0, 100.0, 170.0]))


def test_per_obstacle_half_widths_match_a_shared_one() -> None:
    rng = np.random.default_rng(5)
    Q = rng.uniform(-1, 1, size=(200, 3))
    Q = Q[np.abs(Q).max(1) > 0.3]
    E = Ellipsoid(0.1 * np.eye(3), np.zeros(3))
    req = np.zeros((1, 3))
    A1, b1 = separating_planes(E, Q, 0.05, req)
    A2, b2 = separating_planes(E, Q, np.full(len(Q), 0.05), req)
    assert np.allclose(A1, A2) and np.allclose(b1, b2)
    # mixed widths: every cube lies beyond some plane
    half = np.where(np.arange(len(Q)) % 2 == 0, 0.05, 0.1)
    A, b = separating_planes(E, Q, half, req)
    mins = Q @ A.T - half[:, None] * np.abs(A).sum(1)
    assert np.all((mins >= b - 1e-9).any(1))
