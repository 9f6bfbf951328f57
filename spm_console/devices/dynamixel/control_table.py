"""MX-106 control tables kept as data (vendor e-manual, MX-106(2.0) and MX-106 pages).

Each register: name -> :class:`Register` (address, size in bytes, access, signed,
initial value at power-on or ``None`` when it is a live value). The bus reads and
writes registers by name; the emulator builds its memory from the same table.
Addresses below ``eeprom_end`` are EEPROM: writable only while Torque Enable is 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Access = Literal["R", "RW"]


@dataclass(frozen=True)
class Register:
    """One control-table item."""

    address: int
    size: int
    """Bytes (1, 2 or 4), little-endian on the wire."""
    access: Access
    signed: bool = False
    initial: int | None = None
    """Power-on value (None: a live value the servo computes)."""

    def encode(self, value: int) -> bytes:
        """Value -> little-endian bytes; ValueError when it does not fit."""
        return int(value).to_bytes(self.size, "little", signed=self.signed)

    def decode(self, data: bytes) -> int:
        if len(data) != self.size:
            raise ValueError(f"expected {self.size} bytes, got {len(data)}")
        return int.from_bytes(data, "little", signed=self.signed)

    def fits(self, value: int) -> bool:
        bits = 8 * self.size
        if self.signed:
            return -(1 << (bits - 1)) <= value < (1 << (bits - 1))
        return 0 <= value < (1 << bits)


@dataclass(frozen=True)
class ControlTable:
    """The control table of one servo model under one protocol."""

    model: str
    model_number: int
    protocol: Literal["1.0", "2.0"]
    eeprom_end: int
    """First RAM address; addresses below are EEPROM (torque must be off to write)."""
    size: int
    """Bytes of memory the emulator allocates."""
    registers: dict[str, Register]

    def __getitem__(self, name: str) -> Register:
        try:
            return self.registers[name]
        except KeyError:
            raise KeyError(f"{self.model} ({self.protocol}) has no register {name!r}") from None

    def at(self, address: int) -> tuple[str, Register] | None:
        """The register starting at ``address``, if any."""
        for name, reg in self.registers.items():
            if reg.address == address:
                return name, reg
        return None


def _r(address: int, size: int, access: Access, signed: bool = False,
       initial: int | None = None) -> Register:
    return Register(address, size, access, signed, initial)


#: MX-106 with Protocol 2.0 firmware (model 321), e-manual "MX-106(2.0)" control table.
MX106_P2 = ControlTable(
    model="MX-106(2.0)", model_number=321, protocol="2.0", eeprom_end=64, size=147,
    registers={
        "model_number": _r(0, 2, "R", initial=321),
        "model_information": _r(2, 4, "R", initial=0),
        "firmware_version": _r(6, 1, "R", initial=45),
        "id": _r(7, 1, "RW", initial=1),
        "baud_rate": _r(8, 1, "RW", initial=1),
        "return_delay_time": _r(9, 1, "RW", initial=250),
        "drive_mode": _r(10, 1, "RW", initial=0),
        "operating_mode": _r(11, 1, "RW", initial=3),
        "secondary_id": _r(12, 1, "RW", initial=255),
        "protocol_type": _r(13, 1, "RW", initial=2),
        "homing_offset": _r(20, 4, "RW", signed=True, initial=0),
        "moving_threshold": _r(24, 4, "RW", initial=10),
        "temperature_limit": _r(31, 1, "RW", initial=80),
        "max_voltage_limit": _r(32, 2, "RW", initial=160),
        "min_voltage_limit": _r(34, 2, "RW", initial=95),
        "pwm_limit": _r(36, 2, "RW", initial=885),
        "current_limit": _r(38, 2, "RW", initial=2047),
        "acceleration_limit": _r(40, 4, "RW", initial=32767),
        "velocity_limit": _r(44, 4, "RW", initial=360),
        "max_position_limit": _r(48, 4, "RW", initial=4095),
        "min_position_limit": _r(52, 4, "RW", initial=0),
        "shutdown": _r(63, 1, "RW", initial=52),
        "torque_enable": _r(64, 1, "RW", initial=0),
        "led": _r(65, 1, "RW", initial=0),
        "status_return_level": _r(68, 1, "RW", initial=2),
        "registered_instruction": _r(69, 1, "R", initial=0),
        "hardware_error_status": _r(70, 1, "R", initial=0),
        "velocity_i_gain": _r(76, 2, "RW", initial=1920),
        "velocity_p_gain": _r(78, 2, "RW", initial=100),
        "position_d_gain": _r(80, 2, "RW", initial=0),
        "position_i_gain": _r(82, 2, "RW", initial=0),
        "position_p_gain": _r(84, 2, "RW", initial=850),
        "feedforward_2nd_gain": _r(88, 2, "RW", initial=0),
        "feedforward_1st_gain": _r(90, 2, "RW", initial=0),
        "bus_watchdog": _r(98, 1, "RW", signed=True, initial=0),
        "goal_pwm": _r(100, 2, "RW", signed=True),
        "goal_current": _r(102, 2, "RW", signed=True),
        "goal_velocity": _r(104, 4, "RW", signed=True),
        "profile_acceleration": _r(108, 4, "RW", initial=0),
        "profile_velocity": _r(112, 4, "RW", initial=0),
        "goal_position": _r(116, 4, "RW", signed=True),
        "realtime_tick": _r(120, 2, "R"),
        "moving": _r(122, 1, "R", initial=0),
        "moving_status": _r(123, 1, "R", initial=0),
        "present_pwm": _r(124, 2, "R", signed=True),
        "present_current": _r(126, 2, "R", signed=True),
        "present_velocity": _r(128, 4, "R", signed=True),
        "present_position": _r(132, 4, "R", signed=True),
        "velocity_trajectory": _r(136, 4, "R", signed=True),
        "position_trajectory": _r(140, 4, "R", signed=True),
        "present_input_voltage": _r(144, 2, "R"),
        "present_temperature": _r(146, 1, "R"),
    },
)

#: MX-106 with Protocol 1.0 firmware (model 320), e-manual "MX-106" control table.
MX106_P1 = ControlTable(
    model="MX-106", model_number=320, protocol="1.0", eeprom_end=24, size=74,
    registers={
        "model_number": _r(0, 2, "R", initial=320),
        "firmware_version": _r(2, 1, "R", initial=41),
        "id": _r(3, 1, "RW", initial=1),
        "baud_rate": _r(4, 1, "RW", initial=34),
        "return_delay_time": _r(5, 1, "RW", initial=250),
        "cw_angle_limit": _r(6, 2, "RW", initial=0),
        "ccw_angle_limit": _r(8, 2, "RW", initial=4095),
        "drive_mode": _r(10, 1, "RW", initial=0),
        "temperature_limit": _r(11, 1, "RW", initial=80),
        "min_voltage_limit": _r(12, 1, "RW", initial=60),
        "max_voltage_limit": _r(13, 1, "RW", initial=160),
        "max_torque": _r(14, 2, "RW", initial=1023),
        "status_return_level": _r(16, 1, "RW", initial=2),
        "alarm_led": _r(17, 1, "RW", initial=36),
        "shutdown": _r(18, 1, "RW", initial=36),
        "multi_turn_offset": _r(20, 2, "RW", signed=True, initial=0),
        "resolution_divider": _r(22, 1, "RW", initial=1),
        "torque_enable": _r(24, 1, "RW", initial=0),
        "led": _r(25, 1, "RW", initial=0),
        "d_gain": _r(26, 1, "RW", initial=0),
        "i_gain": _r(27, 1, "RW", initial=0),
        "p_gain": _r(28, 1, "RW", initial=32),
        "goal_position": _r(30, 2, "RW"),
        "moving_speed": _r(32, 2, "RW", initial=0),
        "torque_limit": _r(34, 2, "RW", initial=1023),
        "present_position": _r(36, 2, "R"),
        "present_speed": _r(38, 2, "R"),
        "present_load": _r(40, 2, "R"),
        "present_voltage": _r(42, 1, "R"),
        "present_temperature": _r(43, 1, "R"),
        "registered": _r(44, 1, "R", initial=0),
        "moving": _r(46, 1, "R", initial=0),
        "lock": _r(47, 1, "RW", initial=0),
        "punch": _r(48, 2, "RW", initial=0),
        "current": _r(68, 2, "RW", initial=0),
        "torque_ctrl_mode_enable": _r(70, 1, "RW", initial=0),
        "goal_torque": _r(71, 2, "RW", initial=0),
        "goal_acceleration": _r(73, 1, "RW", initial=0),
    },
)

#: Hardware Error Status bits (2.0, address 70) and what they mean.
HARDWARE_ERROR_BITS_P2 = {
    0: "input voltage error",
    2: "overheating",
    3: "motor encoder error",
    4: "electrical shock",
    5: "overload",
}

#: Status-packet error bits of Protocol 1.0 and what they mean.
STATUS_ERROR_BITS_P1 = {
    0: "input voltage error",
    1: "angle limit error",
    2: "overheating",
    3: "range error",
    4: "checksum error",
    5: "overload",
    6: "instruction error",
}

#: Of the 1.0 status error bits, those that are hardware faults (voltage, overheat, overload).
HARDWARE_MASK_P1 = 0b0010_0101


def table_for(protocol: str) -> ControlTable:
    """The MX-106 control table for protocol '1.0' or '2.0'."""
    return MX106_P2 if protocol == "2.0" else MX106_P1


def describe_bits(bits: int, names: dict[int, str]) -> str:
    """'overload, overheating' for a bit field (or 'none')."""
    found = [text for bit, text in sorted(names.items()) if bits & (1 << bit)]
    unknown = bits & ~sum(1 << b for b in names)
    if unknown:
        found.append(f"unknown bits 0x{unknown:02X}")
    return ", ".join(found) or "none"


def describe_hardware_error(bits: int, protocol: str) -> str:
    """The names of a joint's hardware-error bits: Hardware Error Status (2.0) or the status
    byte's error bits (1.0). The one owner of these names."""
    return describe_bits(bits, HARDWARE_ERROR_BITS_P2 if protocol == "2.0" else STATUS_ERROR_BITS_P1)
