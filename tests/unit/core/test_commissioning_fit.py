"""Commissioning a wrist as built from gravity: the model's Jacobian against finite differences,
exact recovery from noise-free data, what a level base leaves undetermined, and noisy data
against the reported standard errors. The Agile Wrist's geometry (profiles/agile_wrist.toml:
α1 = α2 = 90°, β = γ = the exact magic angle, home θ = 135°, its sign seed)."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.commissioning.design import PoseDesign, design_poses
from spm_console.core.commissioning.fit import CommissioningFit, fit_as_built
from spm_console.core.commissioning.gravity import (
    PARAMETERS,
    AsBuilt,
    evaluate,
    gravity_jacobian,
    predict_gravity,
)
from spm_console.core.commissioning.observability import DEFAULT_SPREAD
from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.modes import home_model

MAGIC_DEG = 54.735610317245346
COMMON = "common horn offset (yaw about the base axis)"
G = 9.80665
TRUTH = AsBuilt(horn_deg=(13.0, -11.5, 6.0), mount_rpy_deg=(7.5, -9.0, 4.0), tilt_deg=(2.5, -3.0),
                d_alpha1_deg=(0.45, -0.3, 0.15), d_alpha2_deg=(-0.2, 0.5, -0.35))
"""A wrist as built: horns a spline tooth off, a tilted bench, an IMU glued by eye, printed arcs."""
ARCS = dict(zip(PARAMETERS[8:], (*TRUTH.d_alpha1_deg, *TRUTH.d_alpha2_deg), strict=True))


@pytest.fixture(scope="module")
def model() -> SpmModel:
    geom = SpmGeometry.from_degrees(90.0, 90.0, MAGIC_DEG, MAGIC_DEG)
    return home_model(geom, np.radians([135.0, 135.0, 135.0]),
                      np.array([-1, 1, 1, 1, 1, 1, -1, -1, 1], float))


def _in_grid(theta_deg: np.ndarray) -> bool:
    return bool((theta_deg >= 65.0).all() and (theta_deg <= 155.0).all())


@pytest.fixture(scope="module")
def wide(model: SpmModel) -> PoseDesign:
    return design_poses(model, 24, (10.0, 20.0, 30.0), _in_grid)


@pytest.fixture(scope="module")
def near(model: SpmModel) -> PoseDesign:
    return design_poses(model, 24, (3.0, 6.0, 10.0), _in_grid)


def _errors(fit: CommissioningFit, truth: AsBuilt) -> np.ndarray:
    return np.array([p.value_deg for p in fit.parameters]) - np.degrees(truth.vector_rad())


def test_jacobian_is_the_finite_difference_of_the_model(model: SpmModel) -> None:
    theta = np.array([[135, 135, 135], [120, 140, 125], [145, 128, 133], [100, 110, 95],
                      [150, 150, 140], [110, 130, 150]], float)
    p = TRUTH.vector_rad()
    J = gravity_jacobian(model, TRUTH, theta)
    base = evaluate(model, p, np.radians(theta), jacobian=False)
    h = 1e-6
    for j, name in enumerate(PARAMETERS):
        dp = np.eye(len(p))[j] * h
        up = evaluate(model, p + dp, np.radians(theta), jacobian=False, warm=base).gravity
        down = evaluate(model, p - dp, np.radians(theta), jacobian=False, warm=base).gravity
        fd = (up - down) / (2 * h)
        assert np.abs(fd - J[:, :, j]).max() < 1e-7, name
    assert np.abs(J).max(axis=(0, 1)).min() > 0.1  # every parameter moves gravity somewhere


def test_noise_free_data_from_a_wide_design_give_back_every_parameter(
        model: SpmModel, wide: PoseDesign) -> None:
    theta = np.array(wide.theta_deg)
    fit = fit_as_built(model, theta, G * predict_gravity(model, TRUTH, theta))
    assert fit.converged and fit.held == ()
    assert not fit.named("undetermined")
    assert np.abs(_errors(fit, TRUTH)).max() < 1e-6
    assert fit.residual_rms_deg < 1e-9


def test_near_home_a_jig_and_known_arcs_give_back_the_rest(model: SpmModel,
                                                           near: PoseDesign) -> None:
    """Near home the arcs act at second order in the distance from home: held at known values
    (and the horns' common mode at a jig's), the other eight come back exactly."""
    theta = np.array(near.theta_deg)
    jig = float(np.mean(TRUTH.horn_deg))
    fit = fit_as_built(model, theta, predict_gravity(model, TRUTH, theta),
                       fixed={"horn_common": jig, **ARCS})
    assert fit.converged and fit.held == () and fit.undetermined_named == ()
    assert set(fit.named("fixed")) == set(ARCS)
    assert np.abs(_errors(fit, TRUTH)).max() < 1e-6
    assert set(fit.named("determined")) == set(PARAMETERS[:8])


def test_a_level_base_leaves_the_common_horn_offset_undetermined_unless_a_jig_fixes_it(
        model: SpmModel, near: PoseDesign) -> None:
    level = AsBuilt(horn_deg=TRUTH.horn_deg, mount_rpy_deg=TRUTH.mount_rpy_deg)
    theta = np.array(near.theta_deg)
    g = predict_gravity(model, level, theta)
    free = fit_as_built(model, theta, g)
    assert COMMON in free.undetermined_named
    assert all(free.parameter(f"horn{i}").status != "determined" for i in (1, 2, 3))
    assert free.held  # and the data hold some directions at the prior
    jig = fit_as_built(model, theta, g, fixed={"horn_common": float(np.mean(level.horn_deg))})
    assert COMMON not in jig.undetermined_named
    arcs = fit_as_built(model, theta, g, fixed={"horn_common": float(np.mean(level.horn_deg)),
                                                **dict.fromkeys(PARAMETERS[8:], 0.0)})
    assert np.abs(_errors(arcs, level)).max() < 1e-6
    assert {arcs.parameter(f"horn{i}").status for i in (1, 2, 3)} == {"determined"}


def test_what_the_data_do_not_determine_keeps_the_prior_not_a_guess(
        model: SpmModel, near: PoseDesign) -> None:
    """Near home with every parameter free the fit holds some directions: along each, the
    fitted values are the start's, exactly (in prior spreads, where the directions are
    orthogonal)."""
    start = AsBuilt(horn_deg=(3.0, 1.0, 2.0), mount_rpy_deg=(0.0, 0.0, 5.0))
    theta = np.array(near.theta_deg)
    fit = fit_as_built(model, theta, predict_gravity(model, TRUTH, theta), start=start)
    assert len(fit.held) == 3
    spread = np.degrees(DEFAULT_SPREAD.vector_rad())
    moved = (fit.as_built.vector_rad() - start.vector_rad()) / np.radians(spread)
    assert np.abs(moved).max() > 0.1  # it did fit something
    for d in fit.held:
        along = np.asarray(d.vector) / spread
        assert abs(moved @ along) / np.linalg.norm(along) < 1e-9
        assert d.std_deg == np.inf
    undetermined = [p for p in fit.parameters if p.status == "undetermined"]
    assert undetermined and all(np.isnan(p.std_deg) for p in undetermined)


def test_a_tilted_base_does_not_determine_it_either(model: SpmModel, near: PoseDesign) -> None:
    """At home a common horn offset turns the platform about the base's axis: on a tilted base
    turning the tilt's azimuth, or the mount's yaw, does the same to gravity."""
    theta = np.array(near.theta_deg)
    fit = fit_as_built(model, theta, predict_gravity(model, TRUTH, theta))
    assert COMMON in fit.undetermined_named
    assert "mount yaw (about the platform axis)" in fit.undetermined_named


def test_gravity_sees_a_common_horn_offset_only_off_the_line_of_equal_angles(
        model: SpmModel) -> None:
    theta = np.array([[135, 135, 135], [120, 120, 120], [145, 135, 135], [135, 145, 130]], float)
    g0 = predict_gravity(model, AsBuilt(), theta)
    g1 = predict_gravity(model, AsBuilt(horn_deg=(1.0, 1.0, 1.0)), theta)
    moved = np.degrees(np.arccos(np.clip((g0 * g1).sum(axis=1), -1.0, 1.0)))
    assert moved[:2] == pytest.approx([0.0, 0.0], abs=1e-5)  # a pure yaw: invisible
    assert moved[2:] == pytest.approx([0.143, 0.191], abs=0.002)  # per degree, 10° off home


def test_noisy_data_fall_within_the_reported_standard_errors(model: SpmModel,
                                                            wide: PoseDesign) -> None:
    """The BNO055's accelerometer: ~0.01 m/s² per axis per sample, 100 samples a pose."""
    theta = np.array(wide.theta_deg)
    sigma = 0.01 / np.sqrt(100)
    g = G * predict_gravity(model, TRUTH, theta)
    g = g + np.random.default_rng(20240611).normal(0.0, sigma, g.shape)
    fit = fit_as_built(model, theta, g, noise_deg=float(np.degrees(sigma / G)))
    assert fit.converged and fit.held == ()
    err = _errors(fit, TRUTH)
    std = np.array([p.std_deg for p in fit.parameters])
    assert (np.abs(err) <= 4.0 * std).all()
    assert np.abs(err[:3]).max() < 0.1
    assert fit.residual_std_deg == pytest.approx(np.degrees(sigma / G), rel=0.4)


def test_fixed_values_are_kept_and_bad_input_refused(model: SpmModel) -> None:
    from spm_console.errors import BadInputError

    theta = np.array([[135.0, 135.0, 135.0], [125.0, 140.0, 135.0]])
    g = predict_gravity(model, TRUTH, theta)
    fit = fit_as_built(model, theta, g, fixed={"tilt_x": 1.25})
    assert fit.parameter("tilt_x").value_deg == 1.25 and fit.parameter("tilt_x").status == "fixed"
    with pytest.raises(BadInputError, match="unknown parameter"):
        fit_as_built(model, theta, g, fixed={"horn4": 0.0})
    with pytest.raises(BadInputError, match="zero vector"):
        fit_as_built(model, theta, np.zeros_like(g))
    with pytest.raises(BadInputError, match="same K"):
        fit_as_built(model, theta, g[:1])
