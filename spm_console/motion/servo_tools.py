"""Servo health and maintenance tools on an open bus: what the vendor's wizard gives every
operator, run by the motion process (the one owner of the port) between motions.

* :func:`read_health` — per joint: position (deg), current (A, Protocol 2.0) or load (% of
  the maximum torque, Protocol 1.0), temperature (°C), input voltage (V), Torque Enable and
  the hardware-error bits with their names. Sync reads of the three servos; when one fails
  every servo is read alone, so a silent one shows as "no reply" and the others still show.
* :func:`set_joint_torque` — Torque Enable of one joint; "on" first writes the joint's goal
  to its present position (and clears a tripped Bus Watchdog), so nothing lunges.
* :func:`reboot_joint` — REBOOT (Protocol 2.0) to clear a latched hardware error; the servo
  comes back with torque off and its goal at its present position.
* :func:`jog_target` — the target of a one-joint jog, refused outside the servo limits. The
  jog itself is an ordinary motion (a straight line plan executed by the runtime).

Degrees, seconds, volts, amperes, °C.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from spm_console.devices.base import SETUP_QUIET_S, CommError
from spm_console.devices.dynamixel.bus import DynamixelBus
from spm_console.devices.dynamixel.control_table import describe_hardware_error
from spm_console.errors import BadInputError, BusError, SpmError

F = NDArray[np.float64]
T = TypeVar("T")

#: Tries of each status read before a servo counts as silent.
READ_ATTEMPTS = 3
#: MX-106(2.0) Present Current unit, A (e-manual: 3.36 mA).
CURRENT_UNIT_A = 0.00336
#: MX-106 (1.0) Present Load unit, % of the maximum torque (e-manual: 0.1 %).
LOAD_UNIT_PCT = 0.1
#: Present (Input) Voltage unit, V (both protocols).
VOLTAGE_UNIT_V = 0.1
#: How long a rebooted servo may take to answer again, s.
REBOOT_WAIT_S = 2.0
#: Largest jog step, deg (a typo such as 100 for 1.00 is refused, not executed).
JOG_MAX_STEP_DEG = 10.0


@dataclass(frozen=True)
class JointHealth:
    """One joint's servo as read now. ``replied`` False: the servo did not answer (every
    other field but ``joint`` and ``id`` is then None)."""

    joint: int
    """1-based joint number."""
    id: int
    replied: bool = True
    position_deg: float | None = None
    torque_on: bool | None = None
    current_a: float | None = None
    """Present Current, A, signed (Protocol 2.0; None on 1.0)."""
    load_pct: float | None = None
    """Present Load, % of the maximum torque, + counter-clockwise (Protocol 1.0; None on 2.0)."""
    temperature_c: float | None = None
    voltage_v: float | None = None
    hardware_error: int | None = None
    """Hardware-error bits (2.0: Hardware Error Status; 1.0: the status packet's error bits)."""
    hardware_error_text: str = ""
    """Their names ("none" when no bit is set), from ``describe_hardware_error``."""

    @property
    def load_text(self) -> str:
        """'+0.12 A' or '-3.4 %' (the joint's own unit), or 'no reply'."""
        if self.current_a is not None:
            return f"{self.current_a:+.2f} A"
        if self.load_pct is not None:
            return f"{self.load_pct:+.1f} %"
        return "no reply"

    @property
    def hardware_text(self) -> str:
        """'none', '0x20 overload', or 'no reply'."""
        if self.hardware_error is None:
            return "no reply"
        if self.hardware_error == 0:
            return "none"
        return f"0x{self.hardware_error:02x} {self.hardware_error_text}"


@dataclass(frozen=True)
class ServoHealth:
    """The three joints' servos, in joint order, read at ``read_at`` (time.monotonic, s)."""

    joints: tuple[JointHealth, ...]
    protocol: str
    read_at: float

    @property
    def position_deg(self) -> F | None:
        """θ (deg) when every servo replied, else None."""
        pos = [j.position_deg for j in self.joints]
        if any(p is None for p in pos):
            return None
        return np.array(pos, float)

    @property
    def silent(self) -> list[int]:
        """Joints whose servo did not answer."""
        return [j.joint for j in self.joints if not j.replied]

    @property
    def faulted(self) -> list[int]:
        """Joints with a hardware-error bit set."""
        return [j.joint for j in self.joints if j.hardware_error]


def _settled(bus: DynamixelBus, fn: Callable[[], T]) -> T:
    """``fn`` with set-up retries (the line drained between tries); the last error raised."""
    for k in range(READ_ATTEMPTS):
        try:
            return fn()
        except (CommError, OSError):
            if k == READ_ATTEMPTS - 1:
                raise
            bus.drain_input(SETUP_QUIET_S)
    raise AssertionError("unreachable")


def _names(protocol: str) -> tuple[str, str]:
    """(load register, voltage register) of the protocol."""
    if protocol == "2.0":
        return "present_current", "present_input_voltage"
    return "present_load", "present_voltage"


def _joint(bus: DynamixelBus, k: int, values: dict[str, int], hw: int) -> JointHealth:
    m = bus.maps[k]
    load_reg, _ = _names(bus.protocol)
    load = values[load_reg]
    if bus.protocol == "2.0":
        current: float | None = load * CURRENT_UNIT_A
        pct: float | None = None
    else:  # bits 0..9 magnitude, bit 10 set: clockwise
        current, pct = None, (load & 0x3FF) * LOAD_UNIT_PCT * (-1 if load & 0x400 else 1)
    return JointHealth(
        joint=m.joint, id=m.id, position_deg=m.to_deg(values["present_position"]),
        torque_on=bool(values["torque_enable"]), current_a=current, load_pct=pct,
        temperature_c=float(values["present_temperature"]),
        voltage_v=values[_names(bus.protocol)[1]] * VOLTAGE_UNIT_V,
        hardware_error=hw, hardware_error_text=describe_hardware_error(hw, bus.protocol))


def _registers(protocol: str) -> tuple[str, ...]:
    return ("present_position", "torque_enable", *_names(protocol), "present_temperature")


def read_health(bus: DynamixelBus) -> ServoHealth:
    """Every joint's health (see module docstring). BusError only when no servo answers."""
    names = _registers(bus.protocol)
    try:
        columns = {n: _settled(bus, functools.partial(bus.sync_read, n)) for n in names}
        hws = _settled(bus, bus.hardware_errors)
        joints = tuple(_joint(bus, k, {n: columns[n][k] for n in names}, hws[k])
                       for k in range(len(bus.maps)))
    except (CommError, OSError, SpmError):
        joints = tuple(_alone(bus, k) for k in range(len(bus.maps)))
        if not any(j.replied for j in joints):
            raise BusError(f"no servo answered a status read on {bus.port}; check power, "
                           "wiring, baud rate and ids (`spm-console servo ping`)") from None
    return ServoHealth(joints, bus.protocol, time.monotonic())


def _alone(bus: DynamixelBus, k: int) -> JointHealth:
    """One servo read by itself: 'no reply' when it stays silent."""
    ident = bus.maps[k].id
    try:
        values = {n: _settled(bus, functools.partial(bus.read, ident, n))
                  for n in _registers(bus.protocol)}
        if bus.protocol == "2.0":
            hw = _settled(bus, lambda: bus.read(ident, "hardware_error_status"))
        else:  # the status byte of the reads just made
            hw = bus.alerts.get(ident, 0)
    except (CommError, OSError, SpmError):
        return JointHealth(joint=bus.maps[k].joint, id=ident, replied=False)
    return _joint(bus, k, values, hw)


def joint_index(bus: DynamixelBus, joint: int) -> int:
    """0-based index of a 1-based joint number; BadInputError otherwise."""
    if not 1 <= joint <= len(bus.maps):
        raise BadInputError(f"joint {joint}: expected 1 to {len(bus.maps)}")
    return joint - 1


def set_joint_torque(bus: DynamixelBus, joint: int, on: bool) -> None:
    """Torque Enable of one joint. On: goal := present position first (a tripped Bus
    Watchdog cleared on 2.0, since it refuses goals), so the joint holds where it is."""
    ident = bus.maps[joint_index(bus, joint)].id
    try:
        if on:
            present = _settled(bus, lambda: bus.read(ident, "present_position"))
            if bus.protocol == "2.0" and _settled(bus, lambda: bus.read(ident, "bus_watchdog")) < 0:
                _settled(bus, lambda: bus.write(ident, "bus_watchdog", 0))
            _settled(bus, lambda: bus.write(ident, "goal_position", present))
        _settled(bus, lambda: bus.set_torque(on, [ident]))
    except (CommError, OSError) as exc:
        raise BusError(f"joint {joint} (servo id {ident}): torque {'on' if on else 'off'} "
                       f"failed after {READ_ATTEMPTS} tries ({exc})") from None
    except BusError as exc:
        hint = (" — a latched hardware error keeps torque off: reboot the servo first"
                if on and bus.alerts.get(ident) else "")
        raise BusError(exc.message + hint) from None


def reboot_joint(bus: DynamixelBus, joint: int, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
    """REBOOT one joint's servo (Protocol 2.0) and wait until it answers a ping again
    (``clock`` and ``sleep``: the wall clock's, or a simulated clock's in lockstep)."""
    ident = bus.maps[joint_index(bus, joint)].id
    try:
        _settled(bus, lambda: bus.reboot([ident]))
    except (CommError, OSError) as exc:
        raise BusError(f"joint {joint} (servo id {ident}): no answer to REBOOT ({exc})") from None
    t_end = clock() + REBOOT_WAIT_S
    while True:
        try:
            bus.ping(ident)
            return
        except BusError:
            if clock() > t_end:
                raise BusError(f"joint {joint} (servo id {ident}) did not answer within "
                               f"{REBOOT_WAIT_S:g} s of its reboot") from None
            sleep(0.05)


def jog_target(theta_deg: Sequence[float] | F, joint: int, step_deg: float,
               limits_deg: tuple[F, F]) -> F:
    """θ (deg) with ``joint`` (1-based) moved by ``step_deg``; BadInputError for a step that
    is not finite, zero or larger than :data:`JOG_MAX_STEP_DEG`, or a target outside the
    joint's servo limits (refused, never clamped)."""
    theta = np.asarray(theta_deg, float).reshape(-1)
    if theta.shape != (3,) or not np.all(np.isfinite(theta)):
        raise BadInputError(f"jog: the present position {theta.tolist()} is not three angles")
    if not 1 <= joint <= 3:
        raise BadInputError(f"jog: joint {joint}: expected 1, 2 or 3")
    if not np.isfinite(step_deg) or step_deg == 0.0 or abs(step_deg) > JOG_MAX_STEP_DEG:
        raise BadInputError(f"jog: step {step_deg:g}° must be non-zero and at most "
                            f"{JOG_MAX_STEP_DEG:g}° in size")
    lo, hi = float(limits_deg[0][joint - 1]), float(limits_deg[1][joint - 1])
    target = theta.copy()
    target[joint - 1] += step_deg
    if not lo <= target[joint - 1] <= hi:
        raise BadInputError(
            f"jog: joint {joint} from {theta[joint - 1]:.2f}° by {step_deg:+g}° would reach "
            f"{target[joint - 1]:.2f}°, outside its servo limits [{lo:g}, {hi:g}]°; refused, "
            "nothing moved")
    return target
