"""BNO055 UART codec against Bosch BST-BNO055-DS000 rev 1.4: frames and error replies of §4.7
byte for byte, the register map of §4.2, the units of §3.6 and the axis remap of §3.4."""

from __future__ import annotations

import math

import pytest

from spm_console.devices.imu import bno055_protocol as bp
from spm_console.devices.imu.bno055_protocol import OprMode, Reg, Status


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def test_request_frames_byte_exact() -> None:
    assert bp.read_frame(Reg.CHIP_ID, 1) == h("AA 01 00 01")
    assert bp.read_frame(bp.DATA_START, bp.DATA_LEN) == h("AA 01 08 2C")  # 0x08..0x33
    assert bp.write_frame(Reg.OPR_MODE, bytes((OprMode.NDOF,))) == h("AA 00 3D 01 0C")
    assert bp.write_frame(Reg.AXIS_MAP_CONFIG, h("21 04")) == h("AA 00 41 02 21 04")


def test_reply_frames_byte_exact() -> None:
    assert bp.read_reply(b"\xa0") == h("BB 01 A0")
    assert bp.status_reply(Status.WRITE_SUCCESS) == h("EE 01")
    for value, status in [(0x02, Status.READ_FAIL), (0x03, Status.WRITE_FAIL),
                          (0x04, Status.INVALID_ADDRESS), (0x05, Status.WRITE_DISABLED),
                          (0x06, Status.WRONG_START_BYTE), (0x07, Status.BUS_OVER_RUN),
                          (0x08, Status.MAX_LENGTH), (0x09, Status.MIN_LENGTH),
                          (0x0A, Status.RECEIVE_CHARACTER_TIMEOUT)]:
        assert bp.status_reply(status) == bytes((0xEE, value))


def test_replies_decode() -> None:
    assert bp.decode_reply(h("BB 01 A0")) == bp.Reply(None, b"\xa0")
    assert bp.decode_reply(h("EE 07")) == bp.Reply(Status.BUS_OVER_RUN)
    assert bp.reply_size(b"") is None and bp.reply_size(h("BB")) is None
    assert bp.reply_size(h("BB 2C")) == 46 and bp.reply_size(h("EE 01")) == 2
    for bad in (h("FF FF"), h("EE 00"), h("EE 0B"), h("BB 00"), h("BB 81")):
        with pytest.raises(bp.FrameError):
            bp.reply_size(bad)
    with pytest.raises(bp.FrameError):
        bp.decode_reply(h("BB 02 A0"))  # one byte short


@pytest.mark.parametrize(("reg", "length", "status"), [
    (0x00, 0, Status.MIN_LENGTH),
    (0x00, 129, Status.MAX_LENGTH),
    (0x00, 255, Status.MAX_LENGTH),
    (0x7F, 2, Status.INVALID_ADDRESS),
    (0x80, 1, Status.INVALID_ADDRESS),
    (0xFF, 1, Status.INVALID_ADDRESS),
    (0x00, 128, None),
    (0x7F, 1, None),
])
def test_header_checks(reg: int, length: int, status: Status | None) -> None:
    assert bp.header_status(reg, length) == status


def test_frames_refuse_what_page_0_cannot_hold() -> None:
    for reg, n in ((0x00, 0), (0x00, 129), (0x7F, 2), (0x80, 1)):
        with pytest.raises(ValueError):
            bp.read_frame(reg, n)
        with pytest.raises(ValueError):
            bp.write_frame(reg, bytes(n))
    with pytest.raises(ValueError):
        bp.read_reply(b"")


def test_register_map_addresses_and_reset_values() -> None:
    addresses = {"CHIP_ID": 0x00, "ACC_ID": 0x01, "MAG_ID": 0x02, "GYR_ID": 0x03, "PAGE_ID": 0x07,
                 "ACC_DATA": 0x08, "MAG_DATA": 0x0E, "GYR_DATA": 0x14, "EUL_DATA": 0x1A,
                 "QUA_DATA": 0x20, "LIA_DATA": 0x28, "GRV_DATA": 0x2E, "TEMP": 0x34,
                 "CALIB_STAT": 0x35, "ST_RESULT": 0x36, "SYS_STATUS": 0x39, "SYS_ERR": 0x3A,
                 "UNIT_SEL": 0x3B, "OPR_MODE": 0x3D, "PWR_MODE": 0x3E, "SYS_TRIGGER": 0x3F,
                 "AXIS_MAP_CONFIG": 0x41, "AXIS_MAP_SIGN": 0x42}
    for name, address in addresses.items():
        assert Reg[name] == address
    page = bp.reset_page()
    assert len(page) == 128
    assert page[0:4] == h("A0 FB 32 0F")
    assert page[Reg.AXIS_MAP_CONFIG] == 0x24 and page[Reg.AXIS_MAP_SIGN] == 0
    assert page[Reg.OPR_MODE] == OprMode.CONFIG and page[Reg.UNIT_SEL] & 0x7F == 0
    assert page[bp.DATA_START:bp.DATA_START + bp.DATA_LEN] == bytes(44)
    # blocks do not overlap, and each byte of one belongs to it
    covered = [a for r in bp.REGISTERS for a in range(r.reg, r.reg + r.size)]
    assert len(covered) == len(set(covered))
    acc = bp.register_at(0x0D)
    assert acc is not None and acc.reg == Reg.ACC_DATA
    assert bp.register_at(0x3C) is None and bp.register_at(0x7F) is None


def test_modes_and_switching_times() -> None:
    assert (OprMode.CONFIG, OprMode.ACCONLY, OprMode.ACCGYRO, OprMode.AMG, OprMode.IMU,
            OprMode.NDOF) == (0x00, 0x01, 0x05, 0x07, 0x08, 0x0C)
    assert set(bp.MODES) == set(OprMode)
    imu = bp.MODES[OprMode.IMU]
    assert imu.acc and imu.gyr and not imu.mag and imu.fusion == "relative" and imu.rate_hz == 100
    assert bp.MODES[OprMode.NDOF].fusion == "absolute"
    assert bp.switch_time_s(OprMode.CONFIG, OprMode.IMU) == 0.007
    assert bp.switch_time_s(OprMode.NDOF, OprMode.CONFIG) == 0.019
    assert bp.switch_time_s(OprMode.IMU, OprMode.NDOF) == pytest.approx(0.026)
    assert bp.switch_time_s(OprMode.IMU, OprMode.IMU) == 0.0


def test_default_units() -> None:
    u = bp.Units.of(0x80)  # the reset value: bit 7 is the orientation format, no unit
    assert u.accel_lsb_per_mps2 == 100 and u.gyro_lsb_per_dps == 16
    assert u.euler_lsb_per_deg == 16 and u.quat_lsb == 2**14 and u.mag_lsb_per_ut == 16
    assert u.temp_c(25) == 25 and u.temp_raw(25.4) == 25


def test_alternative_units() -> None:
    u = bp.Units.of(0x17)  # mg, rad/s, radians, °F
    assert bp.to_lsb((bp.G_MPS2,), u.accel_lsb_per_mps2) == (1000,)  # 1 mg = 1 LSB
    assert bp.to_lsb((math.degrees(1.0),), u.gyro_lsb_per_dps) == (900,)  # 1 rad/s = 900 LSB
    assert bp.to_lsb((math.degrees(1.0),), u.euler_lsb_per_deg) == (900,)
    assert u.temp_raw(25.0) == 38 and u.temp_c(38) == pytest.approx(24.444, abs=1e-3)  # 2 °F/LSB


def test_int16_little_endian_and_saturation() -> None:
    assert bp.pack_int16((1, -1, 0x1234)) == h("01 00 FF FF 34 12")
    assert bp.unpack_int16(h("01 00 FF FF 34 12")) == (1, -1, 0x1234)
    assert bp.to_lsb((9.81, -9.806, 400.0, -400.0), 100.0) == (981, -981, 32767, -32768)
    with pytest.raises(ValueError):
        bp.unpack_int16(h("01 02 03"))


def test_data_block_round_trip() -> None:
    u = bp.Units.of(0)
    d = bp.DataBlock(accel_mps2=(0.01, -9.81, 39.22), mag_ut=(20.0, -0.0625, 40.0),
                     gyro_dps=(0.0625, -2000.0, 1.5), euler_deg=(359.9375, -90.0, 180.0),
                     quat_wxyz=(1.0, 0.0, -0.5, 2**-14), linear_accel_mps2=(0.0, 0.01, -0.02),
                     gravity_mps2=(0.0, 0.0, 9.81))
    raw = bp.encode_data(d, u)
    assert len(raw) == bp.DATA_LEN == 44
    assert raw[0:2] == h("01 00") and raw[24:26] == h("00 40")  # ACC x 1 LSB, QUA w = 2^14
    assert bp.decode_data(raw, u) == d
    with pytest.raises(ValueError):
        bp.decode_data(raw[:-2], u)


def test_axis_remap() -> None:
    assert bp.axis_remap(0x24, 0x00) == ((1, 0, 0), (0, 1, 0), (0, 0, 1))  # the default
    # 0x21: output x from chip y, output y from chip x; sign bit 0: output z negated
    assert bp.axis_remap(0x21, 0x01) == ((0, 1, 0), (1, 0, 0), (0, 0, -1))
    assert bp.axis_remap(0x24, 0x04) == ((-1, 0, 0), (0, 1, 0), (0, 0, 1))  # bit 2: x sign
    assert bp.axis_remap(0x14, 0x00) is None  # x and y both from chip x
    assert bp.axis_remap(0x27, 0x00) is None  # axis code 3
