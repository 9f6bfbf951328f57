"""The leg and counting direction of a nudged servo from the platform rotation an IMU measures:
every leg and direction recovered through any mounting and pose within 25°; a platform that
did not turn, or turned about no leg's axis, is refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.rest import leg_axes
from spm_console.core.kinematics.rotations import expm_so3
from spm_console.services.commissioning.leg_map import match_leg, rotation_vector


def _quat(R: np.ndarray) -> np.ndarray:
    w = math.sqrt(max(0.0, 1.0 + np.trace(R))) / 2.0
    return np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
                     (R[1, 0] - R[0, 1]) / (4 * w)])


def test_the_rotation_vector_of_two_quaternions_is_the_body_frame_rotation() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        R0 = expm_so3(rng.normal(size=3))
        omega = rng.normal(size=3) * 0.05
        R1 = R0 @ expm_so3(omega)  # turned by omega in the body frame
        assert np.allclose(rotation_vector(_quat(R0), _quat(R1)), omega, atol=1e-12)
        assert np.allclose(rotation_vector(_quat(R0), -_quat(R1)), omega, atol=1e-12)


def test_each_leg_and_direction_is_recovered_through_a_mounting_within_25_degrees(
        agile: Profile) -> None:
    model = model_of(agile)
    axes = leg_axes(model, np.radians(agile.home.theta_deg))
    rng = np.random.default_rng(7)
    for _ in range(50):
        tilt = rng.normal(size=3)
        tilt *= math.radians(25.0) / np.linalg.norm(tilt)
        R = expm_so3(tilt)  # base -> sensor: the pose and the mounting together
        leg, direction = int(rng.integers(3)), int(rng.choice([-1, 1]))
        counted = 2.0 * float(rng.choice([-1.0, 1.0]))
        true_dtheta = math.radians(direction * counted)
        rotation = R.T @ axes[leg] * true_dtheta
        m = match_leg(axes, 7, rotation, counted)
        assert (m.leg, m.direction) == (leg + 1, direction)
        assert m.cos > 0.85 and m.runner_up_cos < 0.5


def test_no_rotation_or_an_unexplained_axis_is_refused(agile: Profile) -> None:
    axes = leg_axes(model_of(agile), np.radians(agile.home.theta_deg))
    with pytest.raises(ValueError, match=r"turned 0\.00°"):
        match_leg(axes, 4, np.zeros(3), 2.0)
    between = (axes[0] / np.linalg.norm(axes[0]) + axes[1] / np.linalg.norm(axes[1])
               + axes[2] / np.linalg.norm(axes[2]))
    with pytest.raises(ValueError, match="no leg explains"):
        match_leg(axes, 4, between / np.linalg.norm(between) * 0.03, 2.0)
