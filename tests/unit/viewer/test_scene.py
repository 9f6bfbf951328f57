"""The 3D view's scene as numbers (:mod:`spm_console.viewer.scene`): for a pose, the drawn
links form connected legs from the fixed base to a platform that moves rigidly with the
forward kinematics' R, and every link keeps its length."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.viewer.scene import DRAWN_SEGMENTS, MM, WristParts, pose_transforms, wrist_parts

F = NDArray[np.float64]

POSES_DEG = [(135.0, 135.0, 135.0), (108.0, 60.0, 105.0), (95.0, 110.0, 105.0)]


def _ends(T: F, length_m: float) -> tuple[F, F]:
    """The two ends of a capsule drawn along its local y axis (metres)."""
    c, y = T[:3, 3], T[:3, 1]
    return c - 0.5 * length_m * y, c + 0.5 * length_m * y


def _legs(parts: WristParts, tf: dict[str, F], leg: int) -> dict[str, tuple[F, F]]:
    return {s: _ends(tf[f"legs/leg{leg}/{s}"], parts.segment_length[s]) for s in DRAWN_SEGMENTS}


@pytest.mark.parametrize("theta_deg", POSES_DEG)
def test_a_pose_draws_connected_rigid_legs_on_the_fk_platform(agile: Profile,
                                                               theta_deg: tuple[float, ...]) -> None:
    model, links = model_of(agile), link_model_of(agile)
    parts = wrist_parts(model, links)
    pose = model.track(np.radians(theta_deg)).pose
    assert pose is not None
    tf = pose_transforms(model, links, np.radians(theta_deg), pose.R)
    # the platform frame is the FK's rotation, at the centre
    np.testing.assert_allclose(tf["platform"][:3, :3], pose.R, atol=1e-12)
    np.testing.assert_allclose(tf["platform"][:3, 3], 0.0, atol=1e-15)
    for i in range(3):
        seg = _legs(parts, tf, i + 1)
        for s, T in ((s, tf[f"legs/leg{i + 1}/{s}"]) for s in DRAWN_SEGMENTS):
            R = T[:3, :3]
            np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12, err_msg=s)  # a rotation
            assert np.linalg.det(R) == pytest.approx(1.0)
        # the base end is fixed, the proximal link is one piece, the distal one too
        np.testing.assert_allclose(seg["AB"][0], parts.base_points[i], atol=1e-12)
        np.testing.assert_allclose(seg["AB"][1], seg["BC"][0], atol=1e-12)
        np.testing.assert_allclose(seg["DE"][1], seg["EF"][0], atol=1e-12)
        # the distal link ends on the plate, which moves rigidly with R
        np.testing.assert_allclose(seg["EF"][1], pose.R @ parts.plate_points[i], atol=1e-9)
        # the intermediate axis w_i is drawn along w_i(θ)
        w = model.geom.w(np.radians(theta_deg))[i]
        np.testing.assert_allclose(tf[f"axes/w{i + 1}"][:3, 1], w / np.linalg.norm(w), atol=1e-12)


def test_the_parts_are_the_profiles_sizes_in_metres(agile: Profile) -> None:
    links = link_model_of(agile)
    parts = wrist_parts(model_of(agile), links)
    assert parts.delta == pytest.approx(links.delta * MM)
    np.testing.assert_allclose(np.linalg.norm(parts.base_points, axis=1), links.oa * MM)
    assert set(parts.segment_length) == set(DRAWN_SEGMENTS)
    assert all(0.0 < v < 1.0 for v in parts.segment_length.values())  # metres, not mm
