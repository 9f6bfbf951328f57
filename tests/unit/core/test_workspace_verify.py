"""The sampling verifier: points uniform in P, exact checks, and that it can fail."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.config.models import link_model_of, model_of
from spm_console.core.polytope.region import Region
from spm_console.core.workspace.check import check_points
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.verify import sample_region, verify_region
from tests.support.ws_helpers import agile_profile, agile_workspace


@pytest.fixture(scope="module")
def ws() -> Workspace:
    return agile_workspace()


def test_samples_are_inside_and_spread(ws: Workspace) -> None:
    pts = sample_region(ws.region, 65.0, 155.0, 20_000, np.random.default_rng(1))
    assert pts.shape == (20_000, 3)
    assert ws.region.contains(pts, tol=0.0).all()
    # uniform: the sample mean is the polytope's centroid (checked against qhull's volume
    # split: the halves θ1 < median and > median hold equal volume)
    med = float(np.median(pts[:, 0]))
    lo = Region(np.vstack([ws.region.A, [[1.0, 0, 0]]]), np.r_[ws.region.b, med])
    assert lo.volume() / ws.region.volume() == pytest.approx(0.5, abs=0.02)


def test_point_checks_agree_with_continuation_from_home(ws: Workspace) -> None:
    prof = agile_profile()
    model, links = model_of(prof), link_model_of(prof)
    pts = sample_region(ws.region, 65.0, 155.0, 60, np.random.default_rng(2))
    pc = check_points(ws, model, links, pts)
    assert pc.fk_ok.all()
    res = model.track_batch(np.radians(pts))
    same = 0
    for k, r in enumerate(res):
        if r.ok and r.pose is not None:
            same += 1
            assert np.abs(r.pose.R - pc.R[k]).max() < 1e-9
            assert r.pose.zeta == pytest.approx(float(pc.zeta[k]), abs=1e-9)
    assert same >= 50


def test_region_p_passes(ws: Workspace) -> None:
    prof = agile_profile()
    r = verify_region(ws, model_of(prof), link_model_of(prof), n=5000, seed=3)
    assert r.samples == 5000 and r.infeasible == 0 and r.fk_failures == 0
    assert r.min_zeta >= ws.zeta_min and r.min_link_mm >= ws.min_distance_mm
    assert r.worst_violation <= 0.0


def test_verifier_fails_on_the_whole_box(ws: Workspace) -> None:
    """The grid box holds singular and colliding configurations: the verifier must say so."""
    prof = agile_profile()
    r = verify_region(ws, model_of(prof), link_model_of(prof), region=Region.box(65.0, 155.0),
                      n=5000, seed=4)
    assert r.infeasible > 50 and r.singular > 0 and r.colliding > 0
    assert r.worst_violation > 0.0 and r.fraction_infeasible > 0.01


@pytest.mark.slow
def test_region_p_passes_100k(ws: Workspace) -> None:
    prof = agile_profile()
    r = verify_region(ws, model_of(prof), link_model_of(prof), n=100_000, seed=0)
    assert r.infeasible == 0 and r.fk_failures == 0
