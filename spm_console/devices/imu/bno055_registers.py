"""The Bosch BNO055's page-0 register map as data: addresses, reset values and who may write
each register, the operating modes, the units UNIT_SEL selects and the axis remap.

Pure (no I/O); the frames that carry these registers are ``bno055_protocol.py``. Sources: Bosch
BST-BNO055-DS000 rev 1.4, §4.2 (register map, Table 4-2), §3.3 (operating modes, Tables 3-5,
3-6), §3.4 (axis remap), §3.6 (units, Tables 3-11, 3-17, 3-22; output rates, Table 3-14).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum, StrEnum
from typing import Literal

Remap = tuple[tuple[int, int, int], tuple[int, int, int], tuple[int, int, int]]

PAGE_SIZE = 0x80
"""Addresses of one register page: 0x00..0x7F."""
G_MPS2 = 9.80665
"""Standard gravity, m/s²: the unit 'g' of the ranges and of mg."""


class Reg(IntEnum):
    """Page-0 register addresses (§4.2); a block's address is its first byte's."""

    CHIP_ID = 0x00
    ACC_ID = 0x01
    MAG_ID = 0x02
    GYR_ID = 0x03
    SW_REV_ID_LSB = 0x04
    SW_REV_ID_MSB = 0x05
    BL_REV_ID = 0x06
    PAGE_ID = 0x07
    ACC_DATA = 0x08
    MAG_DATA = 0x0E
    GYR_DATA = 0x14
    EUL_DATA = 0x1A
    QUA_DATA = 0x20
    LIA_DATA = 0x28
    GRV_DATA = 0x2E
    TEMP = 0x34
    CALIB_STAT = 0x35
    ST_RESULT = 0x36
    INT_STA = 0x37
    SYS_CLK_STATUS = 0x38
    SYS_STATUS = 0x39
    SYS_ERR = 0x3A
    UNIT_SEL = 0x3B
    OPR_MODE = 0x3D
    PWR_MODE = 0x3E
    SYS_TRIGGER = 0x3F
    TEMP_SOURCE = 0x40
    AXIS_MAP_CONFIG = 0x41
    AXIS_MAP_SIGN = 0x42
    ACC_OFFSET = 0x55
    MAG_OFFSET = 0x5B
    GYR_OFFSET = 0x61
    ACC_RADIUS = 0x67
    MAG_RADIUS = 0x69


CHIP_ID_VALUE = 0xA0
DATA_START = int(Reg.ACC_DATA)
DATA_LEN = int(Reg.TEMP) - DATA_START
"""ACC_DATA through GRV_DATA, 0x08..0x33: the 44 bytes one burst read returns."""


class Access(StrEnum):
    """Who may write a register."""

    READ_ONLY = "r"
    CONFIG = "config"
    """Writable in CONFIGMODE only (§3.3.1)."""
    ANY = "any"
    """Writable in every operating mode (OPR_MODE, PAGE_ID, SYS_TRIGGER)."""


@dataclass(frozen=True)
class Register:
    """One page-0 register (or block of ``size`` bytes) and its reset value."""

    reg: Reg
    size: int
    reset: int
    """Reset value of each of its bytes."""
    access: Access


_R, _C, _A = Access.READ_ONLY, Access.CONFIG, Access.ANY
REGISTERS: tuple[Register, ...] = (
    Register(Reg.CHIP_ID, 1, 0xA0, _R),
    Register(Reg.ACC_ID, 1, 0xFB, _R),
    Register(Reg.MAG_ID, 1, 0x32, _R),
    Register(Reg.GYR_ID, 1, 0x0F, _R),
    Register(Reg.SW_REV_ID_LSB, 1, 0x08, _R),
    Register(Reg.SW_REV_ID_MSB, 1, 0x03, _R),
    Register(Reg.BL_REV_ID, 1, 0x15, _R),  # "NA" in Table 4-2: a version of our choosing
    Register(Reg.PAGE_ID, 1, 0x00, _A),
    Register(Reg.ACC_DATA, 6, 0x00, _R),
    Register(Reg.MAG_DATA, 6, 0x00, _R),
    Register(Reg.GYR_DATA, 6, 0x00, _R),
    Register(Reg.EUL_DATA, 6, 0x00, _R),
    Register(Reg.QUA_DATA, 8, 0x00, _R),
    Register(Reg.LIA_DATA, 6, 0x00, _R),
    Register(Reg.GRV_DATA, 6, 0x00, _R),
    Register(Reg.TEMP, 1, 0x00, _R),
    Register(Reg.CALIB_STAT, 1, 0x00, _R),
    Register(Reg.ST_RESULT, 1, 0x0F, _R),  # the power-on self test passed: MCU, gyro, mag, acc
    Register(Reg.INT_STA, 1, 0x00, _R),
    Register(Reg.SYS_CLK_STATUS, 1, 0x00, _R),
    Register(Reg.SYS_STATUS, 1, 0x00, _R),
    Register(Reg.SYS_ERR, 1, 0x00, _R),
    # Table 4-2 gives 0x80 (Android orientation), §4.3.60 bit 7 = 0: the units are the same
    Register(Reg.UNIT_SEL, 1, 0x80, _C),
    Register(Reg.OPR_MODE, 1, 0x00, _A),
    Register(Reg.PWR_MODE, 1, 0x00, _C),
    Register(Reg.SYS_TRIGGER, 1, 0x00, _A),
    Register(Reg.TEMP_SOURCE, 1, 0x00, _C),
    Register(Reg.AXIS_MAP_CONFIG, 1, 0x24, _C),
    Register(Reg.AXIS_MAP_SIGN, 1, 0x00, _C),
    Register(Reg.ACC_OFFSET, 6, 0x00, _C),
    Register(Reg.MAG_OFFSET, 6, 0x00, _C),
    Register(Reg.GYR_OFFSET, 6, 0x00, _C),
    Register(Reg.ACC_RADIUS, 2, 0x00, _C),
    Register(Reg.MAG_RADIUS, 2, 0x00, _C),
)


def register_at(address: int) -> Register | None:
    """The register holding byte ``address`` of page 0; None for a reserved address."""
    for r in REGISTERS:
        if r.reg <= address < r.reg + r.size:
            return r
    return None


def reset_page() -> bytearray:
    """Page 0 as after power-on: each register's reset value, reserved bytes 0."""
    page = bytearray(PAGE_SIZE)
    for r in REGISTERS:
        page[r.reg:r.reg + r.size] = bytes((r.reset,)) * r.size
    return page


class OprMode(IntEnum):
    """OPR_MODE's low nibble (§3.3, Table 3-5)."""

    CONFIG = 0x00
    ACCONLY = 0x01
    MAGONLY = 0x02
    GYROONLY = 0x03
    ACCMAG = 0x04
    ACCGYRO = 0x05
    MAGGYRO = 0x06
    AMG = 0x07
    IMU = 0x08
    COMPASS = 0x09
    M4G = 0x0A
    NDOF_FMC_OFF = 0x0B
    NDOF = 0x0C


Fusion = Literal["none", "relative", "absolute"]


@dataclass(frozen=True)
class ModeInfo:
    """What an operating mode runs: the sensors on, the fusion, the fused output rate."""

    acc: bool
    mag: bool
    gyr: bool
    fusion: Fusion
    """"relative": heading zeroed at mode entry; "absolute": heading from the magnetometer."""
    rate_hz: float
    """Data output rate (Table 3-14 for the fusion modes; 100 Hz assumed for the others)."""


MODES: dict[OprMode, ModeInfo] = {
    OprMode.CONFIG: ModeInfo(False, False, False, "none", 0.0),
    OprMode.ACCONLY: ModeInfo(True, False, False, "none", 100.0),
    OprMode.MAGONLY: ModeInfo(False, True, False, "none", 100.0),
    OprMode.GYROONLY: ModeInfo(False, False, True, "none", 100.0),
    OprMode.ACCMAG: ModeInfo(True, True, False, "none", 100.0),
    OprMode.ACCGYRO: ModeInfo(True, False, True, "none", 100.0),
    OprMode.MAGGYRO: ModeInfo(False, True, True, "none", 100.0),
    OprMode.AMG: ModeInfo(True, True, True, "none", 100.0),
    OprMode.IMU: ModeInfo(True, False, True, "relative", 100.0),
    OprMode.COMPASS: ModeInfo(True, True, False, "absolute", 20.0),
    OprMode.M4G: ModeInfo(True, True, False, "relative", 50.0),
    OprMode.NDOF_FMC_OFF: ModeInfo(True, True, True, "absolute", 100.0),
    OprMode.NDOF: ModeInfo(True, True, True, "absolute", 100.0),
}

FROM_CONFIG_S = 0.007
"""Switching time from CONFIGMODE into any operating mode, s (Table 3-6)."""
TO_CONFIG_S = 0.019
"""Switching time from any operating mode into CONFIGMODE, s (Table 3-6)."""


def switch_time_s(old: OprMode, new: OprMode) -> float:
    """How long a switch from ``old`` to ``new`` takes, s: Table 3-6's figures, and both for a
    switch between two operating modes (taken as one through CONFIGMODE); 0 for no change."""
    if old == new:
        return 0.0
    if old == OprMode.CONFIG:
        return FROM_CONFIG_S
    if new == OprMode.CONFIG:
        return TO_CONFIG_S
    return TO_CONFIG_S + FROM_CONFIG_S


@dataclass(frozen=True)
class Units:
    """Register LSB per physical unit for a UNIT_SEL value (§3.6.1, Tables 3-11, 3-17, 3-22).

    Each scale converts an SI-or-degree value to LSB: ``raw = value × scale``."""

    unit_sel: int
    accel_lsb_per_mps2: float
    """100 (m/s²) or 1000/g (mg selected: 1 mg = 1 LSB); also linear acceleration and gravity."""
    gyro_lsb_per_dps: float
    """16 (°/s) or 900·π/180 (rad/s selected: 1 rad/s = 900 LSB)."""
    euler_lsb_per_deg: float
    """16 (degrees) or 900·π/180 (radians selected: 1 rad = 900 LSB)."""
    fahrenheit: bool
    """TEMP in °F (1 LSB = 2 °F) instead of °C (1 LSB = 1 °C)."""
    mag_lsb_per_ut: float = 16.0
    quat_lsb: float = float(1 << 14)

    @classmethod
    def of(cls, unit_sel: int) -> Units:
        """The scales of UNIT_SEL ``unit_sel`` (bits 0, 1, 2, 4; bit 7 changes no unit)."""
        rad = 900.0 * math.pi / 180.0
        return cls(unit_sel & 0xFF,
                   1000.0 / G_MPS2 if unit_sel & 0x01 else 100.0,
                   rad if unit_sel & 0x02 else 16.0,
                   rad if unit_sel & 0x04 else 16.0,
                   bool(unit_sel & 0x10))

    def temp_c(self, raw: int) -> float:
        """TEMP's signed byte ``raw`` as °C."""
        return (2.0 * raw - 32.0) * 5.0 / 9.0 if self.fahrenheit else float(raw)

    def temp_raw(self, celsius: float) -> int:
        """The signed TEMP byte for ``celsius``, °C."""
        value = (celsius * 9.0 / 5.0 + 32.0) / 2.0 if self.fahrenheit else celsius
        return max(-128, min(127, round(value)))


def axis_remap(config: int, sign: int) -> Remap | None:
    """The matrix P (rows of -1/0/1) with ``v_out = P @ v_chip`` for AXIS_MAP_CONFIG ``config``
    and AXIS_MAP_SIGN ``sign`` (§3.4): bits 1:0, 3:2, 5:4 name the chip axis (0 x, 1 y, 2 z)
    of output x, y, z; sign bits 2, 1, 0 negate output x, y, z. None when the configuration is
    invalid (an axis code 3, or one chip axis used twice)."""
    axes = [(config >> (2 * i)) & 0x03 for i in range(3)]
    if 3 in axes or len(set(axes)) != 3:
        return None

    def row(i: int) -> tuple[int, int, int]:
        s = -1 if sign & (0x04 >> i) else 1
        return (s if axes[i] == 0 else 0, s if axes[i] == 1 else 0, s if axes[i] == 2 else 0)

    return (row(0), row(1), row(2))
