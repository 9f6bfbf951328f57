"""The joint angles at rest from three legs' swings (core.commissioning.rest): exact from
noise-free rotations wherever the wrist rests near home and however the IMU is mounted; the
standard errors grow with the link arcs' uncertainty; rotations no pose explains are refused."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.rest import fit_rest, leg_axes, nudge_rotations
from spm_console.errors import SolverError

SWING = np.array([1.8, -1.75, 1.8])  # + end per leg (a servo counting the other way: −)


def _limits(agile: Profile) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([j.min_deg for j in agile.bus.joints], float),
            np.array([j.max_deg for j in agile.bus.joints], float))


def test_noise_free_swings_give_the_angles_at_rest_and_the_mounting(agile: Profile) -> None:
    model = model_of(agile)
    rest = np.asarray(agile.home.theta_deg) + np.array([9.0, -12.0, 6.0])
    mount = np.array([6.0, -4.0, 8.0])
    body = nudge_rotations(model, np.radians(rest), np.radians(SWING), np.radians(-SWING))
    assert body is not None
    measured = body @ Rotation.from_rotvec(np.radians(mount)).as_matrix()
    fit = fit_rest(model, measured, SWING, -SWING, *_limits(agile), noise_deg=0.01,
                   arc_std_deg=0.3)
    np.testing.assert_allclose(fit.theta_deg, rest, atol=1e-4)
    np.testing.assert_allclose(fit.mount_rotvec_deg, mount, atol=1e-4)
    assert fit.residual_rms_deg < 1e-5 and fit.runner_up_deg > 10 * fit.residual_rms_deg
    # the arcs' share dominates the IMU's noise: the standard errors say so
    plain = fit_rest(model, measured, SWING, -SWING, *_limits(agile), noise_deg=0.01)
    assert all(a > 2 * b for a, b in zip(fit.theta_std_deg, plain.theta_std_deg, strict=True))
    # a small swing turns the platform about each leg's axis dω/dθ_i (eqs. 11, 12)
    axes = leg_axes(model, np.radians(rest))
    r0 = model.track(np.radians(rest))
    assert r0.pose is not None
    for i in range(3):
        along = r0.pose.R.T @ axes[i]
        cos = body[i] @ along / np.linalg.norm(body[i]) / np.linalg.norm(along)
        assert abs(cos) > 0.999


def test_rotations_no_pose_explains_are_refused(agile: Profile) -> None:
    measured = np.radians(np.array([[3.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 0.0, 0.0]]))
    with pytest.raises(SolverError, match="explain"):
        fit_rest(model_of(agile), measured, SWING, -SWING, *_limits(agile))
