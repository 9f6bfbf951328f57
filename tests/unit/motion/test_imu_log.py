"""A run's IMU readings (spm_console.motion.logs.imu_log): imu.csv as written and read back,
and the ``/imu`` topic of the run's MCAP as sensor_msgs/msg/Imu, decoded by mcap_ros2 (an
independent reader of the CDR), in ROS units (REP 145)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from spm_console.config.schema import Profile
from spm_console.devices.imu.bno055 import ImuSample
from spm_console.devices.imu.bno055_registers import OprMode
from spm_console.motion.logs import mcap_log
from spm_console.motion.logs.imu_log import IMU_CSV, ImuCsv, read_imu
from spm_console.motion.logs.runlog import RunLog


def _sample(t: float, fused: bool = True) -> ImuSample:
    return ImuSample(t_s=t, mode=OprMode.IMU, accel_mps2=(0.1, -0.2, 9.8),
                     gyro_dps=(90.0, 0.0, -45.0), mag_ut=None,
                     quat_wxyz=(math.cos(0.1), math.sin(0.1), 0.0, 0.0) if fused else None,
                     euler_deg=None, gravity_mps2=(0.0, 0.0, 9.8) if fused else None,
                     linear_accel_mps2=None)


def test_readings_round_trip_and_a_broken_row_is_skipped(tmp_path: Path) -> None:
    log = ImuCsv(tmp_path, t0_s=100.0)
    log.add(_sample(100.5))
    log.add(_sample(100.75, fused=False))
    log.close()
    with (tmp_path / IMU_CSV).open("a") as fh:
        fh.write("1.0,0.5,nan,0,0,0,0,9.8,0,0,0,0,0,9.8\n2.0,1,2\n")  # NaN; a killed writer
    rows = read_imu(tmp_path)
    assert [r.t_s for r in rows] == pytest.approx([0.5, 0.75, 1.0])
    assert rows[0].quat_wxyz == pytest.approx((math.cos(0.1), math.sin(0.1), 0.0, 0.0))
    assert rows[1].quat_wxyz is None and rows[1].gyro_dps == (90.0, 0.0, -45.0)
    assert rows[2].quat_wxyz is None  # not finite: not a rotation
    assert read_imu(tmp_path / "none") == []


def test_the_run_mcap_carries_the_imu(tmp_path: Path, agile: Profile) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    run = RunLog.create("commission", agile.name, agile.digest(), [], root=tmp_path)
    imu = ImuCsv(run.path, t0_s=0.0)
    imu.add(_sample(0.25))
    imu.add(_sample(0.5, fused=False))
    imu.close()
    run.finish("completed", 0, "", {})  # no executor sample: the CSV has its header only
    out = mcap_log.write_run_mcap(run.path, agile).path
    with out.open("rb") as fh:
        msgs = [(ch.topic, schema.name, m) for schema, ch, _r, m in
                make_reader(fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages()
                if ch.topic == "/imu"]
    assert [s for _t, s, _m in msgs] == ["sensor_msgs/msg/Imu"] * 2
    first, second = msgs[0][2], msgs[1][2]
    assert first.header.frame_id == "imu"
    assert (first.orientation.w, first.orientation.x) == pytest.approx((math.cos(0.1),
                                                                         math.sin(0.1)))
    assert first.angular_velocity.x == pytest.approx(math.pi / 2)  # 90 °/s in rad/s
    assert first.linear_acceleration.z == pytest.approx(9.8)
    assert list(first.orientation_covariance) == [0.0] * 9  # unknown
    assert second.orientation_covariance[0] == -1.0  # no orientation (REP 145)
    assert (second.header.stamp.sec, second.header.stamp.nanosec) != (
        first.header.stamp.sec, first.header.stamp.nanosec)
