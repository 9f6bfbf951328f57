"""Workspace figures of merit: the tilt-and-torsion split against rotations built from known
angles, the cone against a hand-made set, and the Agile Wrist's figures against a direct
count on its grid."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from spm_console.config.models import grid_spec, model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.model import normal
from spm_console.core.workspace.metrics import tilt_cone_deg, tilt_torsion_deg, workspace_metrics
from spm_console.core.workspace_build import build_workspace


def _frame(n: np.ndarray) -> np.ndarray:
    """The frame H = [e1 e2 n] the split uses (e1 from the axis least along n)."""
    seed = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = seed - n * (seed @ n)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(n, e1), n], axis=1)


@pytest.mark.parametrize("n", [np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 1.0]) / np.sqrt(3)])
def test_tilt_azimuth_and_torsion_are_recovered_from_known_rotations(n: np.ndarray) -> None:
    rng = np.random.default_rng(5)
    phi = rng.uniform(-179, 179, 50)
    tilt = rng.uniform(0.5, 120, 50)
    sigma = rng.uniform(-179, 179, 50)
    # T&T: Rz(φ) Ry(θt) Rz(σ − φ) in the frame of n, by SciPy (an independent composition)
    local = Rotation.from_euler("ZYZ", np.stack([phi, tilt, sigma - phi], 1), degrees=True)
    H = _frame(n)
    R = np.einsum("ia,nab,jb->nij", H, local.as_matrix(), H)
    t, a, s = tilt_torsion_deg(R, n)
    assert np.allclose(t, tilt, atol=1e-9)
    assert np.allclose(np.angle(np.exp(1j * np.radians(a - phi))), 0, atol=1e-9)
    assert np.allclose(np.angle(np.exp(1j * np.radians(s - sigma))), 0, atol=1e-9)
    # a pure turn about n: no tilt, torsion = the turn
    turn = Rotation.from_rotvec(np.outer([10.0, -35.0], n), degrees=True).as_matrix()
    t, _, s = tilt_torsion_deg(turn, n)
    assert np.allclose(t, 0, atol=1e-6) and np.allclose(s, [10.0, -35.0])


def test_the_cone_is_the_smallest_of_the_sectors_largest_tilts() -> None:
    az = np.arange(-180.0, 180.0, 5.0)
    tilt = np.where(np.abs(az - 90) < 20, 20.0, 45.0)  # two sectors reach only 20°
    assert tilt_cone_deg(tilt, az) == pytest.approx(20.0)
    assert tilt_cone_deg(np.full(len(az), 45.0), az) == pytest.approx(45.0)
    assert tilt_cone_deg(tilt[az < 0], az[az < 0]) == 0.0  # half the sectors empty


def test_agile_wrist_figures_match_a_direct_count(agile: Profile) -> None:
    ws = build_workspace(grid_spec(agile.model_copy(update={"workspace": agile.workspace.model_copy(
        update={"step_deg": 5.0})})), cover=False)
    m = workspace_metrics(ws)
    feas = ws.feasible
    assert m.feasible_nodes == int(feas.sum()) == ws.counts()["feasible"]
    assert m.feasible_fraction == pytest.approx(feas.mean())
    assert m.feasible_volume_deg3 == pytest.approx(feas.sum() * 125.0)
    assert m.zeta_min >= ws.zeta_min and m.zeta_min == pytest.approx(ws.zeta[feas].min())
    assert m.clearance_min_mm >= 0.0 and m.clearance_home_mm > 0.0
    # P's exact volume against counting: P holds about its volume in nodes (Δ³ each)
    inside = ws.region.contains(ws.theta_deg().reshape(-1, 3)).sum() * 125.0
    assert m.p_volume_deg3 == pytest.approx(inside, rel=0.15)
    # θ1 = θ2 = θ3 turns the Agile Wrist's platform about its normal at home: no tilt
    model = model_of(agile)
    diag = np.array([ws.R[k, k, k] for k in range(len(ws.axes_deg[0])) if feas[k, k, k]])
    t, _, s = tilt_torsion_deg(diag, normal(model.v_home))
    assert np.allclose(t, 0.0, atol=1e-6) and np.ptp(s) > 60.0
    assert m.torsion_min_deg <= s.min() and m.torsion_max_deg >= s.max()
    assert 30.0 < m.tilt_cone_deg < 90.0
