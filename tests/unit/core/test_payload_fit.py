"""The payload's first moment from holding offsets (spm_console.core.commissioning.payload):
exact on noise-free offsets simulated from the regressor of the Agile Wrist's bodies, within
its standard errors under quantization and friction-like noise, with or without the runtime's
load model; the mass alone is not what it claims."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.payload import fit_holding, predicted_offsets_deg
from spm_console.core.kinematics.loads import GRAVITY_MPS2, gravity_regressor
from spm_console.description.weight import UP, Weight

S_TRUE = np.array([0.3 * 0.010, -0.3 * 0.005, 0.3 * 0.120])  # 0.3 kg at (10, −5, 120) mm
K_TRUE = 1.4  # deg/(N·m)


def _poses(agile: Profile, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """θ within 25° of home, the wrist's holding torque there, the platform's regressor."""
    model = model_of(agile)
    rng = np.random.default_rng(seed)
    th = np.radians(np.asarray(agile.home.theta_deg) + rng.uniform(-25, 25, (n, 3)))
    ok, Rs = [], []
    for t in th:
        r = model.track(t)
        if r.ok and r.pose is not None:
            ok.append(t)
            Rs.append(r.pose.R)
    th, R = np.asarray(ok), np.asarray(Rs)
    tw = Weight.of(agile).torque_nm(th, R)
    yp = gravity_regressor(model, th, R, UP)[:, :, 18:21]
    return th, tw, yp


def _offsets(tw: np.ndarray, yp: np.ndarray, k_comp: float) -> np.ndarray:
    """θ* − θ the servos hold: the whole load's torque through k, less what the runtime sent."""
    return np.asarray((K_TRUE - k_comp) * tw + K_TRUE * GRAVITY_MPS2 * (yp @ S_TRUE))


@pytest.mark.parametrize("k_comp", [0.0, 1.2])
def test_noise_free_offsets_give_the_payload_exactly(agile: Profile, k_comp: float) -> None:
    _th, tw, yp = _poses(agile, 24, 1)
    fit = fit_holding(_offsets(tw, yp, k_comp), tw, yp, k_comp)
    np.testing.assert_allclose(fit.first_moment_kgm, S_TRUE, atol=1e-10)
    assert fit.compliance_deg_per_nm == pytest.approx(K_TRUE, abs=1e-9)
    assert fit.residual_rms_deg < 1e-10
    np.testing.assert_allclose(predicted_offsets_deg(fit, tw, yp, k_comp),
                               _offsets(tw, yp, k_comp), atol=1e-10)


def test_quantized_offsets_with_friction_stay_within_a_few_standard_errors(
        agile: Profile) -> None:
    _th, tw, yp = _poses(agile, 32, 2)
    rng = np.random.default_rng(3)
    tick = 360.0 / 4096
    held = _offsets(tw, yp, 0.0) + rng.choice([-1.0, 1.0], tw.shape) * 0.09  # friction's band
    measured = tick * np.round(held / tick)
    fit = fit_holding(measured, tw, yp)
    err = np.abs(fit.first_moment_kgm - S_TRUE)
    assert (err <= 4 * fit.first_moment_std_kgm + 1e-4).all(), (err, fit.first_moment_std_kgm)
    assert abs(fit.first_moment_kgm[2] - S_TRUE[2]) < 0.1 * S_TRUE[2]  # the 10 % target's size
    assert fit.singular_values[-1] > 0.2  # wrist and payload seen apart


def test_bad_data_are_refused(agile: Profile) -> None:
    _th, tw, yp = _poses(agile, 6, 4)
    with pytest.raises(ValueError, match="positive compliance"):
        fit_holding(-_offsets(tw, yp, 0.0), tw, yp)
    with pytest.raises(ValueError, match="two poses"):
        fit_holding(np.zeros((1, 3)), tw[:1], yp[:1])
    with pytest.raises(ValueError, match="finite"):
        fit_holding(np.full(tw.shape, np.nan), tw, yp)


def test_the_friction_against_each_joints_approach_is_fitted_exactly(agile: Profile) -> None:
    """Poses held after approaches from either side: the offset f against the approach is a
    fifth unknown, recovered with the payload from noise-free offsets (and left in the
    residual, biasing nothing only on average, without the approach)."""
    _th, tw, yp = _poses(agile, 24, 5)
    approach = np.random.default_rng(6).choice([-1.0, 1.0], tw.shape)
    offsets = _offsets(tw, yp, 0.0) + 0.09 * approach
    fit = fit_holding(offsets, tw, yp, 0.0, approach)
    np.testing.assert_allclose(fit.first_moment_kgm, S_TRUE, atol=1e-10)
    assert fit.compliance_deg_per_nm == pytest.approx(K_TRUE, abs=1e-9)
    assert fit.friction_deg == pytest.approx(0.09, abs=1e-10)
    assert fit.residual_rms_deg < 1e-10
    np.testing.assert_allclose(predicted_offsets_deg(fit, tw, yp, 0.0, approach), offsets,
                               atol=1e-10)
    blind = fit_holding(offsets, tw, yp)
    assert blind.friction_deg is None and blind.residual_rms_deg > 0.05
    with pytest.raises(ValueError, match="approach direction"):
        fit_holding(offsets, tw, yp, 0.0, approach[:-1])
