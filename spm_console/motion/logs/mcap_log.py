"""A run log as MCAP with ROS 2 messages, beside its CSV: Foxglove and PlotJuggler open it;
with ``metadata.yaml`` beside it the run folder is a rosbag2 bag (``ros2 bag info RUN/``,
``ros2 bag play RUN/``; :mod:`spm_console.motion.logs.bag`), each channel carrying the QoS
its topic is offered with.

Written from the finished run's files (:func:`write_mcap`), never from inside the servo loop.
Topics (CDR-encoded ROS 2 messages; angles in rad, as ROS has them; each message stamped with
the run's wall-clock start plus the sample's time):

* ``/joint_states`` (sensor_msgs/msg/JointState): every joint of the URDF that ``spm-console
  export urdf`` writes, from the measured θ and the unique FK along the run (names of
  :mod:`spm_console.description.names`, legs 1..3): ``leg1_motor_joint`` … (θ − θ_home),
  ``leg1_distal_joint`` …, ``leg1_platform_joint`` …; robot_state_publisher and Foxglove draw
  the whole wrist from it;
* ``/spm/reference``, ``/spm/measured``, ``/spm/model``, ``/spm/error`` (JointState, joints
  ``joint1..3``, the servos as the console and the CSV number them): θ*, the measured θ with
  the Kalman velocity, the model's θ and velocity, measured − model (θ as the servos have it,
  not from home: not the URDF's joints, hence names of their own);
* ``/spm/platform`` (geometry_msgs/msg/QuaternionStamped) and ``/tf`` (tf2_msgs/msg/TFMessage,
  base_link → ``platform_fk``): the platform's orientation from the FK of the measured θ (a frame
  of its own: robot_state_publisher, fed the URDF and ``/joint_states``, publishes the URDF's
  ``platform`` link under ``leg1_distal``, and a frame has one parent);
* ``/spm/events`` (std_msgs/msg/String): each event as one JSON object, so every channel stays
  CDR and ``ros2 bag play`` can replay the whole file;
* ``/robot_description`` (std_msgs/msg/String, once at the start): the URDF;
* ``/imu`` (sensor_msgs/msg/Imu), when the run read an IMU (commissioning): each reading of
  its ``imu.csv`` (:mod:`spm_console.motion.logs.imu_log`), frame ``imu``.

A row whose read failed (no measured θ) publishes references and the model only. A measured θ
that is no pose of this wrist (more than :data:`LIMIT_SLACK_DEG` beyond the profile's servo
limits: a corrupt or hand-edited log) is published on ``/spm/measured`` as logged, but gets no
FK: no ``/joint_states``, ``/spm/platform`` or ``/tf`` for that row. That also bounds the FK's
work: every continuation it runs stays inside the servo range.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from mcap.records import Schema
from mcap_ros2.writer import Writer
from numpy.typing import NDArray

from spm_console.config.models import model_of, servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.core.kinematics.joint_states import joint_states
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.rotations import matrix_quaternion
from spm_console.description.for_profile import robot_description
from spm_console.description.names import JOINT_STATE_NAMES
from spm_console.jsonutil import to_jsonable
from spm_console.motion.logs.bag import BagContents, offered_qos, write_metadata
from spm_console.motion.logs.imu_log import IMU_MSGDEF, ImuRow, imu_message, read_imu
from spm_console.motion.logs.runlog import RunData, append_events, load_run
from spm_console.safe_io import atomic_temp
from spm_console.system.realtime import normal_priority

F = NDArray[np.float64]

MCAP_NAME = "run.mcap"
#: Longest run (rows) whose MCAP is written as it ends: 5 minutes at Ts = 20 ms, about 6 s of
#: writing on a 2-core machine (0.4 ms per row); a longer one is deferred to ``logs export``.
MAX_ROWS_AT_FINISH = 15_000

#: How far beyond the servo limits a measured θ is still a pose of the wrist, deg: a run stopped
#: for leaving the limits (exit 25) logs the sample that left them, up to a period's move at
#: the MX-106's rated 270 °/s past the limit (5.4° at Ts = 20 ms), and then some.
LIMIT_SLACK_DEG = 10.0

_RULE = "=" * 80
_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_QUAT = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
_VEC3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"


def _msgdef(main: str, *deps: str) -> str:
    return "\n".join([main, *(f"{_RULE}\n{d}" for d in deps)])


JOINT_STATE = _msgdef("std_msgs/Header header\nstring[] name\nfloat64[] position\n"
                      "float64[] velocity\nfloat64[] effort\n", _HEADER, _TIME)
QUATERNION_STAMPED = _msgdef("std_msgs/Header header\ngeometry_msgs/Quaternion quaternion\n",
                             _HEADER, _TIME, _QUAT)
TF_MESSAGE = _msgdef(
    "geometry_msgs/TransformStamped[] transforms\n",
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/Transform transform\n",
    _HEADER, _TIME,
    "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\n"
    "geometry_msgs/Quaternion rotation\n",
    _VEC3, _QUAT)
STRING = "string data\n"

MOTORS = ("joint1", "joint2", "joint3")
URDF_JOINTS = JOINT_STATE_NAMES


def start_ns(meta: Mapping[str, object]) -> int:
    """The run's wall-clock start, ns since the epoch (0 when meta.json does not say)."""
    try:
        return int(dt.datetime.fromisoformat(str(meta["start_time"])).timestamp() * 1e9)
    except (KeyError, TypeError, ValueError):
        return 0


def _stamp(ns: int, frame: str = "") -> dict[str, Any]:
    return {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000},
            "frame_id": frame}


def _joints(ns: int, names: tuple[str, ...], pos: F, vel: F | None = None) -> dict[str, Any]:
    return {"header": _stamp(ns), "name": list(names), "position": [float(x) for x in pos],
            "velocity": [] if vel is None else [float(x) for x in vel], "effort": []}


def platform_rotations(model: SpmModel, theta: F) -> F:
    """The platform's rotation at each θ row (rad, (N, 3)) by the unique FK, NaN where it has
    none (a row not finite has none): all rows tracked from home at once; a row refused there
    (a singularity on the straight path) is tracked from the row before it, as the wrist went.
    The rows should lie in the servo range (:func:`beyond_limits`): the continuation's work
    grows with the distance it follows."""
    rots = np.full((len(theta), 3, 3), np.nan)
    ok = np.isfinite(theta).all(axis=1)
    if not ok.any():
        return rots
    idx = np.flatnonzero(ok)
    for k, res in zip(idx, model.track_batch(theta[idx]), strict=True):
        if res.ok and res.pose is not None:
            rots[k] = res.pose.R
    prev: int | None = None
    for k in idx:
        if np.isnan(rots[k, 0, 0]) and prev is not None:
            res = model.track(theta[k], theta[prev], rots[prev])
            if res.ok and res.pose is not None:
                rots[k] = res.pose.R
        if not np.isnan(rots[k, 0, 0]):
            prev = int(k)
    return rots


@dataclass(frozen=True)
class _Rows:
    """The run's rows as published (rad, rad/s; ns stamps)."""

    stamp_ns: list[int]
    ref: F
    meas: F
    pred: F
    vel: F
    pred_vel: F
    posed: NDArray[np.bool_]
    """Rows with a measurement and a pose from the FK."""
    joints: F
    """Every URDF joint (N, 9): motors, distal, platform."""
    quats: F
    """The platform's orientation (N, 4), x y z w."""


def _seconds(x: object) -> float:
    """A time in seconds from a log (0 when it is missing or not a finite number)."""
    try:
        v = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return 0.0
    return v if math.isfinite(v) else 0.0


def beyond_limits(theta_deg: F, limits_deg: tuple[F, F]) -> NDArray[np.bool_]:
    """Rows (N, 3) whose θ is finite but more than :data:`LIMIT_SLACK_DEG` beyond the servo
    limits (lowest, highest per joint) in some joint: no pose this wrist reached."""
    lo, hi = limits_deg
    with np.errstate(invalid="ignore"):
        out = ((theta_deg < lo - LIMIT_SLACK_DEG) | (theta_deg > hi + LIMIT_SLACK_DEG)).any(1)
    return np.asarray(out & np.isfinite(theta_deg).all(1))


def _rows(run: RunData, model: SpmModel, limits_deg: tuple[F, F], t0: int) -> _Rows:
    rad = math.pi / 180.0
    t = run.columns.get("t", np.zeros(run.rows))
    meas = run.vec("meas") * rad
    posable = np.where(beyond_limits(run.vec("meas"), limits_deg)[:, None], np.nan, meas)
    rots = platform_rotations(model, posable)
    posed = ~np.isnan(rots[:, 0, 0])
    rots = np.where(posed[:, None, None], rots, np.eye(3))
    js = joint_states(model, np.where(posed[:, None], meas, model.theta_home), rots)
    return _Rows([t0 + round(_seconds(x) * 1e9) for x in t], run.vec("ref") * rad, meas,
                 run.vec("pred") * rad, run.vec("vel") * rad, run.vec("pred_vel") * rad, posed,
                 np.hstack([js.motor, js.distal, js.platform]),
                 matrix_quaternion(rots))


class _BagWriter(Writer):
    """mcap_ros2's writer, each channel carrying the QoS its topic is offered with (the channel
    metadata rosbag2's MCAP storage reads), and counting what it writes for ``metadata.yaml``.
    mcap_ros2 registers a topic's channel on its first message, without metadata: the channel
    is registered here first, in the writer's own table (``_writer``, ``_channel_ids``)."""

    def __init__(self, output: IO[bytes]) -> None:
        super().__init__(output)
        self.contents = BagContents()

    def write_message(self, topic: str, schema: Schema, message: Any, log_time: int | None = None,
                      publish_time: int | None = None, sequence: int = 0) -> None:
        if log_time is None:
            raise ValueError(f"{topic}: every message of a run log has its time")
        if topic not in self._channel_ids:
            self._channel_ids[topic] = self._writer.register_channel(
                topic=topic, message_encoding="cdr", schema_id=schema.id,
                metadata={"offered_qos_profiles": offered_qos(topic)})
        super().write_message(topic, schema, message, log_time, publish_time, sequence)
        self.contents.add(topic, schema.name, log_time)


@dataclass(frozen=True)
class McapWritten:
    """What :func:`write_run_mcap` wrote."""

    path: Path
    messages: int
    beyond_limits: int
    """Rows whose measured θ lies beyond the servo limits (:func:`beyond_limits`): no pose."""
    first_beyond: int | None
    """The first of them, counted from 1 as the CSV's samples (None when there is none)."""


def write_mcap(run: RunData, model: SpmModel, limits_deg: tuple[F, F], urdf: str,
               out: Path, imu: Sequence[ImuRow] = ()) -> BagContents:
    """Write ``run`` (and its IMU readings) as MCAP to ``out`` (replaced whole, never left
    half-written); what it holds (topics, message counts, time span)."""
    t0 = start_ns(run.meta)
    rows = _rows(run, model, limits_deg, t0)
    fd, tmp = atomic_temp(out)
    try:
        with os.fdopen(fd, "wb") as fh:
            contents = _write(fh, run, rows, urdf, t0, imu)
        tmp.replace(out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return contents


def _write(fh: IO[bytes], run: RunData, rows: _Rows, urdf: str, t0: int,
           imu: Sequence[ImuRow]) -> BagContents:
    w = _BagWriter(fh)
    js_schema = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE)
    q_schema = w.register_msgdef("geometry_msgs/msg/QuaternionStamped", QUATERNION_STAMPED)
    tf_schema = w.register_msgdef("tf2_msgs/msg/TFMessage", TF_MESSAGE)
    str_schema = w.register_msgdef("std_msgs/msg/String", STRING)
    w.add_metadata("spm_console", {k: str(run.meta.get(k, "")) for k in
                                   ("run", "kind", "outcome", "exit_code", "start_time")}
                   | {"profile": json.dumps(run.meta.get("profile", {}))})
    w.write_message("/robot_description", str_schema, {"data": urdf}, t0, t0)
    for k, ns in enumerate(rows.stamp_ns):
        msgs: list[tuple[str, Any, dict[str, Any]]] = [
            ("/spm/reference", js_schema, _joints(ns, MOTORS, rows.ref[k])),
            ("/spm/model", js_schema, _joints(ns, MOTORS, rows.pred[k], rows.pred_vel[k])),
        ]
        if np.isfinite(rows.meas[k]).all():
            msgs += [("/spm/measured", js_schema, _joints(ns, MOTORS, rows.meas[k], rows.vel[k])),
                     ("/spm/error", js_schema,
                      _joints(ns, MOTORS, rows.meas[k] - rows.pred[k]))]
            if rows.posed[k]:
                x, y, z, qw = rows.quats[k]
                quat = {"x": float(x), "y": float(y), "z": float(z), "w": float(qw)}
                tf = {"header": _stamp(ns, "base_link"), "child_frame_id": "platform_fk",
                      "transform": {"translation": {"x": 0.0, "y": 0.0, "z": 0.0},
                                    "rotation": quat}}
                msgs += [("/joint_states", js_schema, _joints(ns, URDF_JOINTS, rows.joints[k])),
                         ("/spm/platform", q_schema,
                          {"header": _stamp(ns, "base_link"), "quaternion": quat}),
                         ("/tf", tf_schema, {"transforms": [tf]})]
        for topic, schema, msg in msgs:
            w.write_message(topic, schema, msg, ns, ns, sequence=k)
    for ev in run.events:
        ns = t0 + round(_seconds(ev.get("t", 0.0)) * 1e9)
        w.write_message("/spm/events", str_schema, {"data": json.dumps(to_jsonable(ev))}, ns, ns)
    if imu:
        imu_schema = w.register_msgdef("sensor_msgs/msg/Imu", IMU_MSGDEF)
        for k, row in enumerate(imu):
            ns = t0 + round(row.t_s * 1e9)
            w.write_message("/imu", imu_schema, imu_message(_stamp(ns, "imu"), row), ns, ns,
                            sequence=k)
    w.finish()  # type: ignore[no-untyped-call]  # mcap_ros2 leaves it unannotated
    return w.contents


def write_bag(run_dir: Path, run: RunData, profile: Profile) -> BagContents:
    """Write the run folder's ``run.mcap`` and then its ``metadata.yaml``: the folder is a
    rosbag2 bag (:mod:`spm_console.motion.logs.bag`); what the MCAP holds."""
    out = Path(run_dir) / MCAP_NAME
    contents = write_mcap(run, model_of(profile), servo_limits_deg(profile),
                          robot_description(profile, "urdf"), out, read_imu(run_dir))
    write_metadata(out, contents)
    return contents


def write_run_mcap(run_dir: Path, profile: Profile, out: Path | None = None) -> McapWritten:
    """Write the run folder's MCAP from its files, with ``profile``'s wrist (the one the run was
    logged with): ``run.mcap`` with ``metadata.yaml`` in the folder (a rosbag2 bag), or the
    MCAP alone to ``out`` elsewhere (a bag is a folder; no ``metadata.yaml`` is put beside a
    file of another name)."""
    default = Path(run_dir) / MCAP_NAME
    run = load_run(run_dir)
    limits = servo_limits_deg(profile)
    if out is None or Path(out).resolve() == default.resolve():
        target, contents = default, write_bag(run_dir, run, profile)
    else:
        target = Path(out)
        contents = write_mcap(run, model_of(profile), limits, robot_description(profile, "urdf"),
                              target, read_imu(run_dir))
    beyond = np.flatnonzero(beyond_limits(run.vec("meas"), limits))
    return McapWritten(target, contents.message_count, len(beyond),
                       int(beyond[0]) + 1 if len(beyond) else None)


def mcap_beside(profile: Profile) -> Callable[[Path], object]:
    """A :attr:`RunLog.on_finish` that writes the run's MCAP beside its CSV, at normal priority
    whatever thread finishes the log (a stopped servo loop's is real-time). A run longer than
    :data:`MAX_ROWS_AT_FINISH` rows gets an ``mcap_deferred`` event instead (and no
    ``metadata.yaml``): writing it would
    hold the run's result back for seconds; ``logs export --mcap`` writes it."""

    def write(run_dir: Path) -> None:
        normal_priority()
        run = load_run(run_dir)
        if run.rows > MAX_ROWS_AT_FINISH:
            t = run.columns.get("t")
            append_events(run_dir, [{
                "t": _seconds(t[-1]) if t is not None and len(t) else 0.0,
                "event": "mcap_deferred", "rows": run.rows,
                "message": f"{run.rows} rows: run.mcap not written at the end of the run; "
                           f"`spm-console logs export --mcap {run_dir.name}` writes it"}])
            return
        write_bag(run_dir, run, profile)

    return write
