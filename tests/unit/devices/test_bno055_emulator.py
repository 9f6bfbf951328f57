"""The emulated BNO055 without a pty: its UART receiver and chip on a clock of the test's own
(Bosch BST-BNO055-DS000: §4.7 frames and statuses, Table 3-6 switching times, §3.3.1
CONFIGMODE, §3.4 axis remap, §3.6.1 units; noise from the datasheet's densities)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spm_console.core.kinematics.rotations import rpy_matrix
from spm_console.devices.emulator.bno055 import RESET_S, Bno055Chip, ImuTruth
from spm_console.devices.emulator.bno055_uart import CHAR_TIMEOUT_S, Bno055Uart
from spm_console.devices.imu import bno055_protocol as bp
from spm_console.devices.imu import bno055_registers as br
from spm_console.devices.imu.bno055_protocol import Status
from spm_console.devices.imu.bno055_registers import OprMode, Reg


def h(text: str) -> bytes:
    return bytes.fromhex(text)


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class Rig:
    """A chip, its receiver and the clock they share."""

    def __init__(self, truth: ImuTruth | None = None, seed: int = 0, **chip: object) -> None:
        self.truth = truth or ImuTruth.at_rest(np.eye(3))
        self.clock = Clock()
        self.chip = Bno055Chip(lambda: self.truth, seed, self.clock, **chip)  # type: ignore[arg-type]
        self.uart = Bno055Uart(self.chip, self.clock)

    def ask(self, frame: bytes) -> bytes:
        replies = self.uart.feed(frame)
        assert len(replies) == 1, replies
        return replies[0]

    def read(self, reg: int, n: int) -> bytes:
        reply = self.ask(bp.read_frame(reg, n))
        assert reply[:2] == bytes((0xBB, n)), reply.hex(" ")
        return reply[2:]

    def write(self, reg: int, data: bytes) -> int:
        reply = self.ask(bp.write_frame(reg, data))
        assert reply[0] == 0xEE
        return reply[1]

    def enter(self, mode: OprMode) -> None:
        before = self.chip.mode
        assert self.write(Reg.OPR_MODE, bytes((mode,))) == Status.WRITE_SUCCESS
        self.clock.t += br.switch_time_s(before, mode)

    def sample(self, units: int = 0) -> bp.DataBlock:
        return bp.decode_data(self.read(br.DATA_START, br.DATA_LEN), br.Units.of(units))

    def next_sample(self) -> bp.DataBlock:
        self.clock.t += 0.01
        return self.sample()


TILTED = ImuTruth.at_rest_rpy(10.0, -20.0, 30.0)


def test_reset_registers_and_config_mode_outputs_zero() -> None:
    rig = Rig()
    assert rig.read(Reg.CHIP_ID, 4) == h("A0 FB 32 0F")
    assert rig.read(Reg.OPR_MODE, 1) == b"\x00"
    assert rig.read(br.DATA_START, br.DATA_LEN) == bytes(44)
    assert rig.chip.samples == 0


def test_mode_switch_times_and_what_happens_meanwhile() -> None:
    rig = Rig()
    assert rig.write(Reg.OPR_MODE, bytes((OprMode.IMU,))) == Status.WRITE_SUCCESS
    rig.clock.t += 0.006
    assert rig.ask(bp.read_frame(Reg.OPR_MODE, 1)) == h("EE 02")  # READ_FAIL while switching
    assert rig.ask(bp.write_frame(Reg.OPR_MODE, b"\x0c")) == h("EE 03")  # WRITE_FAIL
    rig.clock.t += 0.0011
    assert rig.read(Reg.OPR_MODE, 1) == b"\x08"
    assert rig.read(Reg.SYS_STATUS, 1) == b"\x05"  # fusion running
    assert rig.write(Reg.OPR_MODE, b"\x08") == Status.WRITE_SUCCESS  # the same mode: no switch
    assert rig.read(Reg.OPR_MODE, 1) == b"\x08"
    rig.write(Reg.OPR_MODE, b"\x00")
    rig.clock.t += 0.018
    assert rig.ask(bp.read_frame(Reg.OPR_MODE, 1)) == h("EE 02")
    rig.clock.t += 0.0011
    assert rig.read(Reg.OPR_MODE, 1) == b"\x00"
    assert rig.read(br.DATA_START, br.DATA_LEN) == bytes(44)  # CONFIGMODE: zero again


def test_writes_refused() -> None:
    rig = Rig()
    for reg, data, status in [
        (Reg.CHIP_ID, b"\x00", Status.WRITE_DISABLED),  # read-only
        (0x3C, b"\x00", Status.WRITE_DISABLED),  # reserved
        (Reg.SYS_ERR, b"\x00\x80", Status.WRITE_DISABLED),  # SYS_ERR read-only, UNIT_SEL not
        (Reg.PAGE_ID, b"\x01", Status.WRITE_FAIL),  # page 1 is not emulated
        (Reg.PWR_MODE, b"\x01", Status.WRITE_FAIL),  # only normal power
        (Reg.OPR_MODE, b"\x0d", Status.WRITE_FAIL),  # no such mode
    ]:
        assert rig.write(reg, data) == status
    assert rig.read(Reg.SYS_ERR, 2) == h("00 80")  # nothing of a refused write is taken
    rig.enter(OprMode.NDOF)
    assert rig.write(Reg.UNIT_SEL, b"\x01") == Status.WRITE_DISABLED  # CONFIGMODE only
    assert rig.read(Reg.UNIT_SEL, 1) == b"\x80"


def test_uart_errors_byte_exact() -> None:
    rig = Rig()
    assert rig.uart.feed(h("55 66 77")) == [h("EE 06")]  # one reply for a burst of garbage
    assert rig.uart.feed(h("AA 01 00 01")) == []  # still the same burst: discarded
    rig.clock.t += CHAR_TIMEOUT_S + 1e-6
    assert rig.uart.feed(h("AA 01 00 01")) == [h("BB 01 A0")]  # the line was quiet: heard
    rig.clock.t += 1.0
    assert rig.ask(h("AA 02 00 01")) == h("EE 06")  # neither read nor write
    rig.clock.t += 1.0
    assert rig.ask(h("AA 01 00 00")) == h("EE 09")
    rig.clock.t += 1.0
    assert rig.ask(h("AA 01 00 81")) == h("EE 08")
    rig.clock.t += 1.0
    assert rig.ask(h("AA 00 7F 02 00 00")) == h("EE 04")  # past 0x7F; data not waited for
    rig.clock.t += 1.0
    assert rig.ask(h("AA 01 40 41")) == h("EE 04")
    rig.clock.t += 1.0
    assert rig.ask(h("AA 01 00 80"))[:3] == h("BB 80 A0")  # the whole page in one frame


def test_receive_character_timeout() -> None:
    rig = Rig()
    assert rig.uart.feed(h("AA 00 3D")) == [] and rig.uart.pending == 3
    assert rig.uart.deadline() == pytest.approx(rig.clock.t + CHAR_TIMEOUT_S)
    rig.clock.t += CHAR_TIMEOUT_S / 2
    assert rig.uart.poll() == []
    assert rig.uart.feed(h("01")) == []  # each byte restarts the timeout
    rig.clock.t += CHAR_TIMEOUT_S + 1e-6
    assert rig.uart.poll() == [h("EE 0A")] and rig.uart.pending == 0
    assert rig.chip.mode == OprMode.CONFIG and rig.uart.deadline() is None
    assert rig.ask(h("AA 01 3D 01")) == h("BB 01 00")


def test_noise_matches_the_datasheet_densities() -> None:
    rig = Rig(seed=3)
    rig.enter(OprMode.ACCGYRO)
    s = [rig.next_sample() for _ in range(1500)]
    acc = np.array([x.accel_mps2 for x in s])
    gyr = np.array([x.gyro_dps for x in s])
    sigma_acc = 150e-6 * 9.80665 * math.sqrt(62.5)  # 0.0116 m/s²
    sigma_gyr = 0.014 * math.sqrt(32.0)  # 0.079 °/s
    # quantisation adds LSB²/12 of variance: 0.01 m/s², 1/16 °/s
    assert acc.std(0) == pytest.approx(np.hypot(sigma_acc, 0.01 / math.sqrt(12)), rel=0.1)
    assert gyr.std(0) == pytest.approx(np.hypot(sigma_gyr, 0.0625 / math.sqrt(12)), rel=0.1)
    assert acc.mean(0) == pytest.approx([0, 0, 9.80665], abs=0.002)
    assert gyr.mean(0) == pytest.approx([0, 0, 0], abs=0.01)
    assert s[0].quat_wxyz == (0, 0, 0, 0) and s[0].mag_ut == (0, 0, 0)  # not in ACCGYRO


def test_samples_are_held_between_output_instants_and_seeded() -> None:
    a, b, c = Rig(seed=7), Rig(seed=7), Rig(seed=8)
    for rig in (a, b, c):
        rig.enter(OprMode.AMG)
    first = a.sample()
    a.clock.t += 0.004
    assert a.sample() == first and a.chip.samples == 1  # the same 10 ms output period
    assert a.next_sample() != first and a.chip.samples == 2
    assert [b.sample(), b.next_sample()] == [first, a.sample()]  # same seed, same data
    assert c.sample() != first


def test_saturation_and_quantisation() -> None:
    truth = ImuTruth(np.eye(3), np.array([50.0, -0.004, 0.006]), np.radians([3000.0, -1.0, 0.03]))
    rig = Rig(truth, noise=False)
    rig.enter(OprMode.ACCGYRO)
    v = bp.unpack_int16(rig.read(br.DATA_START, 6)) + bp.unpack_int16(rig.read(Reg.GYR_DATA, 6))
    assert v == (3923, 0, 1, 32000, -16, 0)  # ±4 g, ±2000 °/s, to the nearest LSB


def test_fusion_relative_heading_gravity_and_linear_acceleration() -> None:
    rig = Rig(TILTED, noise=False)
    R = TILTED.rotation
    rig.enter(OprMode.IMU)
    d = rig.sample()
    g_sensor = R.T @ [0, 0, 9.80665]
    assert d.gravity_mps2 == pytest.approx(g_sensor, abs=0.006)
    assert d.linear_accel_mps2 == pytest.approx([0, 0, 0], abs=0.011)
    # IMU mode: the heading at mode entry is zero, roll and pitch are kept
    assert _rotation(d.quat_wxyz) == pytest.approx(rpy_matrix(*np.radians([10, -20, 0])), abs=2e-4)
    assert d.euler_deg == pytest.approx((0.0, -20.0, 10.0), abs=0.07)
    rig.enter(OprMode.CONFIG)
    rig.enter(OprMode.NDOF)  # absolute heading
    d = rig.sample()
    assert _rotation(d.quat_wxyz) == pytest.approx(R, abs=2e-4)
    assert d.euler_deg == pytest.approx((330.0, -20.0, 10.0), abs=0.07)  # heading clockwise
    assert np.linalg.norm(d.mag_ut) == pytest.approx(math.hypot(20, 40), abs=0.1)


def test_fusion_noise_is_small() -> None:
    rig = Rig(TILTED, seed=5)
    rig.enter(OprMode.NDOF)
    grv = np.array([rig.next_sample().gravity_mps2 for _ in range(300)])
    # 0.05° of orientation error: 0.009 m/s² of gravity, plus quantisation
    assert grv.std(0).max() < 0.015
    assert grv.mean(0) == pytest.approx(TILTED.rotation.T @ [0, 0, 9.80665], abs=0.003)


def test_units_mg_and_rps() -> None:
    truth = ImuTruth(np.eye(3), np.array([0.0, 0.0, 9.80665]), np.array([1.0, 0.0, 0.0]))
    rig = Rig(truth, noise=False)
    assert rig.write(Reg.UNIT_SEL, b"\x03") == Status.WRITE_SUCCESS  # mg, rad/s
    rig.enter(OprMode.ACCGYRO)
    assert bp.unpack_int16(rig.read(Reg.ACC_DATA, 6))[2] == 1000  # 1 mg = 1 LSB
    assert bp.unpack_int16(rig.read(Reg.GYR_DATA, 6))[0] == 900  # 1 rad/s = 900 LSB
    d = rig.sample(units=0x03)
    assert d.accel_mps2[2] == pytest.approx(9.80665) and d.gyro_dps[0] == pytest.approx(57.29578)


def test_axis_remap_applies_to_vectors_and_orientation() -> None:
    rig = Rig(TILTED, noise=False)
    assert rig.write(Reg.AXIS_MAP_CONFIG, h("21 01")) == Status.WRITE_SUCCESS
    assert rig.write(Reg.AXIS_MAP_CONFIG, h("14")) == Status.WRITE_SUCCESS  # invalid: kept
    assert rig.read(Reg.AXIS_MAP_CONFIG, 2) == h("21 01")
    rig.enter(OprMode.NDOF)
    d = rig.sample()
    f = TILTED.specific_force_mps2
    assert d.accel_mps2 == pytest.approx([f[1], f[0], -f[2]], abs=0.006)
    # the quaternion is the remapped frame's: gravity seen through it is the remapped gravity
    R_out = _rotation(d.quat_wxyz)
    assert pytest.approx(d.gravity_mps2, abs=0.01) == R_out.T @ [0, 0, 9.80665]


def test_reset_silences_the_chip_then_restores_the_register_file() -> None:
    rig = Rig()
    rig.write(Reg.UNIT_SEL, b"\x01")
    rig.enter(OprMode.IMU)
    assert rig.write(Reg.SYS_TRIGGER, b"\x20") == Status.WRITE_SUCCESS
    assert rig.uart.feed(bp.read_frame(Reg.CHIP_ID, 1)) == []
    rig.clock.t += RESET_S
    assert rig.read(Reg.CHIP_ID, 1) == b"\xa0"
    assert rig.read(Reg.UNIT_SEL, 3) == h("80 00 00") and rig.chip.mode == OprMode.CONFIG


def test_truth_is_checked() -> None:
    with pytest.raises(ValueError):
        ImuTruth(np.diag([1.0, 1.0, -1.0]), np.zeros(3), np.zeros(3))  # a mirror
    with pytest.raises(ValueError):
        ImuTruth(np.eye(3), np.array([0.0, math.nan, 0.0]), np.zeros(3))
    t = ImuTruth.at_rest_rpy(0.0, 90.0, 0.0)  # x axis pointing down
    assert t.specific_force_mps2 == pytest.approx([-9.80665, 0, 0], abs=1e-9)
    assert not t.rotation.flags.writeable


def _rotation(q: tuple[float, float, float, float]) -> np.ndarray:
    w, x, y, z = np.asarray(q) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
