"""Workspace grid (Algorithm 2): FK by flood fill, ζ, link distances, classes, connectivity."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from spm_console.config.models import link_model_of, model_of
from spm_console.core.workspace.build import check_theta, classify, home_connected
from spm_console.core.workspace.data import NodeClass, Workspace
from tests.support.ws_helpers import MVN_GOAL, MVN_START, agile_profile, agile_workspace


@pytest.fixture(scope="module")
def ws() -> Workspace:
    return agile_workspace()


def test_counts_are_consistent(ws: Workspace) -> None:
    c = ws.counts()
    assert c["nodes"] == 46**3
    infeasible = ws.singular | ws.colliding
    assert c["feasible"] + int(infeasible.sum()) + c["disconnected"] == c["nodes"]
    assert c["feasible"] > 0.8 * c["nodes"]  # the paper's grid is mostly feasible
    assert c["singular"] > 0 and c["colliding"] > 0
    assert ws.feasible[ws.home_index]


def test_classes_follow_thresholds(ws: Workspace) -> None:
    z, d, k = ws.zeta, ws.min_link_mm, ws.klass
    reached = k != NodeClass.UNREACHED
    assert np.all(z[k == NodeClass.FEASIBLE] >= ws.zeta_min)
    assert np.all(d[k == NodeClass.FEASIBLE] >= ws.min_distance_mm)
    assert np.all(z[k == NodeClass.SINGULAR] < ws.zeta_min)
    assert np.all(d[k == NodeClass.COLLIDING] < ws.min_distance_mm)
    assert np.all(np.isnan(d[~reached])) and np.all(np.isfinite(d[reached]))
    assert ws.min_distance_mm == pytest.approx(28.0)


def _bfs(ok: np.ndarray, start: tuple[int, int, int]) -> np.ndarray:
    """Plain breadth-first search over face neighbours (independent of scipy.ndimage)."""
    seen = np.zeros_like(ok)
    q = deque([start])
    seen[start] = True
    while q:
        i, j, k = q.popleft()
        for di, dj, dk in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)):
            n = (i + di, j + dj, k + dk)
            if all(0 <= n[a] < ok.shape[a] for a in range(3)) and ok[n] and not seen[n]:
                seen[n] = True
                q.append(n)
    return seen


def test_feasible_set_is_the_home_component(ws: Workspace) -> None:
    pointwise = (ws.klass == NodeClass.FEASIBLE) | (ws.klass == NodeClass.DISCONNECTED)
    assert np.array_equal(_bfs(pointwise, ws.home_index), ws.feasible)


def test_disconnected_island_is_not_feasible() -> None:
    shape = (7, 7, 7)
    zeta = np.full(shape, 0.9)
    zeta[3, :, :] = 0.1  # a singular wall splits the grid
    d = np.full(shape, 50.0)
    reached = np.ones(shape, bool)
    k = classify(zeta, d, reached, 0.25, 28.0, (0, 0, 0))
    assert np.all(k[:3] == NodeClass.FEASIBLE)
    assert np.all(k[3] == NodeClass.SINGULAR)
    assert np.all(k[4:] == NodeClass.DISCONNECTED)
    assert not home_connected(np.zeros(shape, bool), (0, 0, 0)).any()


def test_nodes_match_independent_continuation(ws: Workspace) -> None:
    """A spread of nodes re-solved by straight-line continuation from home
    (SpmModel.track, not the flood fill) gives the same pose, ζ and link distance."""
    prof = agile_profile()
    model, links = model_of(prof), link_model_of(prof)
    rng = np.random.default_rng(11)
    th = ws.theta_deg()
    picks: list[tuple[int, ...]] = []
    for cls in (NodeClass.FEASIBLE, NodeClass.SINGULAR, NodeClass.COLLIDING):
        idx = np.argwhere(ws.klass == cls)
        picks += [tuple(i) for i in idx[rng.choice(len(idx), 12, replace=False)]]
    compared = 0
    for i in picks:
        r = model.track(np.radians(th[i]))
        if not r.ok or r.pose is None:
            continue  # a straight path from home may cross a singularity the fill went round
        compared += 1
        assert np.abs(r.pose.R - ws.R[i]).max() < 1e-9
        assert r.pose.zeta == pytest.approx(float(ws.zeta[i]), abs=1e-9)
        w = model.geom.w(np.radians(th[i]))
        d = links.pair_distances(model.u, w, r.pose.v)
        assert float(d.min()) == pytest.approx(float(ws.min_link_mm[i]), abs=1e-9)
        assert int(d.argmin()) == int(ws.closest_pair[i])
    assert compared >= 25


def test_check_theta_reasons(ws: Workspace) -> None:
    th = ws.theta_deg()
    ok = check_theta(ws, np.array(MVN_START))
    assert ok.feasible and ok.in_region and ok.plannable and ok.reason == ""
    assert ok.verdict == "feasible, inside P: plannable in P"
    assert ok.zeta is not None and ok.zeta > 0.5

    goal = check_theta(ws, np.array(MVN_GOAL))
    assert goal.feasible and goal.zeta == pytest.approx(0.29, abs=0.01)

    sing = np.argwhere((ws.klass == NodeClass.SINGULAR) & (ws.zeta > 0.1))[0]
    c = check_theta(ws, th[tuple(sing)])
    assert not c.feasible and "singular: ζ = " in c.reason
    assert c.zeta == pytest.approx(float(ws.zeta[tuple(sing)]), abs=1e-9)

    col = np.argwhere(ws.klass == NodeClass.COLLIDING)[0]
    c = check_theta(ws, th[tuple(col)])
    assert not c.feasible and "links collide: leg" in c.reason and "mm < 2δ = 28.0 mm" in c.reason

    c = check_theta(ws, np.array([100.0, 100.0, 160.0]))
    assert not c.feasible and not c.in_range and "outside the workspace grid" in c.reason

    un = np.argwhere(ws.klass == NodeClass.UNREACHED)[0]
    c = check_theta(ws, th[tuple(un)])
    assert not c.feasible and "no FK solution in the home assembly mode" in c.reason
