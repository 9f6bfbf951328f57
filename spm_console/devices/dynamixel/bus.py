"""The Dynamixel servo bus: three MX-106 driving joints 1..3, angles in degrees.

:class:`DynamixelBus` implements :class:`spm_console.devices.base.ServoBus` over a
:class:`Transport` (a serial adapter, the emulator's pty or its socket), in Protocol 2.0
or 1.0 as the profile says. Registers are addressed by name from the control
table (``devices/dynamixel/control_table.py``). Joint angles map to ticks per joint
(offset, direction) and a goal outside the joint's limits is refused with
:class:`LimitError` — never clamped. A failed transaction (timeout, corrupt or
unexpected reply) raises :class:`CommError`; an absent servo, a wrong model or an
error reported by a servo raises :class:`BusError`. A late reply to an earlier request
is never taken for the current one: it fails the transaction it lands in and is counted
in :attr:`DynamixelBus.stale_replies` (how: ``devices/dynamixel/link.py``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.devices.base import CommError, ServoStatus
from spm_console.devices.dynamixel.control_table import (
    ControlTable,
    describe_hardware_error,
    table_for,
)
from spm_console.devices.dynamixel.link import Link, Link1, Link2, Reply
from spm_console.devices.dynamixel.protocol2 import describe_error
from spm_console.devices.dynamixel.tick_map import JointMap, joint_maps
from spm_console.devices.dynamixel.transport import Transport, open_transport
from spm_console.errors import BadInputError, BusError
from spm_console.system.simclock import SimClock

T = TypeVar("T")

F = NDArray[np.float64]


class LimitError(BadInputError):
    """A goal outside a joint's software limits (or the servo's tick range): refused."""

    def __init__(self, message: str, joint: int, value_deg: float,
                 limits_deg: tuple[float, float]) -> None:
        super().__init__(message)
        self.joint = joint
        self.value_deg = value_deg
        self.limits_deg = limits_deg


#: Reply timeouts of the tries of a set-up transaction (ping, status read), s, before a
#: servo counts as absent: the link's own first, then more patient ones. One lost or slow
#: reply (a servo just powered, an emulated bus on a loaded machine) is not a missing servo;
#: set-up is not the real-time loop, so waiting costs nothing there.
SETUP_TIMEOUTS_S = (0.0, 0.05, 0.25)


#: Quiet time on the line before a set-up retry: late replies to the failed try drain first.
RETRY_QUIET_S = 0.02


def _retry(fn: Callable[[], T], transport: Transport,
           drain: Callable[[float], object]) -> T:
    """Call ``fn``, retrying with a longer reply timeout, once the line is quiet, when a
    reply is lost (CommError). When every try fails, a CommError with the first one's
    message (what went wrong; a retry's own refusal, such as a reply length still reserved
    for the first try's late reply, is its consequence) and how often it was tried."""
    first: CommError | None = None
    for k, timeout_s in enumerate(SETUP_TIMEOUTS_S):
        try:
            with transport.patience(timeout_s):
                return fn()
        except CommError as exc:
            first = first or exc
            if k == len(SETUP_TIMEOUTS_S) - 1:
                raise CommError(f"{first}; tried {len(SETUP_TIMEOUTS_S)} times, each with "
                                "more patience") from None
            drain(RETRY_QUIET_S)
    raise AssertionError("unreachable")


class DynamixelBus:
    """Three servos on one serial port (see module docstring)."""

    def __init__(self, profile: Profile, transport: Transport) -> None:
        self.profile = profile
        self.transport = transport
        self.table: ControlTable = table_for(profile.bus.protocol)
        self.link: Link = (Link2(transport, self.table) if profile.bus.protocol == "2.0"
                           else Link1(transport, self.table))
        self.maps: list[JointMap] = joint_maps(profile)
        self.ids = [m.id for m in self.maps]
        self.alerts: dict[int, int] = {}
        """Hardware flags seen in the last status of each id (0 = none)."""

    @property
    def protocol(self) -> str:
        return self.profile.bus.protocol

    @property
    def stale_replies(self) -> int:
        """Status packets that were not the answer to the request in flight: late replies
        to earlier requests, or replies nothing asked for. One that lands while a request
        waits fails that transaction (CommError); one found waiting before a request goes
        out (or by a set-up drain) is discarded. Counts from the bus's opening."""
        return self.link.stale_replies

    @property
    def port(self) -> str:
        return self.transport.port

    def close(self) -> None:
        self.transport.close()

    def __enter__(self) -> DynamixelBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- helpers ----------------------------------------------------------------------

    def _note(self, r: Reply, what: str) -> Reply:
        self.alerts[r.id] = r.hardware
        if r.error_number:
            raise BusError(f"servo id {r.id} refused {what}: {describe_error(r.error_number)}")
        return r

    def _ids(self, ids: Sequence[int] | None) -> list[int]:
        return list(self.ids if ids is None else ids)

    # --- ping / status ----------------------------------------------------------------

    def set_up(self, fn: Callable[[], T]) -> T:
        """``fn``, a set-up transaction on this bus (a read, or a write of registers to values:
        done twice, the same), tried again with more patience once the line is quiet when its
        reply is lost (:data:`SETUP_TIMEOUTS_S`); the last CommError raised."""
        return _retry(fn, self.transport, self.drain_input)

    def ping(self, ident: int) -> ServoStatus:
        """Ping one id; BusError if it does not answer (after the tries of
        :data:`SETUP_TIMEOUTS_S`: one lost reply is not a missing servo) or is not the profile's model."""
        try:
            model, fw, r = self.ping_any(ident)
        except CommError as exc:
            raise BusError(
                f"no status packet from servo id {ident} on {self.port} ({exc}). Check power, "
                f"wiring, the id and the baud rate ({self.profile.bus.baud} bit/s, protocol "
                f"{self.protocol})"
            ) from None
        self.alerts[ident] = r.hardware
        want = self.profile.bus.model_number
        if model != want:
            raise BusError(f"servo id {ident} on {self.port} is model {model}, the profile "
                           f"expects {want} ({self.table.model})")
        return ServoStatus(id=ident, model_number=model, firmware=fw,
                           hardware_error=r.hardware & 0x7F if self.protocol == "1.0" else 0)

    def ping_any(self, ident: int) -> tuple[int, int | None, Reply]:
        """Ping one id with the tries of :data:`SETUP_TIMEOUTS_S`, whatever its model:
        (model number, firmware, status); CommError if it does not answer."""
        return _retry(lambda: self.link.ping(ident), self.transport, self.drain_input)

    def ping_all(self) -> list[ServoStatus]:
        """Ping every joint's servo and read its hardware error status."""
        out = []
        for ident in self.ids:
            st = self.ping(ident)
            hw = _retry(functools.partial(self._hardware_error, ident), self.transport,
                        self.drain_input)
            out.append(ServoStatus(id=st.id, model_number=st.model_number, firmware=st.firmware,
                                   hardware_error=hw))
        return out

    def _hardware_error(self, ident: int) -> int:
        if self.protocol == "2.0":
            return self.read(ident, "hardware_error_status")
        r = self.link.read(ident, self.table["present_temperature"].address, 1)
        self.alerts[ident] = r.hardware
        return r.hardware

    def hardware_errors(self) -> list[int]:
        """Hardware Error Status of each joint (2.0: one sync read of register 70; 1.0: the
        hardware bits of each servo's status byte)."""
        if self.protocol == "2.0":
            return self.sync_read("hardware_error_status")
        return [self._hardware_error(i) for i in self.ids]

    def describe_hardware_error(self, bits: int) -> str:
        return describe_hardware_error(bits, self.protocol)

    # --- registers by name ------------------------------------------------------------

    def read(self, ident: int, name: str) -> int:
        reg = self.table[name]
        r = self._note(self.link.read(ident, reg.address, reg.size), f"a read of {name}")
        return reg.decode(r.data)

    def write(self, ident: int, name: str, value: int) -> None:
        reg = self.table[name]
        if reg.access != "RW":
            raise BadInputError(f"{name} is read-only on the {self.table.model}")
        if not reg.fits(int(value)):
            raise BadInputError(f"{name} = {value} does not fit in {reg.size} byte(s)")
        self._note(self.link.write(ident, reg.address, reg.encode(int(value))),
                   f"{name} = {value}")

    def sync_write(self, name: str, values: dict[int, int]) -> None:
        reg = self.table[name]
        items = [(i, reg.encode(int(v))) for i, v in values.items()]
        self.link.sync_write(reg.address, reg.size, items)

    def sync_read(self, name: str, ids: Sequence[int] | None = None) -> list[int]:
        """Sync read (2.0) / bulk read (1.0) of one register from several ids."""
        reg = self.table[name]
        replies = self.link.read_many(reg.address, reg.size, self._ids(ids))
        return [reg.decode(self._note(r, f"a read of {name}").data) for r in replies]

    # --- motion -----------------------------------------------------------------------

    def set_torque(self, on: bool, ids: Sequence[int] | None = None) -> None:
        """Torque Enable on/off, one confirmed write per servo."""
        for ident in self._ids(ids):
            self.write(ident, "torque_enable", 1 if on else 0)

    def torque(self) -> list[bool]:
        return [bool(v) for v in self.sync_read("torque_enable")]

    def goal_ticks(self, theta_deg: Sequence[float] | F) -> list[int]:
        """Goal ticks for joint angles (deg); LimitError for anything outside the limits."""
        theta = np.asarray(theta_deg, float).reshape(-1)
        if theta.shape != (3,):
            raise BadInputError(f"expected three joint angles, got {theta.size}")
        out = []
        for m, th in zip(self.maps, theta, strict=True):
            if not math.isfinite(th):
                raise BadInputError(f"joint {m.joint}: goal {th} is not a finite angle")
            t = m.goal_ticks(float(th))
            if t is None:
                raise LimitError(
                    f"joint {m.joint} (servo id {m.id}): goal {th:.3f}° is outside its limits "
                    f"[{m.min_deg:g}, {m.max_deg:g}]° — refused, not clamped",
                    m.joint, float(th), (m.min_deg, m.max_deg))
            out.append(t)
        return out

    def write_goal_deg(self, theta_deg: Sequence[float] | F) -> None:
        """Sync-write Goal Position of the three joints (deg); refuses targets outside limits."""
        ticks = self.goal_ticks(theta_deg)
        self.sync_write("goal_position", dict(zip(self.ids, ticks, strict=True)))

    def read_ticks(self) -> list[int]:
        """Present Position of the three joints, ticks (CommError on a lost/corrupt reply)."""
        return self.sync_read("present_position")

    def read_position_deg(self) -> F:
        """Present Position of the three joints, deg (sync read on 2.0, bulk read on 1.0)."""
        ticks = self.read_ticks()
        return np.array([m.to_deg(t) for m, t in zip(self.maps, ticks, strict=True)])

    def drain_input(self, quiet_s: float) -> int:
        """Discard late input until the line is quiet for ``quiet_s``; bytes discarded."""
        return self.transport.drain(quiet_s, on_late=self.link.late_input)

    def hold(self) -> F:
        """Goal := measured position (stop where we are); returns that position (deg)."""
        ticks = self.read_ticks()
        self.sync_write("goal_position", dict(zip(self.ids, ticks, strict=True)))
        return np.array([m.to_deg(t) for m, t in zip(self.maps, ticks, strict=True)])

    # --- maintenance ------------------------------------------------------------------

    def reboot(self, ids: Sequence[int] | None = None) -> None:
        """REBOOT (2.0 only): clears a latched hardware error; torque comes back off."""
        if self.protocol != "2.0":
            raise BusError("Protocol 1.0 has no REBOOT instruction: power-cycle the servos")
        for ident in self._ids(ids):
            self._note(self.link.reboot(ident), "REBOOT")

    def set_watchdog(self, ms: int) -> int:
        """Bus Watchdog (2.0, unit 20 ms; 0 = off). Returns the units written (0 on 1.0)."""
        if self.protocol != "2.0":
            return 0
        if ms < 0:
            raise BadInputError(f"watchdog {ms} ms: must be ≥ 0")
        units = 0 if ms == 0 else min(127, max(1, round(ms / 20)))
        for ident in self.ids:
            if units and self.read(ident, "bus_watchdog") < 0:
                self.write(ident, "bus_watchdog", 0)  # clear a tripped watchdog first
            self.write(ident, "bus_watchdog", units)
        return units


def open_bus(profile: Profile, port: str, exclusive: bool = True,
             sim: SimClock | None = None) -> DynamixelBus:
    """Open ``port`` with the profile's baud rate and reply timeout; BusError if impossible,
    BadInputError when another process drives it (``exclusive``: see ``open_transport``).
    ``sim``: an emulated bus in simulated time (its timeouts and the bytes' time on the wire
    are simulated seconds, see :mod:`spm_console.system.simclock`)."""
    transport = open_transport(port, profile.bus.baud, profile.bus.timeout_s, exclusive)
    if sim is not None:
        transport.simulate(sim, profile.bus.baud)
    bus = DynamixelBus(profile, transport)
    if sim is not None:
        bus.link.clock = sim.now
    return bus
