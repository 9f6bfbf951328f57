"""Commissioning: the platform rotation's Jacobian in the parameters, the I-optimal pose design
for the orientation across a region, and the tour through the poses.

References: central finite differences of the unique FK (4) for the Jacobian; for the design,
its objective recomputed from those differences and compared with random subsets of the same
candidates and with the E-optimal design near home."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spm_console.core.commissioning.design import design_for_orientation, design_poses, tour
from spm_console.core.commissioning.gravity import (
    AsBuilt,
    evaluate,
    orientation_jacobian,
)
from spm_console.core.commissioning.observability import DEFAULT_NOISE_DEG, free_basis
from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.modes import home_model
from spm_console.errors import BadInputError

MAGIC_DEG = 54.735610317245346
PRIOR = AsBuilt(horn_deg=(0.3, -0.2, 0.1), d_alpha1_deg=(0.2, -0.1, 0.3),
                d_alpha2_deg=(-0.2, 0.1, 0.25))
FIXED = {"horn_common": 0.0}


@pytest.fixture(scope="module")
def model() -> SpmModel:
    geom = SpmGeometry.from_degrees(90.0, 90.0, MAGIC_DEG, MAGIC_DEG)
    return home_model(geom, np.radians([135.0, 135.0, 135.0]),
                      np.array([-1, 1, 1, 1, 1, 1, -1, -1, 1], float))


def _box(rng: np.random.Generator, n: int, half_deg: float) -> np.ndarray:
    return 135.0 + rng.uniform(-half_deg, half_deg, (n, 3))


def _fd_orientation(model: SpmModel, ab: AsBuilt, theta_deg: np.ndarray) -> np.ndarray:
    """∂ω/∂p by central differences of the FK's rotation (K, 3, 14), rad per rad."""
    p0, h = ab.vector_rad(), 1e-6
    out = np.zeros((len(theta_deg), 3, 14))
    for j in range(14):
        dp = np.zeros(14)
        dp[j] = h
        up = evaluate(model, p0 + dp, np.radians(theta_deg), jacobian=False).R
        dn = evaluate(model, p0 - dp, np.radians(theta_deg), jacobian=False).R
        for k in range(len(theta_deg)):
            D = up[k] @ dn[k].T  # exp([2h ω]×), base frame
            out[k, :, j] = np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0],
                                     D[1, 0] - D[0, 1]]) / (4.0 * h)
    return out


def test_orientation_jacobian_is_the_finite_difference_of_the_fk(model: SpmModel) -> None:
    theta = np.array([[145.0, 115.0, 150.0], [165.0, 140.0, 125.0], [135.0, 135.0, 135.0]])
    J = orientation_jacobian(model, PRIOR, theta)
    fd = _fd_orientation(model, PRIOR, theta)
    assert np.abs(J - fd).max() < 1e-7
    # the mounting and the tilt move no link; at home (no horn offsets) the arcs turn nothing
    assert not J[:, :, 3:8].any()
    arcs = AsBuilt(d_alpha1_deg=PRIOR.d_alpha1_deg, d_alpha2_deg=PRIOR.d_alpha2_deg)
    home = orientation_jacobian(model, arcs, np.array([[135.0, 135.0, 135.0]]))
    assert np.abs(home[:, :, 8:]).max() < 1e-9


def _ref_jacobian(model: SpmModel, ref: np.ndarray) -> np.ndarray:
    """∂ω/∂(free parameters) at the reference poses (K, 3, free), rad per deg, from finite
    differences of the FK (computed once per set of reference poses)."""
    return np.asarray(_fd_orientation(model, PRIOR, ref) @ free_basis(FIXED) * (math.pi / 180.0))


def _variances(model: SpmModel, poses: np.ndarray, Jw: np.ndarray) -> np.ndarray:
    """Jw_k C Jw_kᵀ per reference pose (K, 3, 3), rad², ``Jw`` from :func:`_ref_jacobian`."""
    N = free_basis(FIXED)
    sig = math.radians(DEFAULT_NOISE_DEG)
    J = evaluate(model, PRIOR.vector_rad(), np.radians(poses)).jacobian
    assert J is not None
    Js = J.reshape(-1, 14) @ N / sig * (math.pi / 180.0)
    C = np.linalg.inv(Js.T @ Js)
    return np.asarray(np.einsum("kai,ij,kbj->kab", Jw, C, Jw))


def _mean_variance(model: SpmModel, poses: np.ndarray, Jw: np.ndarray) -> float:
    """tr(W C): the mean squared orientation error over the reference poses, rad²."""
    return float(np.mean(np.trace(_variances(model, poses, Jw), axis1=1, axis2=2)))


def test_the_design_predicts_the_orientation_better_than_random_or_near_home_poses(
        model: SpmModel) -> None:
    rng = np.random.default_rng(7)
    home = np.array([[135.0, 135.0, 135.0]])
    cand = np.vstack([home, _box(rng, 120, 25.0)])
    ref = _box(rng, 40, 25.0)
    d = design_for_orientation(model, 16, cand, ref, prior=PRIOR, fixed=FIXED)
    assert len(d.theta_deg) == 16 and d.theta_deg[0] == (135.0, 135.0, 135.0)
    chosen = np.asarray(d.theta_deg)
    assert all(any(np.array_equal(c, x) for x in cand) for c in chosen)
    Jw = _ref_jacobian(model, ref)
    ours = _mean_variance(model, chosen, Jw)
    randoms = [_mean_variance(model, np.vstack([home, cand[1 + rng.choice(120, 15, False)]]),
                              Jw) for _ in range(10)]
    assert ours < min(randoms)
    near = design_poses(model, 16, (3.0, 6.0, 10.0), prior=PRIOR, fixed=FIXED)
    assert ours < _mean_variance(model, np.asarray(near.theta_deg), Jw) / 10
    # its own figure: the worst reference pose's standard error along its worst direction
    worst = math.sqrt(float(np.linalg.eigvalsh(_variances(model, chosen, Jw))[:, -1].max()))
    assert d.orientation_std_deg == pytest.approx(math.degrees(worst), rel=1e-4)


def test_the_design_refuses_what_it_cannot_use(model: SpmModel) -> None:
    ref = np.array([[135.0, 135.0, 135.0]])
    with pytest.raises(BadInputError):
        design_for_orientation(model, 4, np.empty((0, 3)), ref)
    with pytest.raises(BadInputError):
        design_for_orientation(model, 0, ref, ref)
    with pytest.raises(BadInputError):  # the first candidate (home) must have a unique FK
        design_for_orientation(model, 4, np.array([[135.0, 135.0, 400.0]]), ref)


def test_the_tour_visits_every_pose_once_nearest_first() -> None:
    line = np.array([[0.0, 0.0, 0.0], [30.0, 0, 0], [10.0, 0, 0], [20.0, 0, 0], [-5.0, 0, 0]])
    order = tour(line, np.array([1.0, 0.0, 0.0]))
    assert order == [0, 4, 2, 3, 1]  # 0 is nearest; then −5 (5 away) before 10 (10 away)
    rng = np.random.default_rng(3)
    pts = rng.uniform(-40, 40, (30, 3))
    o = tour(pts, np.zeros(3))
    assert sorted(o) == list(range(30))
    path = np.abs(np.diff(np.vstack([np.zeros(3), pts[o]]), axis=0)).max(axis=1).sum()
    given = np.abs(np.diff(np.vstack([np.zeros(3), pts]), axis=0)).max(axis=1).sum()
    assert path < given / 2
