"""The weight regressor (kinematics only) against MuJoCo's potential energy of the wrist."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from spm_console.config.load import load_profile
from spm_console.config.models import model_of
from spm_console.core.kinematics.loads import (
    BODIES,
    gravity_regressor,
    path_rotations,
    walk_rotations,
)
from spm_console.devices.emulator.physical import PhysicalWrist
from tests.support.paths import ROOT

G = 9.81
UP = np.array([0.0, 0.0, 1.0])  # the MJCF's gravity is −z


@pytest.fixture(scope="module")
def wrist() -> PhysicalWrist:
    w = PhysicalWrist(model_of(load_profile(ROOT / "profiles" / "agile_wrist.toml")))
    w.mj.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    return w


def _moments(w: PhysicalWrist) -> np.ndarray:
    """First moments m·c (kg·m) of the regressor's bodies at home, from MuJoCo's bodies."""
    w.set_theta(w.spm.theta_home)
    names = [f"leg{n}_{part}" for part in ("proximal", "distal") for n in (1, 2, 3)] + ["platform"]
    assert len(names) == len(BODIES)
    return np.concatenate([w.mj.body(n).mass[0] * w.data.xipos[w.mj.body(n).id] for n in names])


def _energy_gradient(w: PhysicalWrist, theta: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """∂U/∂θ (N·m) of the assembled chain by central differences of MuJoCo's energy."""
    def energy(t: np.ndarray) -> float:
        w.set_theta(t)
        mujoco.mj_energyPos(w.mj, w.data)
        return float(w.data.energy[0])

    out = np.zeros(3)
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        out[j] = (energy(theta + e) - energy(theta - e)) / (2 * h)
    return out


def test_the_regressor_gives_mujocos_weight_torques(wrist: PhysicalWrist) -> None:
    """At poses across the workspace (the paper's MVN start and goal among them), g·Y(θ)·s
    with MuJoCo's own masses and centres of mass is MuJoCo's ∂U/∂θ: the weight's load on
    the motors, from kinematics and six first moments per leg only."""
    s = _moments(wrist)
    spm = wrist.spm
    poses_deg = np.array([[135.0, 135.0, 135.0], [127.53, 83.23, 85.25],
                          [66.8, 155.0, 131.48], [100.0, 120.0, 140.0], [150.0, 110.0, 95.0]])
    theta = np.radians(poses_deg)
    R = np.stack([path_rotations(spm, np.linspace(spm.theta_home, t, 30))[-1] for t in theta])
    Y = gravity_regressor(spm, theta, R, UP)
    for n, t in enumerate(theta):
        dU = _energy_gradient(wrist, t)
        assert np.abs(dU).max() > 0.01  # the weight does load the motors here
        np.testing.assert_allclose(G * Y[n] @ s, dU, atol=2e-4 * max(1.0, np.abs(dU).max()))


def test_a_path_is_the_same_from_the_start_at_once_as_walked_row_after_row() -> None:
    """The unique FK (home modes): every row of a path reached straight from the start in
    one batch is the pose the walk row after row reaches (to Newton's round-off)."""
    spm = model_of(load_profile(ROOT / "profiles" / "agile_wrist.toml"))
    k = np.arange(400)[:, None]
    path = np.radians(135.0 + 18.0 * np.sin(0.031 * k * np.array([1.0, 1.3, 0.7]) + [0, 1, 2]))
    at_once = path_rotations(spm, path)
    walked = walk_rotations(spm, path, np.eye(3), spm.theta_home)
    np.testing.assert_allclose(at_once, walked, atol=1e-10)
    # a path through a type-2 singularity is refused at the row where the walk meets it
    beyond = np.linspace(spm.theta_home, np.radians([141.9, 83.2, 46.6]), 200)
    with pytest.raises(ValueError, match=r"no FK along the path at row .*type-2"):
        path_rotations(spm, beyond)


def test_rotating_the_gravity_about_a_fixed_wrist_is_a_different_load() -> None:
    """``up`` enters: a wrist mounted upside down carries the opposite load."""
    spm = model_of(load_profile(ROOT / "profiles" / "agile_wrist.toml"))
    theta = np.radians([[120.0, 140.0, 130.0]])
    R = path_rotations(spm, theta)
    y_up = gravity_regressor(spm, theta, R, UP)
    y_down = gravity_regressor(spm, theta, R, -UP)
    np.testing.assert_allclose(y_down, -y_up)
    assert math.isfinite(float(np.abs(y_up).max())) and np.abs(y_up).max() > 0


def test_a_weighed_payload_rides_the_twin_where_the_load_model_puts_it() -> None:
    """``[plant] payload_kg`` beside the fitted first moment: the profile's physical twin
    carries the payload at m·c / m, and MuJoCo's ∂U/∂θ of that twin is the load model's
    holding torque (which knows m·c only) at poses across the workspace."""
    from spm_console.config.schema import Profile
    from spm_console.description.mjcf import plant_params
    from spm_console.description.weight import holding_torque_nm

    base = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    plant = base.plant.model_copy(update={"payload_moment_kgmm": (9.0, -12.0, 36.0),
                                          "payload_kg": 0.3})
    profile = Profile.model_validate(base.model_copy(update={"plant": plant}).model_dump())
    assert profile.plant.payload_centre_mm == pytest.approx((30.0, -40.0, 120.0))
    w = PhysicalWrist(model_of(profile), plant_params(profile.plant))
    w.mj.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    assert w.mj.body("payload").mass[0] == pytest.approx(0.3)
    poses_deg = np.array([[127.53, 83.23, 85.25], [100.0, 120.0, 140.0], [150.0, 110.0, 95.0]])
    loaded = holding_torque_nm(profile, poses_deg)
    bare = holding_torque_nm(base, poses_deg)
    for n, t in enumerate(np.radians(poses_deg)):
        dU = _energy_gradient(w, t)
        assert np.abs(loaded[n] - bare[n]).max() > 0.02  # the payload does load the motors
        np.testing.assert_allclose(loaded[n], dU, atol=2e-4 * max(1.0, np.abs(dU).max()))


def test_a_tilted_base_turns_the_twins_gravity_and_the_load_models_alike() -> None:
    """``[plant] base_tilt_deg``: the profile's twin stands tilted (its gravity turned into the
    base's frame), and MuJoCo's ∂U/∂θ of that twin is the load model's holding torque, which
    differs from a level base's by far more than the comparison's tolerance."""
    from spm_console.config.schema import Profile
    from spm_console.description.mjcf import plant_params
    from spm_console.description.weight import holding_torque_nm

    base = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    plant = base.plant.model_copy(update={"base_tilt_deg": (2.0, -3.0),
                                          "payload_moment_kgmm": (9.0, -12.0, 36.0),
                                          "payload_kg": 0.3})
    profile = Profile.model_validate(base.model_copy(update={"plant": plant}).model_dump())
    level = Profile.model_validate(base.model_copy(update={"plant": plant.model_copy(
        update={"base_tilt_deg": (0.0, 0.0)})}).model_dump())
    w = PhysicalWrist(model_of(profile), plant_params(profile.plant))
    w.mj.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    assert abs(float(w.mj.opt.gravity[2])) < G and abs(float(w.mj.opt.gravity[0])) > 0.3
    poses_deg = np.array([[127.53, 83.23, 85.25], [100.0, 120.0, 140.0], [150.0, 110.0, 95.0]])
    tilted, flat = holding_torque_nm(profile, poses_deg), holding_torque_nm(level, poses_deg)
    assert np.abs(tilted - flat).max() > 0.01
    for n, t in enumerate(np.radians(poses_deg)):
        dU = _energy_gradient(w, t)
        np.testing.assert_allclose(tilted[n], dU, atol=2e-4 * max(1.0, np.abs(dU).max()))
