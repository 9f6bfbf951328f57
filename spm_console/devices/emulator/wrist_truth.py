"""The emulated wrist's truth at one instant: what an ideal IMU on its platform senses (no
noise, no bias: :class:`~spm_console.devices.emulator.bno055.ImuTruth`, which an emulated IMU
adds its errors to), the platform's orientation and the joint angles: the truth commissioning
is tested against.

Frames: the world's z axis points up (gravity is −9.81 m/s² along it); the base may be tilted
in it (an as-built ``base_tilt_deg``); the platform frame is the base's at home; the sensor
frame is the IMU's, turned on the platform by its mount (``imu_mount_rpy_deg``). Quaternions
are (w, x, y, z), unit, w ≥ 0, and rotate the second frame named into the first (world ←
sensor: a vector's sensor coordinates to its world coordinates). No MuJoCo here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.devices.emulator.bno055 import ImuTruth

F = NDArray[np.float64]
Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


@dataclass(frozen=True)
class WristTruth:
    """One instant of the emulated wrist's truth."""

    t_s: float
    """The emulator's clock, s (``time.perf_counter()``'s scale, shared by the processes)."""
    imu: ImuTruth
    """What an ideal IMU on the platform senses: world ← sensor rotation, specific force (what
    an accelerometer reads: +9.81 m/s² along the sensor's up axis at rest; MuJoCo's
    ``accelerometer``) and angular rate (MuJoCo's ``gyro``), both in the sensor frame; its
    ``t_s`` is this one's."""
    sensor_quat_wxyz: Quat
    """The sensor's orientation, world ← sensor (``imu.rotation`` as a quaternion)."""
    platform_quat_wxyz: Quat
    """The platform's orientation, world ← platform (with a level base, the forward
    kinematics' R: base ← platform)."""
    theta_deg: Vec3
    """The true joint angles θ1..θ3 at the output shafts, deg."""


def quat_multiply(a: Sequence[float] | F, b: Sequence[float] | F) -> F:
    """The Hamilton product a·b of quaternions (w, x, y, z): rotation b, then a."""
    aw, ax, ay, az = (float(x) for x in a)
    bw, bx, by, bz = (float(x) for x in b)
    return np.array([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw])


def canonical(q: Sequence[float] | F) -> Quat:
    """``q`` normalised, with w ≥ 0 (q and −q are the same rotation)."""
    v = np.asarray(q, float)
    v = v / np.linalg.norm(v)
    if v[0] < 0:
        v = -v
    return (float(v[0]), float(v[1]), float(v[2]), float(v[3]))


def quat_matrix(q: Sequence[float] | F) -> F:
    """The rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = (float(c) for c in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
