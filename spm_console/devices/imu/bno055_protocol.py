"""Bosch BNO055 over UART: frames, statuses and the data block's encoding.

Pure (bytes and numbers in, bytes and numbers out; no I/O), shared by the driver
(``devices/imu/bno055.py``) and the emulated chip (``devices/emulator/bno055.py``); the register
map, modes and units are ``bno055_registers.py``. Source: Bosch BST-BNO055-DS000 rev 1.4, §4.7
(UART protocol), §3.6.5 (output data), §3.7 (burst reads).

Frames (§4.7; 115200 baud, 8N1, at most 128 data bytes a frame):

- write ``AA 00 REG LEN DATA…`` → ``EE 01`` (or ``EE STATUS`` on failure);
- read ``AA 01 REG LEN`` → ``BB LEN DATA…``, or ``EE STATUS`` on failure.

Data registers hold little-endian int16 (LSB first). With UNIT_SEL's unit bits clear (the reset
state): acceleration, linear acceleration and gravity 1 m/s² = 100 LSB, angular rate
1 °/s = 16 LSB, Euler angles 1° = 16 LSB, quaternion 1 = 2¹⁴ LSB, magnetic field 1 µT = 16 LSB,
temperature 1 °C = 1 LSB.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

from spm_console.devices.imu.bno055_registers import DATA_LEN, PAGE_SIZE, Units

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

START = 0xAA
"""First byte of every request."""
WRITE = 0x00
READ = 0x01
READ_OK = 0xBB
"""First byte of a successful read's reply."""
ACK = 0xEE
"""First byte of a write's acknowledgement and of every failure."""
MAX_LEN = 128
"""Most data bytes one frame reads or writes (§4.7)."""


class Status(IntEnum):
    """The status byte after ``EE`` (§4.7)."""

    WRITE_SUCCESS = 0x01
    READ_FAIL = 0x02
    WRITE_FAIL = 0x03
    INVALID_ADDRESS = 0x04
    WRITE_DISABLED = 0x05
    WRONG_START_BYTE = 0x06
    BUS_OVER_RUN = 0x07
    MAX_LENGTH = 0x08
    MIN_LENGTH = 0x09
    RECEIVE_CHARACTER_TIMEOUT = 0x0A


def to_lsb(values: tuple[float, ...], scale: float) -> tuple[int, ...]:
    """Values × scale rounded to the nearest LSB, saturated to int16."""
    return tuple(max(-32768, min(32767, round(v * scale))) for v in values)


def pack_int16(values: tuple[int, ...]) -> bytes:
    """Little-endian int16s (LSB first), as the data registers hold them."""
    return struct.pack(f"<{len(values)}h", *values)


def unpack_int16(raw: bytes) -> tuple[int, ...]:
    """The little-endian int16s of ``raw`` (an even number of bytes)."""
    if len(raw) % 2:
        raise ValueError(f"int16 data need an even number of bytes, not {len(raw)}")
    return struct.unpack(f"<{len(raw) // 2}h", raw)


@dataclass(frozen=True)
class DataBlock:
    """The 44 bytes 0x08..0x33 in physical units (UNIT_SEL applied); vectors in the sensor's
    (remapped) axes, x, y, z."""

    accel_mps2: Vec3
    mag_ut: Vec3
    gyro_dps: Vec3
    euler_deg: Vec3
    """Heading, roll, pitch as EUL_DATA holds them, deg."""
    quat_wxyz: Quat
    linear_accel_mps2: Vec3
    gravity_mps2: Vec3


def _vec(ints: tuple[int, ...], scale: float) -> Vec3:
    return (ints[0] / scale, ints[1] / scale, ints[2] / scale)


def decode_data(block: bytes, units: Units) -> DataBlock:
    """The data block read from 0x08 (:data:`DATA_LEN` bytes) in physical units."""
    if len(block) != DATA_LEN:
        raise ValueError(f"the data block has {DATA_LEN} bytes, not {len(block)}")
    v = unpack_int16(block)
    q = v[12:16]
    return DataBlock(
        accel_mps2=_vec(v[0:3], units.accel_lsb_per_mps2),
        mag_ut=_vec(v[3:6], units.mag_lsb_per_ut),
        gyro_dps=_vec(v[6:9], units.gyro_lsb_per_dps),
        euler_deg=_vec(v[9:12], units.euler_lsb_per_deg),
        quat_wxyz=(q[0] / units.quat_lsb, q[1] / units.quat_lsb, q[2] / units.quat_lsb,
                   q[3] / units.quat_lsb),
        linear_accel_mps2=_vec(v[16:19], units.accel_lsb_per_mps2),
        gravity_mps2=_vec(v[19:22], units.accel_lsb_per_mps2),
    )


def encode_data(data: DataBlock, units: Units) -> bytes:
    """The inverse of :func:`decode_data`: the 44 register bytes (rounded, saturated)."""
    return pack_int16(
        to_lsb(data.accel_mps2, units.accel_lsb_per_mps2)
        + to_lsb(data.mag_ut, units.mag_lsb_per_ut)
        + to_lsb(data.gyro_dps, units.gyro_lsb_per_dps)
        + to_lsb(data.euler_deg, units.euler_lsb_per_deg)
        + to_lsb(data.quat_wxyz, units.quat_lsb)
        + to_lsb(data.linear_accel_mps2, units.accel_lsb_per_mps2)
        + to_lsb(data.gravity_mps2, units.accel_lsb_per_mps2))


def header_status(reg: int, length: int) -> Status | None:
    """The failure a request of ``length`` bytes at ``reg`` earns before any register is
    touched, checked in this order: LEN 0 → MIN_LENGTH, LEN > 128 → MAX_LENGTH, bytes past
    page 0's last address 0x7F → INVALID_ADDRESS. None when the header is acceptable."""
    if length < 1:
        return Status.MIN_LENGTH
    if length > MAX_LEN:
        return Status.MAX_LENGTH
    if reg + length > PAGE_SIZE:
        return Status.INVALID_ADDRESS
    return None


def _check(reg: int, length: int) -> None:
    if not 0 <= reg < PAGE_SIZE or not 1 <= length <= MAX_LEN or reg + length > PAGE_SIZE:
        raise ValueError(f"{length} bytes at 0x{reg:02X} are not within page 0 (0x00..0x7F, "
                         f"1..{MAX_LEN} bytes)")


def read_frame(reg: int, length: int) -> bytes:
    """The request ``AA 01 REG LEN``."""
    _check(reg, length)
    return bytes((START, READ, reg, length))


def write_frame(reg: int, data: bytes) -> bytes:
    """The request ``AA 00 REG LEN DATA…``."""
    _check(reg, len(data))
    return bytes((START, WRITE, reg, len(data))) + bytes(data)


def status_reply(status: Status) -> bytes:
    """``EE STATUS``: a write's acknowledgement or any failure."""
    return bytes((ACK, int(status)))


def read_reply(data: bytes) -> bytes:
    """``BB LEN DATA…``: a successful read."""
    if not 1 <= len(data) <= MAX_LEN:
        raise ValueError(f"a read reply carries 1..{MAX_LEN} bytes, not {len(data)}")
    return bytes((READ_OK, len(data))) + bytes(data)


@dataclass(frozen=True)
class Reply:
    """A decoded reply: the data of a successful read, or the status of an ``EE`` reply."""

    status: Status | None
    """None for ``BB`` (a successful read)."""
    data: bytes = b""


class FrameError(ValueError):
    """Bytes that are not a BNO055 reply."""


def reply_size(head: bytes) -> int | None:
    """The whole reply's length in bytes from its first bytes; None until enough are there
    (two). Raises FrameError when the first byte starts no reply, or a status is unknown."""
    if not head:
        return None
    if head[0] not in (READ_OK, ACK):
        raise FrameError(f"0x{head[0]:02X} starts no BNO055 reply (0xBB or 0xEE)")
    if len(head) < 2:
        return None
    if head[0] == ACK:
        if not Status.WRITE_SUCCESS <= head[1] <= Status.RECEIVE_CHARACTER_TIMEOUT:
            raise FrameError(f"unknown status 0x{head[1]:02X}")
        return 2
    if not 1 <= head[1] <= MAX_LEN:
        raise FrameError(f"a read reply of {head[1]} bytes (1..{MAX_LEN})")
    return 2 + head[1]


def decode_reply(raw: bytes) -> Reply:
    """A complete reply (exactly :func:`reply_size` bytes)."""
    size = reply_size(raw)
    if size is None or len(raw) != size:
        raise FrameError(f"an incomplete or overlong reply: {raw.hex(' ')}")
    if raw[0] == ACK:
        return Reply(Status(raw[1]))
    return Reply(None, bytes(raw[2:]))
