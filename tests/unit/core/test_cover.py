"""The region cover: certified regions, coverage, the overlap graph, the cache, the CLI."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from spm_console.cli.main import main
from spm_console.core.polytope.cover import RegionCover
from spm_console.core.polytope.region import Region
from spm_console.core.regions import cover as cv
from spm_console.core.regions.cover import build_cover, cyclic_symmetric, uncertified_regions
from spm_console.core.regions.cover_graph import overlap_graph
from spm_console.core.regions.cover_refine import boxes_met
from spm_console.core.regions.p_build import obstacle_nodes
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.refine import FineGrid
from spm_console.core.workspace.verify import verify_cover
from spm_console.errors import ExitCode
from spm_console.store import workspace_cache as wc
from spm_console.store.workspace_cache import cache_key, cache_path, load_or_build, save
from tests.support.paths import ROOT as PROJECT_ROOT
from tests.support.ws_helpers import (
    agile_profile,
    agile_workspace,
    agile_workspace_refined,
    coarse_workspace,
    with_step,
)


@pytest.fixture(scope="module", params=["default", "refined"])
def ws(request: pytest.FixtureRequest) -> Workspace:
    """The 2° workspace with the default cover (grid cubes) and with the refined one."""
    return agile_workspace_refined() if request.param == "refined" else agile_workspace()


@pytest.fixture(scope="module")
def cover(ws: Workspace) -> RegionCover:
    assert ws.cover is not None
    return ws.cover


def test_cover_starts_with_p_and_covers_more(ws: Workspace, cover: RegionCover) -> None:
    assert cover.regions[0] is ws.region
    assert 1 < cover.size <= max(cv.COVER_MAX_REGIONS, cv.REFINED_MAX_REGIONS)
    assert all(r.halfspaces <= cv.COVER_HALFSPACES for r in cover.regions[1:])
    feas = ws.theta_deg()[ws.feasible]
    # the stored fraction is the union's, recomputed independently of the build
    inside = np.zeros(len(feas), bool)
    for r in cover.regions:
        inside |= r.contains(feas, tol=1e-7)
    assert cover.covered == pytest.approx(float(inside.mean()), abs=1e-12)
    assert cover.coverage(feas) == pytest.approx(cover.covered, abs=1e-12)


def test_the_default_cover_avoids_the_grid_cubes() -> None:
    ws = agile_workspace()
    c = ws.cover
    assert c is not None and c.resolution_deg is None and c.refined_cells == 0
    assert c.size <= cv.COVER_MAX_REGIONS
    # more than P alone; the 99 % target needs far more regions on the grid's cubes (cover.py)
    assert c.covered > ws.coverage() + 0.02
    # every region avoids every obstacle cube: a plain grid check, no fine verdicts needed
    Q = obstacle_nodes(ws.feasible, ws.theta_deg())
    hw = np.full((len(Q), 3), ws.step_deg)
    for k, r in enumerate(c.regions):
        assert not boxes_met(r, Q - hw, Q + hw).any(), k


def test_boxes_met_agrees_with_one_lp_per_box() -> None:
    """The centre-ball shortcut and the row screen give the LP's verdict: every box checked
    against the largest ball of region ∩ box, on boxes around a region's faces (some met by a
    sliver, some missed by one) and inside it."""
    region = agile_workspace().region
    centre, radius = region.chebyshev()
    rng = np.random.default_rng(5)
    # box centres near the region's faces and vertices, where a box can pass every one-row
    # screen and still miss the region (half-widths 0.001…0.5°), and a few deep inside
    d = rng.normal(size=(100, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    Ad = d @ region.A.T
    exit_at = np.where(Ad > 0, (region.b - centre @ region.A.T) / np.where(Ad > 0, Ad, 1.0),
                       np.inf).min(axis=1)
    on_faces = centre + d * (exit_at + rng.uniform(-0.6, 0.6, 100))[:, None]
    V = region.vertices(interior=centre)
    near_vertices = V[rng.integers(len(V), size=100)] + 0.6 * rng.uniform(-1, 1, (100, 3))
    c = np.vstack([on_faces, near_vertices, centre + 0.5 * radius * d[:20]])
    n = len(c)
    hw = np.exp(rng.uniform(np.log(1e-3), np.log(0.5), size=(n, 3)))
    lo, hi = c - hw, c + hw
    box = np.vstack([np.eye(3), -np.eye(3)])
    ref = np.array([Region(np.vstack([region.A, box]), np.r_[region.b, h, -x]).chebyshev()[1]
                    for x, h in zip(lo, hi, strict=True)])
    tol = 1e-6
    decided = np.abs(ref - tol) > 1e-7  # the LP's own tolerance decides the rest
    got = boxes_met(region, lo, hi, tol=tol)
    assert (got == (ref > tol))[decided].all()
    assert 0.2 * n < int(got.sum()) < 0.8 * n  # both verdicts, many of each


def test_the_refined_cover_reaches_the_target() -> None:
    ws = agile_workspace_refined()
    c = ws.cover
    assert c is not None and c.size <= cv.REFINED_MAX_REGIONS
    # the target on the profile's own 2° grid (P alone holds far less)
    assert c.covered >= 0.99 > ws.coverage()
    assert c.resolution_deg == pytest.approx(ws.step_deg / 4) and c.refined_cells > 0
    assert c.covered > agile_workspace().cover.covered  # type: ignore[union-attr]


def test_seeds_are_feasible_nodes_inside_their_regions(ws: Workspace, cover: RegionCover) -> None:
    for k, (r, s) in enumerate(zip(cover.regions, cover.seeds_deg, strict=True)):
        idx = ws.index_of(s)
        assert idx is not None and bool(ws.feasible[idx]), k
        assert bool(r.contains(s, tol=1e-7)), k


@pytest.mark.slow
def test_every_region_is_certified_exactly(ws: Workspace, cover: RegionCover) -> None:
    """Every fine cell of a bad grid cell that a region's interior meets has exactly feasible
    corners (fresh verdicts, no obstacle list)."""
    assert uncertified_regions(ws, cover, fine=FineGrid(ws)) == []


def test_the_exact_certification_check_can_fail(ws: Workspace, cover: RegionCover) -> None:
    # a small box around an infeasible node next to a feasible one
    bad_node = ws.theta_deg()[tuple(np.argwhere(~ws.feasible & ndimage.binary_dilation(
        ws.feasible, structure=np.ones((3, 3, 3), bool)))[0])]
    box = Region(np.vstack([np.eye(3), -np.eye(3)]),
                 np.r_[bad_node + 0.3 * ws.step_deg, -(bad_node - 0.3 * ws.step_deg)])
    bad = replace(cover, regions=(cover.regions[0], box))
    assert uncertified_regions(ws, bad) == [1]


def test_every_region_passes_the_sample_verifier(ws: Workspace) -> None:
    model, links = ws.exact_models()
    reports = verify_cover(ws, model, links, n=2000, seed=11)
    assert len(reports) == ws.cover.size  # type: ignore[union-attr]
    for k, r in enumerate(reports):
        assert r.samples == 2000 and r.infeasible == 0 and r.fk_failures == 0, k
        assert r.min_zeta >= ws.zeta_min and r.min_link_mm >= ws.min_distance_mm, k


@pytest.mark.slow
def test_every_region_passes_100k_samples(ws: Workspace) -> None:
    model, links = ws.exact_models()
    for k, r in enumerate(verify_cover(ws, model, links, n=100_000, seed=0)):
        assert r.infeasible == 0 and r.fk_failures == 0, k


def test_edges_hold_their_balls(cover: RegionCover) -> None:
    e = cover.edges
    assert e.dtype == np.int64 and e.shape == (len(cover.edge_radius_deg), 2)
    assert (e[:, 0] < e[:, 1]).all() and (e[:, 1] < cover.size).all()
    assert [tuple(x) for x in e] == sorted({tuple(x) for x in e})
    assert (cover.edge_radius_deg >= cover.min_overlap_deg).all()
    assert cover.min_overlap_deg == pytest.approx(0.25 * 2.0)
    for (i, j), c, r in zip(e, cover.edge_points_deg, cover.edge_radius_deg, strict=True):
        for k in (i, j):
            n = cover.regions[k].normalized()
            assert float(n.slack(c).min()) >= r - 1e-6, (i, j)
        assert cover.overlap(int(j), int(i)) is not None


def test_missing_edges_are_really_missing(cover: RegionCover) -> None:
    """Every pair not joined has no ball of the minimum radius in common (second route:
    the intersection's vertices and an LP on normalized rows)."""
    have = {tuple(x) for x in cover.edges}
    for i in range(cover.size):
        for j in range(i + 1, cover.size):
            if (i, j) in have:
                continue
            both = Region(np.vstack([cover.regions[i].A, cover.regions[j].A]),
                          np.r_[cover.regions[i].b, cover.regions[j].b]).normalized()
            assert both.chebyshev()[1] < cover.min_overlap_deg, (i, j)


def test_symmetric_graph_equals_the_full_one(ws: Workspace, cover: RegionCover) -> None:
    assert cyclic_symmetric(ws)
    e, p, r = overlap_graph(cover.regions, cover.min_overlap_deg, symmetric=False)
    assert np.array_equal(e, cover.edges)
    assert np.allclose(r, cover.edge_radius_deg, atol=1e-6)
    # centres may differ when the LP's optimum is not unique: both must hold the ball
    for (i, j), c, rad in zip(e, p, r, strict=True):
        for k in (i, j):
            assert float(cover.regions[k].normalized().slack(c).min()) >= rad - 1e-6


def test_graph_is_connected(cover: RegionCover) -> None:
    assert cover.connected and (cover.components() == 0).all()
    assert "connected" in cover.describe() and f"{cover.size} regions" in cover.describe()


def test_queries(ws: Workspace, cover: RegionCover) -> None:
    home = ws.theta_deg()[ws.home_index]
    assert 0 in cover.containing(home)
    for k, s in enumerate(cover.seeds_deg):
        assert k in cover.containing(s)
    assert cover.containing(np.array([0.0, 0.0, 0.0])) == []
    i, j = (int(x) for x in cover.edges[0])
    assert j in cover.neighbours(i) and i in cover.neighbours(j)
    assert all(cover.overlap(i, n) is not None for n in cover.neighbours(i))
    assert cover.coverage(np.zeros((0, 3))) == 0.0
    assert cover.coverage(np.array([home, [0.0, 0.0, 0.0]])) == 0.5


def test_a_disconnected_cover_says_so(ws: Workspace) -> None:
    far = Region.box(0.0, 1.0)
    c = RegionCover(regions=(ws.region, far), seeds_deg=np.zeros((2, 3)),
                    edges=np.zeros((0, 2), np.int64), edge_points_deg=np.zeros((0, 3)),
                    edge_radius_deg=np.zeros(0), min_overlap_deg=0.5, covered=0.9)
    assert not c.connected and list(c.components()) == [0, 1]
    assert "2 components" in c.describe() and c.neighbours(0) == []


@pytest.mark.parametrize("refined", [False, True])
def test_build_stops_at_the_region_cap_and_reports_progress_in_order(refined: bool) -> None:
    ws5 = coarse_workspace()  # 5° grid: a fast build
    seen: list[float] = []
    c = build_cover(ws5, max_regions=4, progress=seen.append, refined=refined)
    assert c.size == 4 and ws5.coverage() < c.covered
    assert c.connected
    assert (c.refined_cells > 0) is refined and len(seen) >= 3
    assert seen == sorted(seen) and seen[0] == 0.0 and seen[-1] == 1.0
    if not refined:
        assert c.covered < ws5.cover.covered  # type: ignore[union-attr]


# --- cache -------------------------------------------------------------------------------


def _same_cover(a: RegionCover, b: RegionCover) -> None:
    assert a.size == b.size
    for ra, rb in zip(a.regions, b.regions, strict=True):
        assert np.array_equal(ra.A, rb.A) and np.array_equal(ra.b, rb.b)
    for name in ("seeds_deg", "edges", "edge_points_deg", "edge_radius_deg"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert (a.covered, a.min_overlap_deg, a.seconds) == (b.covered, b.min_overlap_deg, b.seconds)
    assert (a.resolution_deg, a.refined_cells, a.fine_nodes, a.refine_seconds) == (
        b.resolution_deg, b.refined_cells, b.fine_nodes, b.refine_seconds)


def test_cache_round_trip(tmp_path: Path, ws: Workspace) -> None:
    prof = agile_profile()
    path = cache_path(prof, tmp_path)
    save(ws, path, cache_key(prof))
    back = wc.load(path, prof, cache_key(prof))
    assert back.cover is not None and back.cover.regions[0] is back.region
    _same_cover(ws.cover, back.cover)  # type: ignore[arg-type]


def test_cache_without_cover(tmp_path: Path) -> None:
    prof = with_step(agile_profile(), 5.0)
    bare = replace(coarse_workspace(), cover=None)
    path = cache_path(prof, tmp_path)
    save(bare, path, cache_key(prof))
    assert wc.load(path, prof, cache_key(prof)).cover is None


def test_cache_rejects_an_edited_cover(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    prof = with_step(agile_profile(), 5.0)
    ws5 = coarse_workspace()
    assert ws5.cover is not None and ws5.cover.size > 1
    path = cache_path(prof, tmp_path)
    save(ws5, path, cache_key(prof))
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["cover_b"] = arrays["cover_b"] + 1.0  # a looser region: must not be a hit
    np.savez(path, **arrays)  # type: ignore[arg-type]
    monkeypatch.setattr(wc, "build_workspace", lambda profile, progress=None, refined_cover=None: ws5)
    _, info = load_or_build(prof, tmp_path)
    assert not info.hit and "content digest" in info.rebuilt_because


def test_an_older_format_is_stale_not_corrupt(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    prof = with_step(agile_profile(), 5.0)
    ws5 = coarse_workspace()
    path = cache_path(prof, tmp_path)
    save(ws5, path, "an older key")
    with np.load(path) as z:  # and without the cover arrays, as format 3 wrote it
        arrays = {k: z[k] for k in z.files if not k.startswith("cover_")}
    np.savez(path, **arrays)  # type: ignore[arg-type]
    monkeypatch.setattr(wc, "build_workspace", lambda profile, progress=None, refined_cover=None: ws5)
    _, info = load_or_build(prof, tmp_path)
    assert not info.hit and info.rebuilt_because.startswith("stale key")


# --- CLI ---------------------------------------------------------------------------------


@pytest.fixture()
def cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    prof = with_step(agile_profile(), 5.0)
    save(coarse_workspace(), cache_path(prof, tmp_path), cache_key(prof))
    monkeypatch.setenv("SPM_CONSOLE_CACHE", str(tmp_path))
    return tmp_path


def _profile_file(tmp_path: Path) -> Path:
    src = (PROJECT_ROOT / "profiles" / "agile_wrist.toml").read_text()
    assert "step_deg = 2.0" in src
    p = tmp_path / "agile_wrist.toml"
    p.write_text(src.replace("step_deg = 2.0", "step_deg = 5.0"))
    return p


def test_cli_show_reports_the_cover(cache_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    prof = _profile_file(cache_dir)
    assert main(["workspace", "show", "--profile", str(prof), "--json"]) == ExitCode.OK
    d = json.loads(capsys.readouterr().out)
    assert d["cache"]["hit"] is True
    c = coarse_workspace().cover
    assert c is not None
    assert d["cover"]["regions"] == c.size and d["cover"]["covered"] == c.covered
    assert d["cover"]["edges"] == c.edges.tolist() and d["cover"]["connected"] is c.connected
    assert main(["workspace", "show", "--profile", str(prof)]) == ExitCode.OK
    assert f"cover: {c.size} regions" in capsys.readouterr().out


def test_cli_verify_cover(cache_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    prof = _profile_file(cache_dir)
    code = main(["workspace", "verify", "--profile", str(prof), "--cover", "--samples", "300",
                 "--json"])
    d = json.loads(capsys.readouterr().out)
    assert code == ExitCode.OK and d["infeasible"] == 0
    assert len(d["regions"]) == coarse_workspace().cover.size  # type: ignore[union-attr]


def test_cli_builds_a_refined_cover(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("SPM_CONSOLE_CACHE", str(tmp_path))
    prof = _profile_file(tmp_path)
    argv = ["workspace", "build", "--profile", str(prof), "--json"]
    assert main([*argv, "--refined-cover"]) == ExitCode.OK
    d = json.loads(capsys.readouterr().out)
    assert d["cache"]["hit"] is False and d["cover"]["refined_cells"] > 0
    assert d["cover"]["resolution_deg"] == pytest.approx(5.0 / 4)
    assert d["cover"]["covered"] > coarse_workspace().cover.covered  # type: ignore[union-attr]
    assert d["cache"]["path"].endswith("-refined.npz")
    assert main([*argv, "--refined-cover"]) == ExitCode.OK  # the refined file again
    again = json.loads(capsys.readouterr().out)
    assert again["cache"]["hit"] is True and again["cover"]["covered"] == d["cover"]["covered"]
