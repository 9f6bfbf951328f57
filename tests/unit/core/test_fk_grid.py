"""Flood-fill FK over a θ grid (core.kinematics.fk_grid) against per-node continuation from
home (:meth:`SpmModel.track`, one straight path per node, no neighbour seeding), the FK
equations (4) evaluated directly, and the 6-connected component of the nodes whose ζ clears
the floor (scipy.ndimage.label). Angles: the grid axes are in rad (the routine's interface),
written here as degrees around the home pose."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import ndimage

from spm_console.core.kinematics.fk_grid import _DIRS, GridFk, neighbour_table, track_grid
from spm_console.core.kinematics.model import SpmModel


def _axes_deg(model: SpmModel, step_deg: float, lo: int, hi: int, offset_deg: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Axes θ_home + offset + step·k, k = lo..hi (deg), returned in rad."""
    home = np.degrees(model.theta_home)
    k = np.arange(lo, hi + 1)
    a, b, c = (np.radians(h + offset_deg + step_deg * k) for h in home)
    return a, b, c


def _per_node(model: SpmModel, g: GridFk) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ok, ζ, R) of every node solved on its own from home (straight-path continuation)."""
    rs = model.track_batch(g.theta().reshape(-1, 3))
    poses = [r.pose for r in rs]
    assert all(p is not None for p in poses)
    ok = np.array([r.ok for r in rs]).reshape(g.shape)
    zeta = np.array([p.zeta for p in poses if p is not None]).reshape(g.shape)
    R = np.array([p.R for p in poses if p is not None]).reshape(*g.shape, 3, 3)
    return ok, zeta, R


def test_every_node_matches_its_own_solve_from_home(agile_model: SpmModel) -> None:
    """A 9³ grid of 10° around home (all of it reachable): each node's rotation and ζ agree
    with the node solved alone from home, v = R v⁰ row by row, and the stored residual is
    max |w·v − cos α2| recomputed from the geometry; the waves are the largest grid (L1)
    distance from the start node, here the node 2° from home at index (5, 5, 5): 5 + 5 + 5."""
    model = agile_model
    axes = _axes_deg(model, 10.0, -5, 3, offset_deg=2.0)
    g = track_grid(model, axes)
    assert g.shape == (9, 9, 9)
    ok, zeta, R = _per_node(model, g)
    assert ok.all() and g.reached.all()
    assert np.abs(g.R - R).max() < 1e-9
    assert np.abs(g.zeta - zeta).max() < 1e-9
    assert np.abs(g.v - np.einsum("...ab,ib->...ia", R, model.v_home)).max() < 1e-9
    w = model.geom.w(g.theta().reshape(-1, 3)).reshape(*g.shape, 3, 3)
    res = np.abs((w * g.v).sum(-1) - model.geom.cos_alpha2).max(-1)
    assert np.abs(g.residual - res).max() < 1e-12
    assert res.max() < 1e-9
    assert g.waves == 15
    # θ() is the meshgrid of the axes (deg → rad here)
    TH = g.theta()
    assert TH[2, 7, 4] == pytest.approx([axes[0][2], axes[1][7], axes[2][4]], abs=0)


@pytest.mark.parametrize("floor", [0.45, 0.6, 0.8])
def test_reached_is_the_component_above_the_floor(agile_model: SpmModel, floor: float) -> None:
    """With a ζ floor, the reached nodes are exactly the 6-connected component, holding the
    start node, of the nodes whose own solve from home succeeds with ζ ≥ floor (no node's ζ
    within 1e-3 of these floors); unreached nodes carry NaN poses and ζ = 0."""
    model = agile_model
    g = track_grid(model, _axes_deg(model, 10.0, -4, 4), zeta_floor=floor)
    ok, zeta, R = _per_node(model, g)
    assert np.abs(zeta - floor).min() > 1e-3  # the verdicts are not decided by rounding
    labels, _ = ndimage.label(ok & (zeta >= floor))
    component = labels == labels[4, 4, 4]
    assert 0 < component.sum() < component.size  # the floor cuts the grid
    np.testing.assert_array_equal(g.reached, component)
    assert np.abs(g.R[g.reached] - R[g.reached]).max() < 1e-9
    out = ~g.reached
    assert np.isnan(g.R[out]).all() and np.isnan(g.v[out]).all() and np.isnan(g.residual[out]).all()
    assert (g.zeta[out] == 0.0).all()


def test_progress_reports_the_tried_fraction(agile_model: SpmModel) -> None:
    """One report per wave, rising, the last the share of nodes tried: the reached ones and
    their 6-neighbours (a binary dilation of ``reached``), below 1 when a ζ floor of 0.8 cuts
    the 9³ grid of 10°."""
    seen: list[float] = []
    g = track_grid(agile_model, _axes_deg(agile_model, 10.0, -4, 4), zeta_floor=0.8,
                   progress=seen.append)
    tried = ndimage.binary_dilation(g.reached, ndimage.generate_binary_structure(3, 1))
    assert 0.0 < tried.mean() < 1.0
    assert len(seen) == g.waves > 0
    assert all(b > a for a, b in itertools.pairwise(seen))
    assert seen[-1] == pytest.approx(float(tried.mean()), abs=1e-12)


def test_the_neighbour_table_names_each_nodes_six_neighbours_in_order() -> None:
    """Row p of the table: the flat index of p + d for each d of the flood fill's order, −1
    outside the grid (brute force over a grid with three different lengths)."""
    shape = (4, 3, 5)
    table = neighbour_table(shape)
    assert table.shape == (60, 6)
    for p in itertools.product(*(range(n) for n in shape)):
        for d, step in enumerate(_DIRS):
            q = tuple(a + b for a, b in zip(p, step, strict=True))
            inside = all(0 <= a < n for a, n in zip(q, shape, strict=True))
            want = int(np.ravel_multi_index(q, shape)) if inside else -1
            assert table[np.ravel_multi_index(p, shape), d] == want, (p, step)
