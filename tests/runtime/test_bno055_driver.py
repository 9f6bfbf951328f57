"""The BNO055 driver over a real pseudo-terminal: against the emulated chip, and against ports
where no BNO055 answers (a silent one, one that answers another chip's id, one that answers
bytes of another protocol)."""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
import tty
from collections.abc import Iterator

import numpy as np
import pytest
import serial

from spm_console.core.kinematics.rotations import rpy_matrix
from spm_console.devices.emulator.bno055 import EmulatedBno055, ImuTruth
from spm_console.devices.imu.bno055 import Bno055
from spm_console.devices.imu.bno055_registers import OprMode, Reg
from spm_console.errors import BadInputError, ExitCode, ImuError
from spm_console.system.realtime import EMULATOR_PRIORITY, HELPER_PRIORITY

TILTED = ImuTruth.at_rest_rpy(10.0, -20.0, 30.0)
G_SENSOR = TILTED.rotation.T @ [0.0, 0.0, 9.80665]


@pytest.fixture
def em() -> Iterator[EmulatedBno055]:
    with EmulatedBno055(lambda: TILTED, seed=11) as chip:
        yield chip
        assert chip.error is None


@contextlib.contextmanager
def fake_device(*answers: str) -> Iterator[str]:
    """A raw pty whose far end answers each burst of bytes with the next of ``answers`` (hex),
    the last one again once they are used up; never with no answers."""
    replies = [bytes.fromhex(a) for a in answers]
    master, slave = os.openpty()
    tty.setraw(slave)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            ready, _, _ = select.select([master], [], [], 0.02)
            if ready:
                os.read(master, 4096)
                if replies:
                    os.write(master, replies.pop(0) if len(replies) > 1 else replies[0])

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield os.ttyname(slave)
    finally:
        stop.set()
        thread.join(1.0)
        os.close(master)
        os.close(slave)


def test_the_serving_thread_runs_below_the_emulated_servos_and_above_normal_threads(
        em: EmulatedBno055) -> None:
    """Its truth() steps the emulated wrist under the servos' lock: preempted while holding
    it, it would hold up the servos' SCHED_FIFO thread."""
    t_end = time.monotonic() + 2.0
    while em.realtime.detail == "not serving yet" and time.monotonic() < t_end:
        time.sleep(0.01)
    (thread,) = [t for t in threading.enumerate() if t.name == "spm-bno055" and t.is_alive()]
    assert thread.native_id is not None
    if em.realtime.policy == "SCHED_FIFO":
        assert os.sched_getscheduler(thread.native_id) == os.SCHED_FIFO
        assert os.sched_getparam(thread.native_id).sched_priority == HELPER_PRIORITY
        assert 0 < HELPER_PRIORITY < EMULATOR_PRIORITY
    else:  # not permitted here: it says why, and the thread runs at the priority it got
        assert em.realtime.detail and "not serving yet" not in em.realtime.detail
        assert os.sched_getscheduler(thread.native_id) == os.SCHED_OTHER


def test_open_reads_the_chip_ids_and_the_units(em: EmulatedBno055) -> None:
    with Bno055.open(em.port) as imu:
        assert imu.mode == OprMode.CONFIG
        assert imu.units.accel_lsb_per_mps2 == 100 and imu.units.gyro_lsb_per_dps == 16
        assert imu.read(Reg.CHIP_ID, 4) == bytes.fromhex("A0 FB 32 0F")


def test_modes_and_a_sample_that_sees_gravity(em: EmulatedBno055) -> None:
    with Bno055.open(em.port) as imu:
        with pytest.raises(ImuError, match="CONFIGMODE"):
            imu.read_sample()
        imu.set_mode(OprMode.IMU)
        assert imu.mode == OprMode.IMU and em.chip.mode == OprMode.IMU
        a, b = imu.read_sample(), imu.read_sample()
        assert b.t_s > a.t_s
        assert a.mag_ut is None and a.accel_mps2 is not None and a.gyro_dps is not None
        assert a.gravity_mps2 is not None and a.quat_wxyz is not None
        # the fusion's gravity: 0.05° of orientation noise and 0.01 m/s² LSB
        assert np.asarray(a.gravity_mps2) == pytest.approx(G_SENSOR, abs=0.05)
        # the accelerometer: 0.0116 m/s² of noise, 5 σ
        assert np.asarray(a.accel_mps2) == pytest.approx(G_SENSOR, abs=0.06)
        assert np.asarray(a.gyro_dps) == pytest.approx([0, 0, 0], abs=0.5)
        # IMU mode: relative heading, zero at the mode's entry; roll and pitch absolute
        assert _rotation(a.quat_wxyz) == pytest.approx(rpy_matrix(*np.radians([10, -20, 0])),
                                                       abs=0.005)
        imu.set_mode(OprMode.NDOF)  # through CONFIGMODE
        s = imu.read_sample()
        assert s.mag_ut is not None and s.quat_wxyz is not None
        assert _rotation(s.quat_wxyz) == pytest.approx(TILTED.rotation, abs=0.005)
        imu.set_mode(OprMode.CONFIG)
        assert em.chip.mode == OprMode.CONFIG


def test_the_driver_waits_out_a_switching_chip(em: EmulatedBno055) -> None:
    """A read while the chip switches (19 ms into CONFIGMODE) may get READ_FAIL: the driver
    tries again and gets the mode."""
    with Bno055.open(em.port) as imu:
        imu.set_mode(OprMode.ACCGYRO)
        imu.write(Reg.OPR_MODE, bytes((OprMode.CONFIG,)))
        assert imu.read(Reg.OPR_MODE, 1) == bytes((OprMode.CONFIG,))


def test_busy_statuses_are_tried_again() -> None:
    with fake_device("EE 07", "BB 01 A0", "BB 03 80 00 0C") as port, Bno055.open(port) as imu:
        assert imu.mode == OprMode.NDOF  # as OPR_MODE read: the driver keeps what it finds


def test_a_chip_busy_every_time() -> None:
    with fake_device("EE 07") as port, pytest.raises(
            ImuError, match=r"failed every read of CHIP_ID \(3 tries\): status 0x07 BUS_OVER_RUN"):
        Bno055.open(port)


def test_refused_and_malformed_requests_are_typed(em: EmulatedBno055) -> None:
    with Bno055.open(em.port) as imu:
        with pytest.raises(ImuError, match="0x05 WRITE_DISABLED"):
            imu.write(Reg.CHIP_ID, b"\x00")
        with pytest.raises(BadInputError):
            imu.read(0x7F, 2)
        with pytest.raises(BadInputError):
            imu.set_mode(0x0D)
    with pytest.raises(BadInputError):
        Bno055.open(em.port, timeout_s=5.0)


def test_frame_errors_on_the_wire(em: EmulatedBno055) -> None:
    with serial.Serial(em.port, 115200, timeout=0.5) as raw:
        raw.write(b"\xaa\x01")  # then silence: the chip gives up on the frame
        assert raw.read(2) == b"\xee\x0a"
        raw.write(b"\x55")
        assert raw.read(2) == b"\xee\x06"
        time.sleep(0.05)  # the line quiet again
        raw.write(bytes.fromhex("AA 01 00 00"))
        assert raw.read(2) == b"\xee\x09"
        time.sleep(0.05)
        raw.write(bytes.fromhex("AA 01 00 01"))
        assert raw.read(3) == b"\xbb\x01\xa0"


def test_a_port_where_nothing_answers() -> None:
    with fake_device() as port:
        t0 = time.monotonic()
        with pytest.raises(ImuError, match=f"no reply from an IMU on {port} within 20 ms") as exc:
            Bno055.open(port, timeout_s=0.02, attempts=2)
        assert time.monotonic() - t0 < 1.0  # 2 × 20 ms, and a 30 ms quiet line between
        assert exc.value.exit_code == ExitCode.BUS_ERROR


def test_a_port_that_answers_another_chip_id() -> None:
    with fake_device("BB 01 42") as port, \
            pytest.raises(ImuError, match=r"not a BNO055 on .*: CHIP_ID 0x42"):
        Bno055.open(port)


def test_a_port_that_answers_another_protocol() -> None:
    # a Dynamixel status packet (protocol 2.0)
    with fake_device("FF FF FD 00 01 04 00 55 00 A1 0C") as port, \
            pytest.raises(ImuError, match=r"not a BNO055 on .*: it answered ff ff fd 00"):
        Bno055.open(port, attempts=2)


def test_a_reply_of_the_wrong_length_is_named_so() -> None:
    """A reply that starts as a BNO055's (0xBB) but has the wrong length is not told "a
    BNO055 replies 0xBB or 0xEE" (which it did)."""
    with fake_device("BB FF 01 02 03") as port, \
            pytest.raises(ImuError, match=r"it answered bb ff 01 02 03: a read reply of the "
                                          r"wrong length") as exc:
        Bno055.open(port, attempts=1)
    assert "replies 0xBB or 0xEE" not in exc.value.message


def test_a_port_that_does_not_exist() -> None:
    with pytest.raises(ImuError, match="cannot open the IMU's serial port /dev/nonexistent-imu"):
        Bno055.open("/dev/nonexistent-imu")


def _rotation(q: tuple[float, float, float, float]) -> np.ndarray:
    w, x, y, z = np.asarray(q) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
