"""One emulated MX-106: control-table memory and the closed-loop model (27), or its joint of
the physical wrist (:mod:`spm_console.devices.emulator.physical`) when it has one.

Position in ticks follows θ̈ = p²(θ* − θ) − 2p θ̇ (double pole at −p) with the Goal
Position θ* held constant between writes (zero-order hold), integrated exactly
in closed form. Present Position is the true position (plus optional noise)
rounded to a whole tick. Torque off, a stall or a hardware-error shutdown freeze
the shaft. Protocol-independent: the dispatch modules turn packets into
:meth:`read` / :meth:`write` calls and error numbers into status bits.

The state is the encoder's own count (Drive Mode 0, Homing Offset 0); on the Protocol 2.0
firmware the registers hold it as the e-manual's MX-106(2.0) control table says: Drive Mode
(address 10) bit 0 set reverses the direction, and Homing Offset (address 20) is added to
Present Position (Goal Position is in the same frame), so
register = s·count + base + homing_offset, with s = −1 and base = ticks_per_turn − 1 when
reversed (the e-manual does not say where the reversed count's zero lies: mirrored within one
turn here, 0 ↔ 4095, so a position in the servo's range stays in it), s = 1 and base = 0
otherwise. Both are EEPROM: written with torque off only.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from spm_console.core.servo.model import Pole, dynamics, exact_step
from spm_console.devices.dynamixel.control_table import ControlTable
from spm_console.devices.dynamixel.protocol2 import ErrorNumber
from spm_console.devices.emulator.plant_joint import PlantJoint

if TYPE_CHECKING:  # the physical wrist loads MuJoCo: only a servo on it needs its types
    from spm_console.devices.emulator.physical import DriveGains

#: Hardware Error Status bit 5 (overload) — what a stalled, overloaded servo reports.
OVERLOAD = 0x20
#: Drive Mode (address 10) bit 0: reverse mode, the servo counts the other way.
DRIVE_MODE_REVERSE = 0x01
#: Largest |Homing Offset| the MX-106(2.0) accepts, ticks (e-manual: ±1,044,479).
MAX_HOMING_OFFSET = 1_044_479


def reversed_zero(ticks_per_turn: int) -> int:
    """In reverse mode (Homing Offset 0), a count plus its register value: the count mirrored
    within one turn (assumed; the e-manual does not say where the reversed count's zero lies)."""
    return ticks_per_turn - 1


class EmulatedServo:
    """State and memory of one servo. Not thread-safe: the emulator holds a lock."""

    def __init__(self, table: ControlTable, ident: int, p: Pole, position_ticks: float,
                 t: float, noise_ticks: float = 0.0, rng: np.random.Generator | None = None,
                 ticks_per_turn: int = 4096, joint: PlantJoint | None = None,
                 drive_mode: int = 0) -> None:
        """``position_ticks``: the encoder's count (Drive Mode 0, Homing Offset 0);
        ``drive_mode``: the Drive Mode register at power-on (Protocol 2.0; bit 0: reverse)."""
        self.table = table
        self.joint = joint
        """The physical wrist's joint this servo drives (None: eq. (27) in closed form)."""
        self.dynamics = dynamics(p)
        """The closed-loop model the ideal servo is (eq. (27) for a bare p; its delay is not
        emulated)."""
        self.noise_ticks = noise_ticks
        self.rng = rng or np.random.default_rng(0)
        self.ticks_per_turn = ticks_per_turn
        self.mem = bytearray(table.size)
        for name, reg in table.registers.items():
            if reg.initial is not None:
                self._set(name, reg.initial)
        self._set("id", ident)
        self._set("return_delay_time", 0)  # [lab setting] the project sets Return Delay Time 0
        self._sign = 1
        self._base = 0
        """The register frame: register = _sign·count + _base (Homing Offset included)."""
        if table.protocol == "2.0":
            self._set("drive_mode", drive_mode)
        self._frame()
        self.pos = float(position_ticks)
        """The encoder's count, ticks (the register frame of Drive Mode 0, Homing Offset 0)."""
        self.vel = 0.0
        """Its rate, ticks/s."""
        self.t = t
        self.stalled = False
        self.hw_error = 0
        self.last_rx = t
        self._set("goal_position", round(self.register(self.pos)))
        self._command()

    # --- memory -----------------------------------------------------------------------

    def _set(self, name: str, value: int) -> None:
        reg = self.table[name]
        self.mem[reg.address : reg.address + reg.size] = reg.encode(value)

    def get(self, name: str) -> int:
        reg = self.table[name]
        return reg.decode(bytes(self.mem[reg.address : reg.address + reg.size]))

    # --- the register frame (Drive Mode, Homing Offset) ---------------------------------

    def _frame(self) -> None:
        """The register frame from Drive Mode and Homing Offset (Protocol 2.0; 1.0: the count)."""
        if self.table.protocol != "2.0":
            return
        reverse = bool(self.get("drive_mode") & DRIVE_MODE_REVERSE)
        self._sign = -1 if reverse else 1
        self._base = ((reversed_zero(self.ticks_per_turn) if reverse else 0)
                      + self.get("homing_offset"))

    def register(self, count: float) -> float:
        """The register value (Present/Goal Position) of an encoder count, ticks."""
        return self._sign * count + self._base if self._sign < 0 or self._base else count

    def count(self, register: float) -> float:
        """The encoder count of a register value (Present/Goal Position), ticks."""
        return self._sign * (register - self._base) if self._sign < 0 or self._base else register

    @property
    def reversed(self) -> bool:
        """Whether Drive Mode's reverse bit is set (the registers count the other way)."""
        return self._sign < 0

    @property
    def id(self) -> int:
        return self.get("id")

    @property
    def torque(self) -> bool:
        return self.get("torque_enable") != 0

    @property
    def moving_freely(self) -> bool:
        return self.torque and not self.stalled and not self.hw_error

    # --- dynamics ---------------------------------------------------------------------

    def advance(self, t: float) -> None:
        """Integrate exactly from self.t to t with the goal held (ZOH)."""
        if t <= self.t:
            return
        self._watchdog(t)
        if self.joint is not None:
            self.t = t
            self.pos, self.vel = self.joint.follow(t)
            if self.torque and self.joint.overloaded():
                self.raise_hardware_error(OVERLOAD)  # the firmware's overload shutdown
            return
        dt = t - self.t
        self.t = t
        if not self.moving_freely:
            self.vel = 0.0
            return
        u = self.count(float(self.get("goal_position")))
        if self.dynamics.zeta != 1.0:
            Phi, Gam = exact_step(self.dynamics, dt)
            self.pos, self.vel = (Phi[0, 0] * self.pos + Phi[0, 1] * self.vel + Gam[0] * u,
                                  Phi[1, 0] * self.pos + Phi[1, 1] * self.vel + Gam[1] * u)
            return
        p = self.dynamics.wn
        z0, v0 = self.pos - u, self.vel
        c2 = v0 + p * z0
        e = math.exp(-p * dt)
        self.pos = u + (z0 + c2 * dt) * e
        self.vel = (v0 - p * c2 * dt) * e

    def _watchdog(self, t: float) -> None:
        if "bus_watchdog" not in self.table.registers:
            return
        w = self.get("bus_watchdog")
        if w <= 0 or not self.torque:
            return
        trip = self.last_rx + 0.02 * w
        if t > trip:
            self.advance(trip)  # move with the old goal up to the trip time
            self._set("bus_watchdog", -1)
            self._set("goal_position", round(self.register(self.pos)))
            self._command()

    def stall(self) -> None:
        """The shaft is blocked from now on (call advance() to the stall time first)."""
        self.stalled = True
        self.vel = 0.0
        self._command()

    def raise_hardware_error(self, bits: int = OVERLOAD) -> None:
        """Hardware error shutdown: latch the bits, torque off."""
        self.hw_error |= bits
        if "hardware_error_status" in self.table.registers:
            self._set("hardware_error_status", self.hw_error)
        self._set("torque_enable", 0)
        self.vel = 0.0
        self._command()

    def reboot(self) -> None:
        """REBOOT: clears the hardware error, torque off, goal = present position."""
        self.hw_error = 0
        if "hardware_error_status" in self.table.registers:
            self._set("hardware_error_status", 0)
        self._set("torque_enable", 0)
        if "bus_watchdog" in self.table.registers:
            self._set("bus_watchdog", 0)
        self._set("goal_position", round(self.register(self.pos)))
        self.vel = 0.0
        self._command()

    def place(self, position_ticks: float) -> None:
        """Put the shaft somewhere (at rest; an encoder count, ticks); the goal follows so
        torque-on does not lunge."""
        self.pos = float(position_ticks)
        self.vel = 0.0
        self._set("goal_position", round(self.register(self.pos)))
        self._command()

    def _command(self) -> None:
        """Hand the goal and the drive's state to the physical wrist (when there is one)."""
        if self.joint is not None:
            # a blocked shaft still feels its drive (and overloads it); torque off or a
            # hardware error leave the drive off
            drive_on = self.torque and not self.hw_error
            self.joint.command(self.count(float(self.get("goal_position"))), drive_on,
                               self.stalled, self._gains())

    def _gains(self) -> DriveGains | None:
        """The position loop's gains as the driver wrote them (Protocol 2.0 registers); None on
        the 1.0 firmware (the physical wrist keeps its power-on loop)."""
        if "position_p_gain" not in self.table.registers:
            return None
        from spm_console.devices.emulator.physical import DriveGains  # loads MuJoCo

        return DriveGains(self.get("position_p_gain"), self.get("position_i_gain"),
                          self.get("position_d_gain"), self.get("pwm_limit"))

    def present_ticks(self) -> int:
        """Present Position: the count (plus noise) in the register frame, a whole tick."""
        noise = self.rng.normal(0.0, self.noise_ticks) if self.noise_ticks > 0 else 0.0
        return round(self.register(self.pos + noise))

    def _refresh(self) -> None:
        """Live registers from the state (before a read)."""
        rpm = self._sign * self.vel / self.ticks_per_turn * 60.0
        moving = abs(rpm) > 10 * 0.229
        if self.table.protocol == "2.0":
            self._set("present_position", self.present_ticks())
            self._set("present_velocity", round(rpm / 0.229))
            # profile velocity/acceleration 0: the trajectory is the goal itself, at rest
            self._set("position_trajectory", self.get("goal_position"))
            self._set("velocity_trajectory", 0)
            self._set("moving", int(moving))
            self._set("present_input_voltage", 120)
            self._set("present_temperature", 35)
            self._set("realtime_tick", int(self.t * 1000) % 32768)
            self._set("present_current", 0 if self.joint is None else self.joint.current_units())
            if self.joint is not None:
                self._set("present_pwm", self.joint.pwm())
        else:
            self._set("present_position", min(max(self.present_ticks(), 0), 4095))
            speed = min(round(abs(rpm) / 0.114), 1023) | (1024 if rpm < 0 else 0)
            self._set("present_speed", speed)
            self._set("moving", int(moving))
            self._set("present_voltage", 120)
            self._set("present_temperature", 35)
            self._set("present_load", 0)

    # --- register access --------------------------------------------------------------

    def read(self, address: int, length: int) -> tuple[ErrorNumber, bytes]:
        if length <= 0 or address < 0 or address + length > self.table.size:
            return ErrorNumber.ACCESS, b""
        self._refresh()
        return ErrorNumber.NONE, bytes(self.mem[address : address + length])

    def write(self, address: int, data: bytes) -> ErrorNumber:
        """Write like the firmware: whole registers only, RW only, EEPROM with torque off."""
        end = address + len(data)
        if not data or address < 0 or end > self.table.size:
            return ErrorNumber.ACCESS
        touched = []
        for name, reg in self.table.registers.items():
            r0, r1 = reg.address, reg.address + reg.size
            if r1 <= address or r0 >= end:
                continue
            if r0 < address or r1 > end:
                return ErrorNumber.DATA_LENGTH
            if reg.access != "RW":
                return ErrorNumber.ACCESS
            if r0 < self.table.eeprom_end and self.torque:
                return ErrorNumber.ACCESS
            touched.append((name, reg, reg.decode(bytes(data[r0 - address : r1 - address]))))
        for name, _reg, value in touched:
            err = self._check(name, value)
            if err:
                return err
        for name, _reg, value in touched:
            self._apply(name, value)
        return ErrorNumber.NONE

    def _check(self, name: str, value: int) -> ErrorNumber:
        if name == "goal_position":
            if self.table.protocol == "2.0":
                if "bus_watchdog" in self.table.registers and self.get("bus_watchdog") < 0:
                    return ErrorNumber.DATA_RANGE
                lo, hi = self.get("min_position_limit"), self.get("max_position_limit")
            else:
                lo, hi = self.get("cw_angle_limit"), self.get("ccw_angle_limit")
            if not lo <= value <= hi:
                return ErrorNumber.DATA_LIMIT
        if name == "torque_enable" and value not in (0, 1):
            return ErrorNumber.DATA_RANGE
        if name == "torque_enable" and value == 1 and self.hw_error:
            return ErrorNumber.RESULT_FAIL
        if name == "bus_watchdog" and not (value == 0 or 1 <= value <= 127):
            return ErrorNumber.DATA_RANGE
        if name == "id" and not 0 <= value <= 252:
            return ErrorNumber.DATA_RANGE
        if name == "homing_offset" and not -MAX_HOMING_OFFSET <= value <= MAX_HOMING_OFFSET:
            return ErrorNumber.DATA_RANGE
        return ErrorNumber.NONE

    def _apply(self, name: str, value: int) -> None:
        if name == "torque_enable" and bool(value) != self.torque and self.joint is None:
            self.vel = 0.0
        self._set(name, value)
        if name in ("drive_mode", "homing_offset"):
            self._frame()  # the goal register now means another count: the wrist is told
        if name in ("goal_position", "torque_enable", "position_p_gain", "position_i_gain",
                    "position_d_gain", "pwm_limit", "drive_mode", "homing_offset"):
            self._command()
