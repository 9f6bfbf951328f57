"""BNO055 UART codec against Bosch BST-BNO055-DS000 rev 1.4: the frames and error replies of
§4.7 byte for byte, little-endian int16 data and the data block's encoding."""

from __future__ import annotations

import pytest

from spm_console.devices.imu import bno055_protocol as bp
from spm_console.devices.imu import bno055_registers as br
from spm_console.devices.imu.bno055_protocol import Status
from spm_console.devices.imu.bno055_registers import OprMode, Reg


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def test_request_frames_byte_exact() -> None:
    assert bp.read_frame(Reg.CHIP_ID, 1) == h("AA 01 00 01")
    assert bp.read_frame(br.DATA_START, br.DATA_LEN) == h("AA 01 08 2C")  # 0x08..0x33
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


def test_int16_little_endian_and_saturation() -> None:
    assert bp.pack_int16((1, -1, 0x1234)) == h("01 00 FF FF 34 12")
    assert bp.unpack_int16(h("01 00 FF FF 34 12")) == (1, -1, 0x1234)
    assert bp.to_lsb((9.81, -9.806, 400.0, -400.0), 100.0) == (981, -981, 32767, -32768)
    with pytest.raises(ValueError):
        bp.unpack_int16(h("01 02 03"))


def test_data_block_round_trip() -> None:
    u = br.Units.of(0)
    d = bp.DataBlock(accel_mps2=(0.01, -9.81, 39.22), mag_ut=(20.0, -0.0625, 40.0),
                     gyro_dps=(0.0625, -2000.0, 1.5), euler_deg=(359.9375, -90.0, 180.0),
                     quat_wxyz=(1.0, 0.0, -0.5, 2**-14), linear_accel_mps2=(0.0, 0.01, -0.02),
                     gravity_mps2=(0.0, 0.0, 9.81))
    raw = bp.encode_data(d, u)
    assert len(raw) == br.DATA_LEN == 44
    assert raw[0:2] == h("01 00") and raw[24:26] == h("00 40")  # ACC x 1 LSB, QUA w = 2^14
    assert bp.decode_data(raw, u) == d
    with pytest.raises(ValueError):
        bp.decode_data(raw[:-2], u)
