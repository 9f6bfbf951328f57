"""Commissioning: the greedy pose design (feasibility callback, growth with the radius) and the
held-out verification (gravity angle, platform orientation against a truth)."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.commissioning.design import DIRECTIONS, candidate_poses, design_poses
from spm_console.core.commissioning.gravity import AsBuilt, platform_orientation, predict_gravity
from spm_console.core.commissioning.verify import verify_as_built
from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.modes import home_model

MAGIC_DEG = 54.735610317245346  # profiles/agile_wrist.toml: beta_deg = gamma_deg
TRUTH = AsBuilt(horn_deg=(4.0, -3.0, 2.5), mount_rpy_deg=(2.0, -1.5, 3.0), tilt_deg=(1.0, -0.5),
                d_alpha1_deg=(0.3, -0.2, 0.1), d_alpha2_deg=(-0.1, 0.25, -0.3))


@pytest.fixture(scope="module")
def model() -> SpmModel:
    geom = SpmGeometry.from_degrees(90.0, 90.0, MAGIC_DEG, MAGIC_DEG)
    return home_model(geom, np.radians([135.0, 135.0, 135.0]),
                      np.array([-1, 1, 1, 1, 1, 1, -1, -1, 1], float))


def test_candidates_move_every_joint_by_zero_or_the_radius() -> None:
    c = candidate_poses(np.array([135.0, 135.0, 135.0]), (3.0, 10.0))
    assert c.shape == (2 * len(DIRECTIONS), 3)
    offsets = np.unique(np.abs(c - 135.0))
    assert offsets.tolist() == [0.0, 3.0, 10.0]


def test_design_keeps_to_what_the_caller_allows_and_starts_at_home(model: SpmModel) -> None:
    asked: list[tuple[float, ...]] = []

    def allowed(theta_deg: np.ndarray) -> bool:
        asked.append(tuple(theta_deg))
        return bool(theta_deg[0] <= 140.0)  # e.g. a workspace edge on joint 1

    d = design_poses(model, 12, (3.0, 6.0, 10.0), allowed)
    assert len(d.theta_deg) == 12 and len(set(d.theta_deg)) == 12
    assert d.theta_deg[0] == (135.0, 135.0, 135.0)
    assert all(t[0] <= 140.0 for t in d.theta_deg)
    assert d.refused == 2 * 9  # joint 1 at +6° and +10°: nine directions each
    assert d.candidates == len(asked) == 1 + 3 * 26
    assert d.unreachable == 0
    assert d.singular_values == tuple(sorted(d.singular_values, reverse=True))
    assert d.worst_std_deg == pytest.approx(1.0 / d.singular_values[-1])


def test_farther_poses_determine_the_wrist_better(model: SpmModel) -> None:
    near = design_poses(model, 16, (3.0, 6.0, 10.0))
    far = design_poses(model, 16, (10.0, 20.0, 30.0))
    assert far.worst_std_deg < near.worst_std_deg / 2
    # fixing what a jig and a drawing give leaves the eight others far better determined
    fixed = {"horn_common": 0.0, **dict.fromkeys(
        ("d_alpha1_leg1", "d_alpha1_leg2", "d_alpha1_leg3",
         "d_alpha2_leg1", "d_alpha2_leg2", "d_alpha2_leg3"), 0.0)}
    known = design_poses(model, 16, (3.0, 6.0, 10.0), fixed=fixed)
    assert len(known.singular_values) == 7
    assert known.worst_std_deg < near.worst_std_deg / 5


def test_verification_of_the_truth_is_exact_and_of_a_wrong_fit_is_not(model: SpmModel) -> None:
    theta = np.array([[130.0, 140.0, 128.0], [142.0, 131.0, 137.0], [125.0, 125.0, 145.0]])
    g = 9.8 * predict_gravity(model, TRUTH, theta)
    truth_R = platform_orientation(model, TRUTH, theta)
    ok = verify_as_built(model, TRUTH, theta, g, truth_R)
    assert ok.gravity_max_deg < 1e-9
    assert ok.orientation_max_deg is not None and ok.orientation_max_deg < 1e-9
    wrong = AsBuilt(horn_deg=(5.0, -3.0, 2.5), mount_rpy_deg=TRUTH.mount_rpy_deg,
                    tilt_deg=TRUTH.tilt_deg, d_alpha1_deg=TRUTH.d_alpha1_deg,
                    d_alpha2_deg=TRUTH.d_alpha2_deg)
    off = verify_as_built(model, wrong, theta, g, truth_R)
    assert off.orientation_deg is not None
    assert min(off.orientation_deg) > 0.3 and max(off.orientation_deg) < 1.5  # one horn by 1°
    assert off.gravity_max_deg > 0.3
    assert verify_as_built(model, TRUTH, theta, g).orientation_deg is None
