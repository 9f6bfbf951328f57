"""FK around singularities along the workspace graph (core/kinematics/fk_path.py), checked by second
routes: the loop-closure residual, continuation back home along the reversed path, the
straight path from home and the flood fill's own pose, and the home's assembly and working
modes. Refusals are checked against every assembly mode at θ (multi-start solve)."""

from __future__ import annotations

import itertools
import json
from dataclasses import replace

import numpy as np
import pytest

from spm_console.core.kinematics.continuation import PATH_ZETA_FLOOR
from spm_console.core.kinematics.model import FkResult, SpmModel, full_residual, platform_axes
from spm_console.core.kinematics.modes import solve_all
from spm_console.core.workspace.fk_path import FkGraph, fk_connected, fk_graph, graph_of, route_fk
from tests.support.ws_helpers import agile_workspace

BOX = (65.0, 155.0)
FORCED = FkResult(ok=False, pose=None, reason="straight path refused (forced by the test)")


@pytest.fixture(scope="module")
def setup() -> tuple[SpmModel, FkGraph]:
    ws = agile_workspace()
    model, _ = ws.exact_models()
    return model, fk_graph(ws, model)


def _on_home_side(model: SpmModel, theta_rad: np.ndarray, R: np.ndarray) -> bool:
    _, d1, d2 = model.mode_check(theta_rad, R)
    return bool(d1 > 1e-9 and (d2 > 1e-9).all())


def _check_pose(model: SpmModel, r: FkResult, theta_deg: np.ndarray) -> None:
    """Second routes for a graph-path FK result."""
    assert r.ok and r.pose is not None, r.reason
    th = np.radians(theta_deg)
    # (a) the loop-closure equations (3)-(5) hold
    w = model.geom.w(th)
    assert float(full_residual(model.geom, w, platform_axes(r.pose.R, model.v_home))) < 1e-10
    # (b) back home along the reversed path: the identity orientation again
    way = np.asarray(r.waypoints_deg)
    np.testing.assert_allclose(way[0], np.degrees(model.theta_home), atol=1e-12)
    np.testing.assert_allclose(way[-1], theta_deg, atol=1e-12)
    R = r.pose.R
    for a, b in zip(way[::-1][:-1], way[::-1][1:], strict=True):
        back = model.track(np.radians(b), np.radians(a), R)
        assert back.ok and back.pose is not None, back.reason
        R = back.pose.R
    np.testing.assert_allclose(R, np.eye(3), atol=1e-9)
    # (c) the home's assembly mode and working modes
    assert _on_home_side(model, th, r.pose.R)


@pytest.mark.parametrize("theta_deg", [[66.80, 155.00, 131.48], [65.0, 71.0, 139.0],
                                       [150.3, 66.1, 90.7], [100.0, 100.0, 100.0]])
def test_graph_route_agrees_with_straight_path_and_flood_fill(
        setup: tuple[SpmModel, FkGraph], theta_deg: list[float]) -> None:
    model, graph = setup
    th = np.asarray(theta_deg)
    r = route_fk(model, graph, np.radians(th), FORCED)
    assert r.route == "graph" and len(r.waypoints_deg) >= 2
    _check_pose(model, r, th)
    straight = model.track(np.radians(th))  # a second route: straight from home
    assert straight.ok and straight.pose is not None
    np.testing.assert_allclose(r.pose.R, straight.pose.R, atol=1e-9)  # type: ignore[union-attr]
    idx = agile_workspace().index_of(th)
    if idx is not None and np.allclose(graph.node_deg(idx), th):  # a node: the flood fill's pose
        np.testing.assert_allclose(r.pose.R, graph.R[idx], atol=1e-9)  # type: ignore[union-attr]


def test_route_goes_around_a_blocked_region(setup: tuple[SpmModel, FkGraph]) -> None:
    """Nodes removed from the graph between home and θ: the route detours through the
    remaining nodes (several segments) and still lands on the straight path's pose."""
    model, graph = setup
    ws = agile_workspace()
    th = np.array([95.0, 97.0, 101.0])
    T = ws.theta_deg()
    block = np.all((T >= 103.0) & (T <= 127.0), axis=-1)  # a cube across the straight line
    g2 = graph_of(graph.axes_deg, graph.step_deg, graph.nodes & ~block, ws.zeta, ws.R, graph.home_index)
    r = route_fk(model, g2, np.radians(th), FORCED)
    assert r.route == "graph" and len(r.waypoints_deg) >= 3  # at least one detour corner
    way = np.asarray(r.waypoints_deg)
    for a, b in itertools.pairwise(way):  # no segment enters the blocked cube
        s = a + np.linspace(0, 1, 200)[:, None] * (b - a)
        assert not np.all((s > 103.0 + 1e-9) & (s < 127.0 - 1e-9), axis=-1).any()
    _check_pose(model, r, th)
    straight = model.track(np.radians(th))
    np.testing.assert_allclose(r.pose.R, straight.pose.R, atol=1e-9)  # type: ignore[union-attr]


def test_random_straight_failures(setup: tuple[SpmModel, FkGraph]) -> None:
    """The issue's sample (1,200 uniform θ in the grid box, fixed seed): every θ whose
    straight path from home crosses a singularity is either solved along the graph (and
    checked) or refused as not connected to home; a refusal that says no mode is on the
    home's side is checked against every assembly mode at θ."""
    model, graph = setup
    T = np.random.default_rng(1).uniform(*BOX, (1200, 3))  # 12 straight-path failures
    failed = [t for t, r in zip(T, model.track_batch(np.radians(T)), strict=True) if not r.ok]
    assert len(failed) >= 5
    for th in failed:
        r = fk_connected(model, np.radians(th), lambda: graph, BOX)
        if r.ok:
            _check_pose(model, r, th)
            continue
        assert r.reason.startswith("not connected to home through non-singular configurations")
        # every refusal of this sample is proven from all the assembly modes at θ
        Rs = solve_all(model.geom, np.radians(th), model.v_home)
        home_side = [R for R in Rs if _on_home_side(model, np.radians(th), R)]
        if "no assembly mode" in r.reason:
            assert Rs and not home_side
        else:
            assert "continuation floor" in r.reason and home_side
            assert all(model.mode_check(np.radians(th), R)[0] < PATH_ZETA_FLOOR for R in home_side)


def test_refusals_name_the_reason(setup: tuple[SpmModel, FkGraph]) -> None:
    model, graph = setup
    r = fk_connected(model, np.radians([70.55, 76.08, 152.62]), lambda: graph, BOX)
    assert not r.ok and "not connected to home" in r.reason and "ζ = 0" in r.reason

    def no_graph() -> FkGraph:
        raise AssertionError("outside the grid: the graph must not be loaded")

    r = fk_connected(model, np.radians([10.0, 170.0, 20.0]), no_graph, BOX)
    assert not r.ok and "outside the workspace grid" in r.reason and "only attempt" in r.reason
    r = route_fk(model, graph, np.radians([10.0, 170.0, 20.0]), replace(FORCED, reason="x"))
    assert "outside the workspace grid" in r.reason


def test_straight_path_never_loads_the_graph(setup: tuple[SpmModel, FkGraph]) -> None:
    model, _ = setup

    def no_graph() -> FkGraph:
        raise AssertionError("the straight path worked: no graph needed")

    r = fk_connected(model, np.radians([95.0, 110.0, 105.0]), no_graph, BOX)
    assert r.ok and r.route == "straight" and len(r.waypoints_deg) == 2


def test_cli_path_key_and_refusal(capsys: pytest.CaptureFixture[str]) -> None:
    from spm_console.cli.main import main

    assert main(["fk", "--theta", "95", "110", "105", "--json"]) == 0
    p = json.loads(capsys.readouterr().out)["path"]
    assert p["route"] == "straight" and p["waypoints"] == 2
    np.testing.assert_allclose(p["waypoints_deg"][-1], [95, 110, 105])
    assert main(["fk", "--theta", "70.55", "76.08", "152.62"]) == 5
    err = capsys.readouterr().err
    assert "not connected to home" in err and "Traceback" not in err


def test_the_wrist_service_fk_reports_the_path() -> None:
    from spm_console.errors import UnreachableError
    from spm_console.services.wrist_service import WristService
    from tests.support.ws_helpers import agile_profile

    w = WristService(agile_profile())
    rec = w.fk([100.0, 120.0, 110.0])
    assert rec.path is not None and rec.path.route == "straight" and rec.path.waypoints == 2
    assert w.workspace is None and w._fk_graph._graph is None  # the fast path loads nothing
    with pytest.raises(UnreachableError, match="not connected to home"):
        w.fk([70.55, 76.08, 152.62])


def test_failed_shortcut_falls_back_to_grid_steps(setup: tuple[SpmModel, FkGraph],
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A shortcut that fails (here: every segment longer than one grid step, refused on
    purpose) is replaced by its grid steps; the pose is the straight path's all the same."""
    import spm_console.core.workspace.fk_path as fk_path

    model, graph = setup
    real = fk_path._segment

    def short_only(m: SpmModel, a: np.ndarray, R: np.ndarray, b: np.ndarray):  # type: ignore[no-untyped-def]
        if float(np.abs(np.asarray(b) - np.asarray(a)).max()) > graph.step_deg + 1e-9:
            return fk_path._Leg(False, R, 0, 1.0, "refused by the test")
        return real(m, a, R, b)

    monkeypatch.setattr(fk_path, "_segment", short_only)
    th = np.array([121.0, 125.0, 129.0])  # a node 7 + 5 + 3 grid steps from home (a node too)
    r = route_fk(model, graph, np.radians(th), FORCED)
    assert r.ok and r.pose is not None, r.reason
    way = np.asarray(r.waypoints_deg)
    assert len(way) == 1 + 7 + 5 + 3  # home, then one waypoint per grid step
    assert np.abs(np.diff(way[1:], axis=0)).max() <= graph.step_deg + 1e-9
    straight = model.track(np.radians(th))
    np.testing.assert_allclose(r.pose.R, straight.pose.R, atol=1e-9)  # type: ignore[union-attr]


def test_poses_together_are_each_pose_alone(setup: tuple[SpmModel, FkGraph]) -> None:
    """SpmModel.poses (the batch a continuation ends with) gives what pose() gives row by row,
    and a batch of straight paths gives each row what its own path gives."""
    model, _ = setup
    rng = np.random.default_rng(11)
    theta = model.theta_home + np.radians(rng.uniform(-25.0, 25.0, (40, 3)))
    together = model.track_batch(theta)
    for k in (0, 13, 39):
        alone = model.track(theta[k])
        assert alone.ok == together[k].ok and alone.reason == together[k].reason
        assert alone.pose is not None and together[k].pose is not None
        np.testing.assert_allclose(together[k].pose.R, alone.pose.R, atol=1e-12)
    ok = [r for r in together if r.ok and r.pose is not None]
    assert len(ok) > 30
    batch = model.poses(np.array([r.pose.theta for r in ok]), np.array([r.pose.R for r in ok]))
    for r, p in zip(ok, batch, strict=True):
        single = model.pose(r.pose.theta, r.pose.R)
        np.testing.assert_array_equal(p.theta, single.theta)
        np.testing.assert_allclose(p.v, single.v, atol=1e-15)
        np.testing.assert_allclose(p.n, single.n, atol=1e-15)
        assert p.zeta == pytest.approx(single.zeta, abs=1e-15)
        assert p.residual == pytest.approx(single.residual, abs=1e-15)
