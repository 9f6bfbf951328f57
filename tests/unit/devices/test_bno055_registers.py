"""The BNO055's register map as data against Bosch BST-BNO055-DS000 rev 1.4: addresses and
reset values of §4.2, the modes and switching times of §3.3, the units of §3.6.1 and the axis
remap of §3.4."""

from __future__ import annotations

import math

import pytest

from spm_console.devices.imu import bno055_protocol as bp
from spm_console.devices.imu import bno055_registers as br
from spm_console.devices.imu.bno055_registers import OprMode, Reg


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def test_register_map_addresses_and_reset_values() -> None:
    addresses = {"CHIP_ID": 0x00, "ACC_ID": 0x01, "MAG_ID": 0x02, "GYR_ID": 0x03, "PAGE_ID": 0x07,
                 "ACC_DATA": 0x08, "MAG_DATA": 0x0E, "GYR_DATA": 0x14, "EUL_DATA": 0x1A,
                 "QUA_DATA": 0x20, "LIA_DATA": 0x28, "GRV_DATA": 0x2E, "TEMP": 0x34,
                 "CALIB_STAT": 0x35, "ST_RESULT": 0x36, "SYS_STATUS": 0x39, "SYS_ERR": 0x3A,
                 "UNIT_SEL": 0x3B, "OPR_MODE": 0x3D, "PWR_MODE": 0x3E, "SYS_TRIGGER": 0x3F,
                 "AXIS_MAP_CONFIG": 0x41, "AXIS_MAP_SIGN": 0x42}
    for name, address in addresses.items():
        assert Reg[name] == address
    page = br.reset_page()
    assert len(page) == 128
    assert page[0:4] == h("A0 FB 32 0F")
    assert page[Reg.AXIS_MAP_CONFIG] == 0x24 and page[Reg.AXIS_MAP_SIGN] == 0
    assert page[Reg.OPR_MODE] == OprMode.CONFIG and page[Reg.UNIT_SEL] & 0x7F == 0
    assert page[br.DATA_START:br.DATA_START + br.DATA_LEN] == bytes(44)
    # blocks do not overlap, and each byte of one belongs to it
    covered = [a for r in br.REGISTERS for a in range(r.reg, r.reg + r.size)]
    assert len(covered) == len(set(covered))
    acc = br.register_at(0x0D)
    assert acc is not None and acc.reg == Reg.ACC_DATA
    assert br.register_at(0x3C) is None and br.register_at(0x7F) is None


def test_modes_and_switching_times() -> None:
    assert (OprMode.CONFIG, OprMode.ACCONLY, OprMode.ACCGYRO, OprMode.AMG, OprMode.IMU,
            OprMode.NDOF) == (0x00, 0x01, 0x05, 0x07, 0x08, 0x0C)
    assert set(br.MODES) == set(OprMode)
    imu = br.MODES[OprMode.IMU]
    assert imu.acc and imu.gyr and not imu.mag and imu.fusion == "relative" and imu.rate_hz == 100
    assert br.MODES[OprMode.NDOF].fusion == "absolute"
    assert br.switch_time_s(OprMode.CONFIG, OprMode.IMU) == 0.007
    assert br.switch_time_s(OprMode.NDOF, OprMode.CONFIG) == 0.019
    assert br.switch_time_s(OprMode.IMU, OprMode.NDOF) == pytest.approx(0.026)
    assert br.switch_time_s(OprMode.IMU, OprMode.IMU) == 0.0


def test_default_units() -> None:
    u = br.Units.of(0x80)  # the reset value: bit 7 is the orientation format, no unit
    assert u.accel_lsb_per_mps2 == 100 and u.gyro_lsb_per_dps == 16
    assert u.euler_lsb_per_deg == 16 and u.quat_lsb == 2**14 and u.mag_lsb_per_ut == 16
    assert u.temp_c(25) == 25 and u.temp_raw(25.4) == 25


def test_alternative_units() -> None:
    u = br.Units.of(0x17)  # mg, rad/s, radians, °F
    assert bp.to_lsb((br.G_MPS2,), u.accel_lsb_per_mps2) == (1000,)  # 1 mg = 1 LSB
    assert bp.to_lsb((math.degrees(1.0),), u.gyro_lsb_per_dps) == (900,)  # 1 rad/s = 900 LSB
    assert bp.to_lsb((math.degrees(1.0),), u.euler_lsb_per_deg) == (900,)
    assert u.temp_raw(25.0) == 38 and u.temp_c(38) == pytest.approx(24.444, abs=1e-3)  # 2 °F/LSB


def test_axis_remap() -> None:
    assert br.axis_remap(0x24, 0x00) == ((1, 0, 0), (0, 1, 0), (0, 0, 1))  # the default
    # 0x21: output x from chip y, output y from chip x; sign bit 0: output z negated
    assert br.axis_remap(0x21, 0x01) == ((0, 1, 0), (1, 0, 0), (0, 0, -1))
    assert br.axis_remap(0x24, 0x04) == ((-1, 0, 0), (0, 1, 0), (0, 0, 1))  # bit 2: x sign
    assert br.axis_remap(0x14, 0x00) is None  # x and y both from chip x
    assert br.axis_remap(0x27, 0x00) is None  # axis code 3
