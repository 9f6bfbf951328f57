"""One naming scheme for the wrist's links and joints in the URDF, the MJCF and the run logs'
joint states: legs numbered 1..3 everywhere, and no link named as a joint (Pinocchio and other
tools that put a URDF's links and joints in one namespace of frames refuse an ambiguous name).
Pinocchio is not among the dependencies: the URDF is read with ElementTree, the MJCF by MuJoCo.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import mujoco
import pytest

from spm_console.config.schema import Profile
from spm_console.description.for_profile import robot_description
from spm_console.motion.logs.mcap_log import URDF_JOINTS

LINKS = {"base_link", "platform", "leg1_proximal", "leg2_proximal", "leg3_proximal",
         "leg1_distal", "leg2_distal", "leg3_distal"}
URDF_JOINT_NAMES = {"leg1_motor_joint", "leg2_motor_joint", "leg3_motor_joint",
                    "leg1_distal_joint", "leg2_distal_joint", "leg3_distal_joint",
                    "leg1_platform_joint"}


def _urdf(profile: Profile) -> ET.Element:
    text = robot_description(profile, "urdf")
    return ET.fromstring(text.split("\n", 1)[1])  # after the XML declaration


def _numbers(names: set[str]) -> set[str]:
    """Every number in the names ("leg2_distal" → "2"): legs, edges, numbered from 1."""
    return {n for name in names for n in re.findall(r"\d+", name)}


def test_urdf_links_and_joints_never_share_a_name(agile: Profile) -> None:
    robot = _urdf(agile)
    links = [e.get("name") for e in robot.iter("link")]
    joints = [e.get("name") for e in robot.iter("joint")]
    assert set(links) == LINKS and len(links) == len(LINKS)
    assert set(joints) == URDF_JOINT_NAMES and len(joints) == len(URDF_JOINT_NAMES)
    assert not set(links) & set(joints)
    assert _numbers(set(links) | set(joints)) == {"1", "2", "3"}
    for j in robot.iter("joint"):  # every joint joins two of the links
        parent, child = j.find("parent"), j.find("child")
        assert parent is not None and child is not None
        assert {parent.get("link"), child.get("link")} <= LINKS
    collisions = {e.get("name") for e in robot.iter("collision")}
    assert collisions and _numbers({str(c) for c in collisions}) == {"1", "2", "3"}


def _mj_names(mj: mujoco.MjModel, kind: str, count: int) -> set[str]:
    return {getattr(mj, kind)(k).name for k in range(count)}


@pytest.mark.parametrize("backlash_deg", [0.33, 0.0])
def test_mjcf_uses_the_urdfs_names(agile: Profile, backlash_deg: float) -> None:
    """The MJCF's bodies are the URDF's links (and, with a gear play, each drive's rotor), its
    joints the URDF's (and the play between rotor and output shaft); its actuators and
    envelopes are numbered by leg 1..3 as well."""
    profile = agile.model_copy(update={"plant": agile.plant.model_copy(
        update={"backlash_deg": backlash_deg})})
    mj = mujoco.MjModel.from_xml_string(robot_description(profile, "mjcf"))
    bodies = _mj_names(mj, "body", mj.nbody) - {"world"}
    joints = _mj_names(mj, "joint", mj.njnt)
    played = {f"leg{n}_rotor" for n in (1, 2, 3)} if backlash_deg else set()
    assert bodies == (LINKS - {"base_link"}) | played
    plays = {f"leg{n}_play_joint" for n in (1, 2, 3)} if backlash_deg else set()
    assert joints == URDF_JOINT_NAMES | plays
    assert not bodies & joints
    actuators = _mj_names(mj, "actuator", mj.nu)
    assert actuators == {"leg1_servo", "leg2_servo", "leg3_servo"}
    for n in (1, 2, 3):  # each leg's servo drives its motor joint
        assert mj.actuator_trnid[mj.actuator(f"leg{n}_servo").id, 0] == mj.joint(
            f"leg{n}_motor_joint").id
    geoms = {g for g in _mj_names(mj, "geom", mj.ngeom) if g}
    assert _numbers(geoms) == {"1", "2", "3"}


def test_joint_states_name_the_urdfs_joints(agile: Profile) -> None:
    """The logs' /joint_states: the URDF's joints, then the two platform joints of legs 2 and 3
    that the tree leaves out (the MCAP's own names are checked in tests/unit/motion)."""
    urdf = {e.get("name") for e in _urdf(agile).iter("joint")}
    assert set(URDF_JOINTS) == urdf | {"leg2_platform_joint", "leg3_platform_joint"}
    assert len(URDF_JOINTS) == len(set(URDF_JOINTS))
    assert not set(URDF_JOINTS) & LINKS
