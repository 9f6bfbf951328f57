"""The emulated MX-106's Drive Mode (address 10, bit 0: reverse) and Homing Offset (address 20,
added to Present Position): the registers' frame over the encoder's own count."""

from __future__ import annotations

from spm_console.devices.dynamixel.control_table import MX106_P1, MX106_P2
from spm_console.devices.dynamixel.protocol2 import ErrorNumber
from spm_console.devices.emulator.servo import (
    DRIVE_MODE_REVERSE,
    MAX_HOMING_OFFSET,
    EmulatedServo,
    reversed_zero,
)

T = 4096


def _present(s: EmulatedServo) -> int:
    reg = MX106_P2["present_position"]
    err, data = s.read(reg.address, reg.size)
    assert err == ErrorNumber.NONE
    return reg.decode(data)


def _write(s: EmulatedServo, name: str, value: int) -> ErrorNumber:
    reg = s.table[name]
    return s.write(reg.address, reg.encode(value))


def test_a_reversed_servo_reports_the_bit_and_counts_the_other_way() -> None:
    s = EmulatedServo(MX106_P2, 1, 30.0, 2000.0, 0.0, drive_mode=DRIVE_MODE_REVERSE)
    assert s.get("drive_mode") & 1 and s.reversed
    assert _present(s) == reversed_zero(T) - 2000 == 2095
    assert s.get("goal_position") == 2095  # the goal follows, in the same frame
    s.place(2010.0)  # the shaft turns +10 counts: the register goes down by 10
    assert _present(s) == 2085
    # torque off: Drive Mode is EEPROM and writable; cleared, the servo counts as built
    assert _write(s, "drive_mode", 0) == ErrorNumber.NONE
    assert not s.reversed and _present(s) == 2010


def test_a_reversed_servo_moves_to_its_goal_in_its_own_frame() -> None:
    s = EmulatedServo(MX106_P2, 1, 30.0, 2000.0, 0.0, drive_mode=DRIVE_MODE_REVERSE)
    assert _write(s, "goal_position", 2095 - 50) == ErrorNumber.NONE
    assert _write(s, "torque_enable", 1) == ErrorNumber.NONE
    s.advance(2.0)  # eq. (27) with p = 30: settled
    assert _present(s) == 2045 and round(s.pos) == 2050  # the count went up by 50
    assert _write(s, "drive_mode", 0) == ErrorNumber.ACCESS  # EEPROM with torque on


def test_homing_offset_is_added_to_present_position() -> None:
    s = EmulatedServo(MX106_P2, 1, 30.0, 2000.0, 0.0)
    assert _write(s, "homing_offset", -300) == ErrorNumber.NONE
    assert _present(s) == 1700
    assert _write(s, "drive_mode", DRIVE_MODE_REVERSE) == ErrorNumber.NONE
    assert _present(s) == reversed_zero(T) - 2000 - 300
    assert _write(s, "homing_offset", MAX_HOMING_OFFSET + 1) == ErrorNumber.DATA_RANGE
    assert _write(s, "homing_offset", -MAX_HOMING_OFFSET) == ErrorNumber.NONE


def test_a_servo_as_shipped_is_unchanged() -> None:
    """Drive Mode 0, Homing Offset 0: the registers are the count (the 1.0 firmware's too)."""
    for table in (MX106_P2, MX106_P1):
        s = EmulatedServo(table, 1, 30.0, 1234.4, 0.0)
        assert s.register(1234.4) == 1234.4 and s.count(77.0) == 77.0
        assert s.present_ticks() == 1234 and s.get("goal_position") == 1234
