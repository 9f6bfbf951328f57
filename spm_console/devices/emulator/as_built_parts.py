"""The parts a wrist as built adds to the physical emulated wrist's MuJoCo model
(:class:`~spm_console.description.mjcf.AsBuiltBody`): the IMU's sensors, read on demand, and
the home jig.

The IMU's sensors (MuJoCo's ``accelerometer``, ``gyro``, ``framequat`` on the platform's IMU
site) are switched off while the wrist steps (``mjDSBL_SENSOR``: an accelerometer costs a
constraint-force pass every step) and computed when asked, by one ``mj_forward`` at the state
reached. That pass writes only quantities derived from the state (not the state, nor the
solver's warm start, which only a step's integration sets), so reading the truth leaves the
motion bit-identical.

The jig holds each output shaft at home (a ``joint`` equality per leg, inactive in the model):
an operator's home jig, fitted while torque is off and taken off when torque first goes on.

The truth (:class:`WristTruth`) is in these frames: the world's z axis points up (gravity is
−9.81 m/s² along it); the base may be tilted in it (an as-built ``base_tilt_deg``); the platform
frame is the base's at home; the sensor frame is the IMU's, turned on the platform by its mount
(``imu_mount_rpy_deg``). Quaternions are (w, x, y, z), unit, w ≥ 0, and rotate the second frame
named into the first (world ← sensor: a vector's sensor coordinates to its world coordinates).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from spm_console.description import names
from spm_console.description.mjcf import AsBuiltBody
from spm_console.devices.emulator.bno055 import ImuTruth

F = NDArray[np.float64]
Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

_SENSOR_OFF = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)


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


def _quat_wxyz(R: F) -> F:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, float).reshape(9))
    return q


class AsBuiltParts:
    """The IMU's sensors and the jig of one MuJoCo model built with an :class:`AsBuiltBody`."""

    def __init__(self, mj: mujoco.MjModel, body: AsBuiltBody) -> None:
        self.body = body
        self.base_quat = _quat_wxyz(body.base_rotation)
        """World ← base (w, x, y, z)."""
        self._acc = int(mj.sensor(names.IMU_ACCELEROMETER).adr[0])
        self._gyro = int(mj.sensor(names.IMU_GYRO).adr[0])
        self._quat = int(mj.sensor(names.IMU_FRAMEQUAT).adr[0])
        self._platform = int(mj.body(names.PLATFORM).id)
        self._jigs = [int(mj.equality(names.jig_equality(i)).id) for i in range(3)]
        mj.opt.disableflags |= _SENSOR_OFF  # computed on demand (read)

    # --- the jig ---------------------------------------------------------------------------

    def held(self, data: mujoco.MjData) -> bool:
        """Whether the jig holds the output shafts."""
        return bool(data.eq_active[self._jigs].any())

    def hold(self, data: mujoco.MjData) -> None:
        """Fit the jig: each output shaft held at home (θ = θ_home) from the next step."""
        data.eq_active[self._jigs] = 1

    def release(self, data: mujoco.MjData) -> None:
        """Take the jig off."""
        data.eq_active[self._jigs] = 0

    # --- the IMU ---------------------------------------------------------------------------

    def read(self, mj: mujoco.MjModel, data: mujoco.MjData, t: float, theta_rad: F) -> WristTruth:
        """The truth at the state reached (time ``t``, s; joint angles θ, rad)."""
        flags = mj.opt.disableflags
        mj.opt.disableflags = flags & ~_SENSOR_OFF
        try:
            mujoco.mj_forward(mj, data)
        finally:
            mj.opt.disableflags = flags
        s = data.sensordata
        sensor = canonical(quat_multiply(self.base_quat, s[self._quat:self._quat + 4]))
        platform = canonical(quat_multiply(self.base_quat, data.xquat[self._platform]))
        imu = ImuTruth(quat_matrix(sensor), np.array(s[self._acc:self._acc + 3], float),
                       np.array(s[self._gyro:self._gyro + 3], float), float(t))
        th = [math.degrees(float(x)) for x in theta_rad]
        return WristTruth(float(t), imu, sensor, platform, (th[0], th[1], th[2]))
