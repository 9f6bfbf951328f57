"""A run's IMU readings: ``imu.csv`` beside ``samples.csv``, and the ``/imu`` topic of its MCAP.

Commissioning reads a BNO055 on the platform (:mod:`spm_console.devices.imu.bno055`); every
reading it takes is one row, written as it comes and flushed at once (a killed process leaves
every row but a partial last one). Columns: ``t`` (s from the run's start), the fused
orientation ``qw qx qy qz`` (unit quaternion, world ← sensor, a relative heading in the IMU
fusion mode), the accelerometer ``ax ay az`` (m/s², specific force: +9.81 up at rest), the
gyroscope ``gx gy gz`` (deg/s) and the fusion's gravity ``grx gry grz`` (m/s²), each in the
sensor's axes; a cell the operating mode does not give is empty.

In the MCAP (:mod:`spm_console.motion.logs.mcap_log`) each row is one sensor_msgs/msg/Imu on
``/imu``, frame ``imu``, rad/s and m/s² as ROS has them (REP 145): covariances are unknown
(zeros), and a row without orientation has ``orientation_covariance[0] = -1``.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from spm_console.devices.imu.bno055 import ImuSample
from spm_console.safe_io import MB, read_capped

IMU_CSV = "imu.csv"
IMU_COLUMNS = ("t", "qw", "qx", "qy", "qz", "ax", "ay", "az", "gx", "gy", "gz",
               "grx", "gry", "grz")
#: Largest imu.csv read back, bytes (commissioning writes about 100 kB).
MAX_IMU_BYTES = 64 * MB

_VEC3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
_QUAT = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
_RULE = "=" * 80
IMU_MSGDEF = "\n".join([
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
    "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
    "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
    "float64[9] linear_acceleration_covariance\n",
    f"{_RULE}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n",
    f"{_RULE}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n",
    f"{_RULE}\n{_QUAT}", f"{_RULE}\n{_VEC3}"])


def _cells(values: Any, n: int) -> list[str]:
    return [""] * n if values is None else [repr(float(x)) for x in values]


class ImuCsv:
    """Writer of a run folder's ``imu.csv``."""

    def __init__(self, run_dir: Path, t0_s: float) -> None:
        self._fh: IO[str] = (Path(run_dir) / IMU_CSV).open("w", newline="")
        self._csv = csv.writer(self._fh)
        self._csv.writerow(IMU_COLUMNS)
        self._fh.flush()
        self.t0_s = t0_s
        """The run's start on ``time.monotonic()``'s clock (the samples' ``t_s``)."""
        self.rows = 0

    def add(self, s: ImuSample) -> None:
        """One reading, flushed at once."""
        self._csv.writerow([f"{s.t_s - self.t0_s:.6f}", *_cells(s.quat_wxyz, 4),
                            *_cells(s.accel_mps2, 3), *_cells(s.gyro_dps, 3),
                            *_cells(s.gravity_mps2, 3)])
        self._fh.flush()
        self.rows += 1

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()


@dataclass(frozen=True)
class ImuRow:
    """One reading read back (None: not given)."""

    t_s: float
    quat_wxyz: tuple[float, float, float, float] | None
    accel_mps2: tuple[float, float, float] | None
    gyro_dps: tuple[float, float, float] | None


def _vec(cells: list[str]) -> tuple[float, ...] | None:
    try:
        values = tuple(float(c) for c in cells)
    except ValueError:
        return None
    return values if all(math.isfinite(v) for v in values) else None


def read_imu(run_dir: Path) -> list[ImuRow]:
    """The rows of ``run_dir``'s imu.csv (none when it has none); a malformed row (a killed
    writer's last line, an edited cell) is skipped."""
    path = Path(run_dir) / IMU_CSV
    if not path.exists():
        return []
    text = read_capped(path, MAX_IMU_BYTES).decode("utf-8", "replace")
    rows = []
    for cells in list(csv.reader(text.splitlines()))[1:]:
        if len(cells) != len(IMU_COLUMNS):
            continue
        t = _vec(cells[:1])
        if t is None:
            continue
        q, a, g = _vec(cells[1:5]), _vec(cells[5:8]), _vec(cells[8:11])
        rows.append(ImuRow(t[0], q if q is None else (q[0], q[1], q[2], q[3]),
                           a if a is None else (a[0], a[1], a[2]),
                           g if g is None else (g[0], g[1], g[2])))
    return rows


def imu_message(stamp: dict[str, object], row: ImuRow) -> dict[str, object]:
    """``row`` as a sensor_msgs/msg/Imu (``stamp``: the header, frame ``imu``)."""
    zeros = [0.0] * 9
    rad = math.pi / 180.0
    q = row.quat_wxyz
    g = row.gyro_dps
    a = row.accel_mps2
    return {
        "header": stamp,
        "orientation": ({"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0} if q is None
                        else {"x": q[1], "y": q[2], "z": q[3], "w": q[0]}),
        "orientation_covariance": [-1.0, *zeros[1:]] if q is None else zeros,
        "angular_velocity": ({"x": 0.0, "y": 0.0, "z": 0.0} if g is None
                             else {"x": g[0] * rad, "y": g[1] * rad, "z": g[2] * rad}),
        "angular_velocity_covariance": [-1.0, *zeros[1:]] if g is None else zeros,
        "linear_acceleration": ({"x": 0.0, "y": 0.0, "z": 0.0} if a is None
                                else {"x": a[0], "y": a[1], "z": a[2]}),
        "linear_acceleration_covariance": [-1.0, *zeros[1:]] if a is None else zeros,
    }
