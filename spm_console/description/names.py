"""The one naming scheme of the wrist's links, joints and parts, shared by the URDF, the MJCF
(which the physical emulator loads and reads back by these names) and the run logs' joint
states.

Legs are numbered 1, 2, 3 in every name (the functions below take the code's leg index 0, 1,
2). A link (an MJCF body) is ``base_link``, ``platform`` or ``leg<n>_<part>``; a joint's name
always ends in ``_joint`` and a link's never does, so no link shares a name with a joint (a
URDF's links and joints are frames of one namespace in tools such as Pinocchio):

* ``leg<n>_motor_joint``: the servo's joint, base → ``leg<n>_proximal`` about −u_n (with a
  gear play in the MJCF, base → the drive's rotor ``leg<n>_rotor``, and ``leg<n>_play_joint``
  turns the proximal link against it within the play);
* ``leg<n>_distal_joint``: ``leg<n>_proximal`` → ``leg<n>_distal`` about w_n;
* ``leg<n>_platform_joint``: ``leg<n>_distal`` → ``platform`` about v_n.
"""

from __future__ import annotations

LEGS = 3
BASE = "base_link"
PLATFORM = "platform"
PAYLOAD = "payload"
"""A payload welded to the platform (MJCF of a wrist as built only)."""
IMU_SITE = "imu"
"""The IMU's site on the platform, and the prefix of its sensors (MJCF of a wrist as built)."""
IMU_ACCELEROMETER = "imu_accelerometer"
IMU_GYRO = "imu_gyro"
IMU_FRAMEQUAT = "imu_framequat"


def leg(i: int) -> str:
    """The prefix of leg index ``i`` (0, 1, 2): "leg1", "leg2", "leg3"."""
    if not 0 <= i < LEGS:
        raise ValueError(f"leg index {i}: the wrist has legs 0..{LEGS - 1} (named 1..{LEGS})")
    return f"leg{i + 1}"


def proximal_link(i: int) -> str:
    return f"{leg(i)}_proximal"


def distal_link(i: int) -> str:
    return f"{leg(i)}_distal"


def rotor_body(i: int) -> str:
    """The drive's rotor (MJCF, with a gear play only)."""
    return f"{leg(i)}_rotor"


def motor_joint(i: int) -> str:
    return f"{leg(i)}_motor_joint"


def play_joint(i: int) -> str:
    """The output shaft against the rotor within the gear's play (MJCF, with a play only)."""
    return f"{leg(i)}_play_joint"


def distal_joint(i: int) -> str:
    return f"{leg(i)}_distal_joint"


def platform_joint(i: int) -> str:
    return f"{leg(i)}_platform_joint"


def servo_actuator(i: int) -> str:
    """The MJCF actuator of leg ``i``'s servo."""
    return f"{leg(i)}_servo"


def jig_equality(i: int) -> str:
    """The home jig's hold on leg ``i``'s output shaft (MJCF of a wrist as built only)."""
    return f"{leg(i)}_jig"


def envelope_geom(i: int, segment: str) -> str:
    """Leg ``i``'s collision envelope on ``segment`` (e.g. "leg1_envelope_BC")."""
    return f"{leg(i)}_envelope_{segment}"


LINKS = (BASE, *(proximal_link(i) for i in range(LEGS)), *(distal_link(i) for i in range(LEGS)),
         PLATFORM)
"""The URDF's links (the MJCF's bodies, less the rotors a gear play adds)."""
JOINT_STATE_NAMES = (*(motor_joint(i) for i in range(LEGS)), *(distal_joint(i) for i in range(LEGS)),
                     *(platform_joint(i) for i in range(LEGS)))
"""Every joint of the closed chain, in the order of the logs' ``/joint_states``: the URDF's
joints and the two platform joints of legs 2 and 3 that a tree leaves out."""
