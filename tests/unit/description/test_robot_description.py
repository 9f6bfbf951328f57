"""The exported URDF and MJCF against independent readers: yourdfpy's forward kinematics and
MuJoCo's kinematics and mass properties, at 100 random poses of the unique FK."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import yourdfpy

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.joint_states import JointStates, joint_states
from spm_console.core.kinematics.model import platform_axes
from spm_console.core.kinematics.rotations import expm_so3
from spm_console.description.for_profile import robot_description

POSES = 100


@pytest.fixture(scope="module")
def poses(agile: Profile) -> list[tuple[np.ndarray, np.ndarray, JointStates]]:
    """(θ rad, R, joint states) at 100 random θ within ±25° of home that the FK solves in
    the home modes, well away from singularities (ζ > 0.05)."""
    model = model_of(agile)
    rng = np.random.default_rng(7)
    thetas = model.theta_home + np.radians(rng.uniform(-25.0, 25.0, (3 * POSES, 3)))
    out = []
    for theta, res in zip(thetas, model.track_batch(thetas), strict=True):
        if res.ok and res.pose is not None and res.pose.zeta > 0.05:
            out.append((theta, res.pose.R, joint_states(model, theta, res.pose.R)))
    assert len(out) >= POSES
    return out[:POSES]


def test_joint_states_close_every_leg(agile: Profile,
                                      poses: list[tuple[np.ndarray, np.ndarray, JointStates]]) -> None:
    """Each leg's chain (motor, distal, platform joint) gives the FK's platform rotation, and
    the proximal joint puts w_i where eq. (2) does."""
    model = model_of(agile)
    w0, v0 = model.geom.w(model.theta_home), model.v_home
    for theta, R, js in poses:
        w = model.geom.w(theta)
        for i in range(3):
            prox = expm_so3(-model.u[i] * js.motor[i])
            assert np.abs(prox @ w0[i] - w[i]).max() < 1e-12
            chain = prox @ expm_so3(w0[i] * js.distal[i]) @ expm_so3(v0[i] * js.platform[i])
            assert np.abs(chain - R).max() < 1e-12


def test_urdf_forward_kinematics_puts_the_platform_where_the_fk_does(
        agile: Profile, tmp_path: Path,
        poses: list[tuple[np.ndarray, np.ndarray, JointStates]]) -> None:
    path = tmp_path / "wrist.urdf"
    path.write_text(robot_description(agile, "urdf"))
    robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=True)
    assert sorted(robot.actuated_joint_names) == sorted(
        ["leg1_motor_joint", "leg2_motor_joint", "leg3_motor_joint", "leg1_distal_joint",
         "leg2_distal_joint", "leg3_distal_joint", "leg1_platform_joint"])
    model = model_of(agile)
    v_home = model.v_home
    for _theta, R, js in poses:
        cfg = {f"leg{i + 1}_motor_joint": js.motor[i] for i in range(3)}
        cfg |= {f"leg{i + 1}_distal_joint": js.distal[i] for i in range(3)}
        cfg["leg1_platform_joint"] = js.platform[0]
        robot.update_cfg(cfg)
        T = robot.get_transform("platform", "base_link")
        assert np.abs(T[:3, :3] - R).max() < 1e-9
        assert np.abs(T[:3, 3]).max() < 1e-12  # every joint at the centre
        v = platform_axes(R, v_home)
        for i in range(3):  # legs 2 and 3 end where the platform's v_i is
            D = robot.get_transform(f"leg{i + 1}_distal", "base_link")[:3, :3]
            assert np.abs(D @ v_home[i] - v[i]).max() < 1e-9
    motors = [robot.joint_map[f"leg{i + 1}_motor_joint"] for i in range(3)]
    lo_hi = [(j.limit.lower, j.limit.upper) for j in motors]
    home = np.array(agile.home.theta_deg)
    for i, (lo, hi) in enumerate(lo_hi):
        assert np.isclose(np.degrees(lo), agile.bus.joints[i].min_deg - home[i])
        assert np.isclose(np.degrees(hi), agile.bus.joints[i].max_deg - home[i])


def _mjcf(agile: Profile) -> tuple[mujoco.MjModel, mujoco.MjData]:
    mj = mujoco.MjModel.from_xml_string(robot_description(agile, "mjcf"))
    return mj, mujoco.MjData(mj)


def test_mjcf_closes_the_chain_at_the_fk_joint_states(
        agile: Profile, poses: list[tuple[np.ndarray, np.ndarray, JointStates]]) -> None:
    mj, data = _mjcf(agile)
    adr = {name: mj.jnt_qposadr[mj.joint(name).id] for name in
           (*(f"leg{n}_{k}_joint" for k in ("motor", "play", "distal") for n in (1, 2, 3)),
            "leg1_platform_joint")}
    assert mj.neq == 2
    worst = 0.0
    for _theta, R, js in poses:
        for i in range(3):  # the motor's angle is the drive's plus the gear's play (here 0)
            data.qpos[adr[f"leg{i + 1}_motor_joint"]] = js.motor[i]
            data.qpos[adr[f"leg{i + 1}_play_joint"]] = 0.0
            data.qpos[adr[f"leg{i + 1}_distal_joint"]] = js.distal[i]
        data.qpos[adr["leg1_platform_joint"]] = js.platform[0]
        mujoco.mj_kinematics(mj, data)
        assert np.abs(data.xmat[mj.body("platform").id].reshape(3, 3) - R).max() < 1e-9
        for k in range(mj.neq):
            b1, b2 = mj.eq_obj1id[k], mj.eq_obj2id[k]
            p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ mj.eq_data[k, 0:3]
            p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ mj.eq_data[k, 3:6]
            worst = max(worst, float(np.linalg.norm(p1 - p2)))
    assert worst < 1e-9, worst


def test_urdf_masses_and_inertias_are_mujocos(agile: Profile, tmp_path: Path) -> None:
    """The URDF's inertial of each body equals what MuJoCo computes from the MJCF's capsules."""
    path = tmp_path / "wrist.urdf"
    path.write_text(robot_description(agile, "urdf"))
    robot = yourdfpy.URDF.load(str(path), load_meshes=False)
    mj, _ = _mjcf(agile)
    names = [f"leg{n}_{part}" for part in ("proximal", "distal") for n in (1, 2, 3)] + ["platform"]
    for name in names:
        inertial = robot.link_map[name].inertial
        b = mj.body(name).id
        assert np.isclose(inertial.mass, mj.body_mass[b], rtol=1e-9)
        assert np.allclose(inertial.origin[:3, 3], mj.body_ipos[b], atol=1e-12)
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, mj.body_iquat[b])
        rot = rot.reshape(3, 3)
        full = rot @ np.diag(mj.body_inertia[b]) @ rot.T
        assert np.allclose(inertial.inertia, full, rtol=1e-7, atol=1e-12), name
    total = sum(robot.link_map[n].inertial.mass for n in names)
    assert np.isclose(total, 6 * agile.plant.link_mass_kg + agile.plant.platform_mass_kg)


@pytest.mark.parametrize("name", ["x---y", "a--b-", "wrist 2.0+"])
def test_any_profile_name_gives_well_formed_files(agile: Profile, name: str) -> None:
    import xml.etree.ElementTree as ET

    named = agile.model_copy(update={"profile": agile.profile.model_copy(update={"name": name})})
    robot = ET.fromstring(robot_description(named, "urdf").split("\n", 1)[1])
    assert robot.get("name") == name
    ET.fromstring(robot_description(named, "mjcf"))
    mujoco.MjModel.from_xml_string(robot_description(named, "mjcf"))


def test_a_tilted_base_turns_the_mjcfs_gravity_and_the_urdf_says_so(agile: Profile) -> None:
    """``[plant] base_tilt_deg``: MuJoCo reads the exported MJCF's gravity turned into the
    base's frame (R_tiltᵀ·(0, 0, −g)); the URDF, which has no gravity, names the tilt in its
    comment; a level profile's files say nothing of it."""
    from spm_console.description.mjcf import base_rotation

    tilted = agile.model_copy(update={"plant": agile.plant.model_copy(
        update={"base_tilt_deg": (2.0, -3.0)})})
    mj = mujoco.MjModel.from_xml_string(robot_description(tilted, "mjcf"))
    expected = base_rotation((2.0, -3.0)).T @ np.array([0.0, 0.0, -9.81])
    np.testing.assert_allclose(mj.opt.gravity, expected, atol=1e-5)
    assert "base_tilt_deg" in robot_description(tilted, "urdf")
    assert "base_tilt_deg" not in robot_description(agile, "urdf")
    level = mujoco.MjModel.from_xml_string(robot_description(agile, "mjcf"))
    np.testing.assert_allclose(level.opt.gravity, [0.0, 0.0, -9.81])
