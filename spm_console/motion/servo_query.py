"""Bus diagnostics by servo id (``servo ping|read|torque``), run in the motion process that
owns the port, like every other bus access (refused while the wrist moves).

Unlike the console's servo tools (the profile's three joints), these address any id 0..252
and any control-table register by name — what a lab checks before the wrist is assembled or
when a servo does not answer. Degrees.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from spm_console.devices.base import CommError
from spm_console.errors import BadInputError, BusError

Action = Literal["ping", "scan", "joints", "register", "torque"]


@dataclass(frozen=True)
class BusQuery:
    """What to ask (``ids`` empty: the profile's joints)."""

    action: Action
    ids: tuple[int, ...] = ()
    register: str = ""
    on: bool = False


@dataclass(frozen=True)
class PingedServo:
    id: int
    model_number: int
    firmware: int | None


@dataclass(frozen=True)
class JointRead:
    joint: int
    id: int
    ticks: int
    theta_deg: float
    torque: bool
    hardware_error: int
    hardware_error_text: str


@dataclass(frozen=True)
class BusReport:
    """The answer; the fields of the query's action are filled."""

    port: str
    protocol: str
    ids: tuple[int, ...]
    found: tuple[PingedServo, ...] = ()
    missing: tuple[str, ...] = ()
    """ping: why each silent id failed."""
    values: tuple[tuple[int, int], ...] = ()
    """register: (id, value) pairs."""
    joints: tuple[JointRead, ...] = ()
    torque_on: bool | None = None


def check_ids(ids: list[int]) -> list[int]:
    bad = [i for i in ids if not 0 <= i <= 252]
    if bad:
        raise BadInputError(f"--ids: servo ids are 0..252, got {bad[:10]}")
    if len(set(ids)) != len(ids):
        raise BadInputError("--ids: give each servo id at most once")
    return ids


#: Reply timeout of one scan ping, s (a servo answers a ping within its Return Delay Time,
#: 0.5 ms by default; an absent id costs this much).
SCAN_TIMEOUT_S = 0.004

#: Quiet time on the line after a silent id, s: a late reply is let in, and is not the next id's.
SCAN_QUIET_S = 0.002

#: Quiet time on the line after the last id, s: a reply this late (a USB adapter's latency timer
#: is 16 ms by default) still shows that its servo is there.
SCAN_LAST_QUIET_S = 0.05


def _scan(bus: object, ids: tuple[int, ...]) -> BusReport:
    """One ping per id, any model (a scan lists what is on the bus; ``ping`` checks the
    profile's servos with retries): about a second for every id on an empty bus. An id whose
    reply came after its ping's timeout (seen on the line later), or whose ping saw another
    id's late reply, is pinged again with the set-up tries: a slow answer is a servo, not a
    gap."""
    from spm_console.devices.dynamixel.bus import DynamixelBus

    assert isinstance(bus, DynamixelBus)
    found: dict[int, PingedServo] = {}
    again: set[int] = set()  # silent ids that saw traffic during their ping
    bus.link.take_answered_late()  # what came late before this scan is not its business
    for ident in ids:
        stale = bus.link.stale_replies
        try:
            with bus.transport.patience(SCAN_TIMEOUT_S):
                model, fw, _r = bus.link.ping(ident)
        except CommError:
            if bus.drain_input(SCAN_QUIET_S) or bus.link.stale_replies != stale:
                again.add(ident)
            continue
        found[ident] = PingedServo(ident, int(model), fw)
    tried: set[int] = set()
    wanted = set(ids)
    while True:
        bus.drain_input(SCAN_LAST_QUIET_S if not tried else SCAN_QUIET_S)
        todo = ((again | bus.link.take_answered_late()) & wanted) - found.keys() - tried
        if not todo:  # (each id is pinged again at most once)
            break
        again.clear()
        for ident in sorted(todo):
            tried.add(ident)
            try:
                model, fw, _r = bus.ping_any(ident)
            except CommError:
                continue
            found[ident] = PingedServo(ident, int(model), fw)
    return BusReport(bus.port, bus.protocol, ids, found=tuple(found[i] for i in ids if i in found))


def answer(bus: object, q: BusQuery) -> BusReport:
    """Run ``q`` on ``bus`` (a DynamixelBus)."""
    from spm_console.devices.dynamixel.bus import DynamixelBus

    assert isinstance(bus, DynamixelBus)
    ids = tuple(check_ids(list(q.ids) if q.ids else list(bus.ids)))
    try:
        if q.action == "scan":
            return _scan(bus, ids if q.ids else tuple(range(253)))
        if q.action == "ping":
            found, missing = [], []
            for ident in ids:
                try:
                    st = bus.ping(ident)
                    found.append(PingedServo(st.id, st.model_number, st.firmware))
                except BusError as exc:
                    missing.append(exc.message)
            return BusReport(bus.port, bus.protocol, ids, found=tuple(found), missing=tuple(missing))
        if q.action == "register":
            if q.register not in bus.table.registers:
                names = ", ".join(sorted(bus.table.registers))
                raise BadInputError(f"unknown register {q.register!r} on the {bus.table.model}; "
                                    f"known: {names}")
            vals = tuple((i, int(bus.read(i, q.register))) for i in ids)
            return BusReport(bus.port, bus.protocol, ids, values=vals)
        if q.action == "joints":
            if q.ids:
                raise BadInputError("--ids needs --register (positions are per joint)")
            ticks = bus.read_ticks()
            torque = bus.torque()
            hw = bus.hardware_errors()
            joints = tuple(
                JointRead(m.joint, m.id, int(t), float(m.to_deg(t)), bool(tq), int(h),
                          bus.describe_hardware_error(h))
                for m, t, tq, h in zip(bus.maps, ticks, torque, hw, strict=True))
            return BusReport(bus.port, bus.protocol, ids, joints=joints)
        # a lost reply is tried again (set-up: writes of a value, done twice the same)
        if q.on:
            bus.set_up(bus.hold)  # goal := present position first, so torque-on does not lunge
        bus.set_up(lambda: bus.set_torque(q.on, list(ids)))
        return BusReport(bus.port, bus.protocol, ids, torque_on=q.on)
    except CommError as exc:
        raise BusError(f"{q.action} on {bus.port} failed: {exc}") from None
