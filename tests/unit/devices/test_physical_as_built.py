"""The physical emulated wrist as built: a tilted base seen by the IMU (MuJoCo's accelerometer
against R·g), a payload's weight in the drives' current, the home jig, and a truth that reading
does not disturb."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spm_console.config.as_built import AsBuilt
from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.rotations import rpy_matrix
from spm_console.description.mjcf import plant_params
from spm_console.devices.emulator.as_built_parts import quat_matrix
from spm_console.devices.emulator.physical import PhysicalWrist
from spm_console.devices.emulator.twin import true_wrist

G = np.array([0.0, 0.0, 9.81])
HEAVY = AsBuilt(payload_kg=2.0, payload_com_mm=(150.0, 0.0, 150.0))


def _wrist(profile: Profile, ab: AsBuilt, jig: bool = False) -> PhysicalWrist:
    tw = true_wrist(profile, ab)
    w = PhysicalWrist(tw.model, plant_params(profile.plant), 4096, None, tw.body)
    w.set_theta(tw.model.theta_home)
    if jig:
        w.hold_jig()
    return w


def test_a_tilted_base_shows_in_the_imu_truth_at_rest(agile: Profile) -> None:
    ab = AsBuilt(base_tilt_deg=(3.0, -2.0), imu_mount_rpy_deg=(5.0, -3.0, 20.0))
    w = _wrist(agile, ab, jig=True)
    w.advance(0.2)
    tr = w.truth()
    R = quat_matrix(tr.sensor_quat_wxyz)  # world ← sensor
    assert np.allclose(tr.imu.rotation, R, atol=1e-12)
    # MuJoCo's accelerometer agrees with the sensor's view of gravity, +g up
    assert np.abs(tr.imu.specific_force_mps2 - R.T @ G).max() < 1e-3
    assert np.abs(tr.imu.angular_rate_radps).max() < 1e-6
    # the sensor sits where the tilt and the mount put it (the platform at home: R = I)
    tilt = rpy_matrix(math.radians(3.0), math.radians(-2.0), 0.0)
    mount = rpy_matrix(*np.radians([5.0, -3.0, 20.0]))
    assert np.abs(R - tilt @ mount).max() < 1e-4
    assert np.abs(quat_matrix(tr.platform_quat_wxyz) - tilt).max() < 1e-4
    # the tilt is what gravity shows: on a level base the same mount reads another direction
    level = _wrist(agile, AsBuilt(imu_mount_rpy_deg=(5.0, -3.0, 20.0)), jig=True)
    level.advance(0.2)
    f_level = level.truth().imu.specific_force_mps2
    assert np.abs(f_level - mount.T @ G).max() < 1e-3
    assert np.degrees(np.arccos(np.dot(f_level, tr.imu.specific_force_mps2) / 9.81**2)) \
        == pytest.approx(math.degrees(math.acos(tilt[2, 2])), abs=0.01)
    assert tr.theta_deg == pytest.approx(tuple(agile.home.theta_deg), abs=0.01)


def test_a_neutral_as_built_moves_bit_identically_to_the_profiles_wrist(agile: Profile) -> None:
    """Its IMU site, switched-off sensors and inactive jigs change nothing in the motion."""
    runs = []
    for body in (None, true_wrist(agile, AsBuilt()).body):
        w = PhysicalWrist(model_of(agile), plant_params(agile.plant), 4096, None, body)
        w.set_theta(w.spm.theta_home)
        for i in range(3):
            w.command(i, w.spm.theta_home[i] + math.radians(5.0 * (i + 1)), True, False)
        w.advance(0.3)
        runs.append(w.data.qpos.copy())
    assert np.array_equal(runs[0], runs[1])


def test_reading_the_truth_leaves_the_motion_bit_identical(agile: Profile) -> None:
    ab = AsBuilt(base_tilt_deg=(2.0, 1.0), payload_kg=0.5, payload_com_mm=(40.0, 0.0, 100.0))
    runs = []
    for read in (False, True):
        w = _wrist(agile, ab)
        for i in range(3):
            w.command(i, w.spm.theta_home[i] + math.radians(3.0 * (i + 1)), True, False)
        for k in range(1, 101):
            w.advance(k * 0.002)
            if read:
                w.truth()
        runs.append((w.data.qpos.copy(), w.data.qvel.copy()))
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])


def test_a_payload_changes_the_holding_current(agile: Profile) -> None:
    currents = []
    for ab in (AsBuilt(), AsBuilt(payload_kg=1.0, payload_com_mm=(100.0, 0.0, 100.0))):
        w = _wrist(agile, ab)
        for i in range(3):
            w.command(i, float(w.spm.theta_home[i]), True, False)
        w.advance(1.0)
        currents.append(np.abs([w.current(i) for i in range(3)]))
    # the empty wrist's drives push against friction and its own weight only (~0.06 A); the
    # payload's ~1 N·m about the centre takes several times that on every leg
    assert currents[0].max() < 0.1
    assert (currents[1] > 2 * currents[0]).all() and currents[1].max() > 0.3


def test_the_jig_holds_the_true_home_until_torque_goes_on(agile: Profile) -> None:
    free = _wrist(agile, HEAVY)
    free.advance(0.5)  # 2 kg at 21 cm outweighs the gears' backdrive friction: it falls
    assert np.degrees(np.abs(free.theta() - free.spm.theta_home)).max() > 5.0
    held = _wrist(agile, HEAVY, jig=True)
    held.advance(0.5)
    assert held.jig_held
    assert np.degrees(np.abs(held.theta() - held.spm.theta_home)).max() < 0.01
    held.command(0, float(held.spm.theta_home[0]), False, False)  # torque off: still held
    assert held.jig_held
    held.command(0, float(held.spm.theta_home[0]), True, False)  # torque on: the jig comes off
    assert not held.jig_held


def test_only_a_wrist_as_built_has_an_imu_and_a_jig(agile: Profile) -> None:
    w = PhysicalWrist(model_of(agile), plant_params(agile.plant))
    assert w.parts is None and not w.jig_held
    with pytest.raises(ValueError, match="IMU"):
        w.truth()
    with pytest.raises(ValueError, match="jig"):
        w.hold_jig()
    w.release_jig()  # nothing to take off
