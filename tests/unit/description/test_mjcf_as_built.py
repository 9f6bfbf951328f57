"""The MJCF of a wrist as built: tilt, payload, IMU, jigs; and, without one, the same text as
before as-built files existed (tests/data/mjcf/*.xml were written by that code)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.rotations import rpy_matrix
from spm_console.description import names
from spm_console.description.mjcf import AsBuiltBody, imu_position, plant_params, wrist_mjcf
from tests.support.paths import ROOT

DATA = ROOT / "tests" / "data" / "mjcf"


def test_without_an_as_built_body_the_mjcf_is_byte_identical(agile: Profile) -> None:
    model = model_of(agile)
    with_play = wrist_mjcf(model, plant_params(agile.plant), link_model_of(agile))
    assert with_play + "\n" == (DATA / "agile_wrist.xml").read_text()
    rigid = plant_params(agile.plant.model_copy(update={"backlash_deg": 0.0}))
    assert wrist_mjcf(model, rigid) + "\n" == (DATA / "agile_wrist_rigid.xml").read_text()
    assert wrist_mjcf(model, rigid, None, None) == wrist_mjcf(model, rigid)


@pytest.mark.parametrize("backlash_deg", [0.33, 0.0])
def test_an_as_built_body_adds_its_parts(agile: Profile, backlash_deg: float) -> None:
    model = model_of(agile)
    params = plant_params(agile.plant.model_copy(update={"backlash_deg": backlash_deg}))
    tilt = rpy_matrix(math.radians(4.0), math.radians(-3.0), 0.0)
    body = AsBuiltBody(tilt, rpy_matrix(0.1, -0.2, 0.3), 0.5, (0.02, 0.0, 0.1))
    mj = mujoco.MjModel.from_xml_string(wrist_mjcf(model, params, link_model_of(agile), body))
    assert np.allclose(mj.opt.gravity, tilt.T @ [0.0, 0.0, -9.81])
    site = mj.site(names.IMU_SITE)
    assert site.bodyid[0] == mj.body(names.PLATFORM).id
    assert np.allclose(mj.site_pos[site.id], imu_position(model, params))
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, rpy_matrix(0.1, -0.2, 0.3).reshape(9))
    assert np.allclose(mj.site_quat[site.id], q) or np.allclose(mj.site_quat[site.id], -q)
    payload = mj.body(names.PAYLOAD)
    assert payload.parentid[0] == mj.body(names.PLATFORM).id and payload.jntnum[0] == 0
    assert mj.body_mass[payload.id] == pytest.approx(0.5)
    assert np.allclose(mj.body_pos[payload.id], (0.02, 0.0, 0.1))
    kinds = {int(mj.sensor(k).type[0]) for k in range(mj.nsensor)}
    assert kinds == {int(mujoco.mjtSensor.mjSENS_ACCELEROMETER), int(mujoco.mjtSensor.mjSENS_GYRO),
                     int(mujoco.mjtSensor.mjSENS_FRAMEQUAT)}
    jigs = [mj.equality(names.jig_equality(i)).id for i in range(3)]
    assert not mj.eq_active0[jigs].any()  # inactive until the emulator fits the jig
    # the mass of the wrist's own parts is unchanged
    assert sum(mj.body_mass) == pytest.approx(6 * params.link_mass_kg + params.platform_mass_kg
                                              + 0.5 + (3e-6 if backlash_deg else 0.0))


def test_a_weightless_payload_is_no_body(agile: Profile) -> None:
    body = AsBuiltBody(np.eye(3), np.eye(3))
    text = wrist_mjcf(model_of(agile), plant_params(agile.plant), None, body)
    assert names.PAYLOAD not in text and 'gravity="0 0 -9.81"' in text
