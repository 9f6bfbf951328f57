"""What a chain of emulated servos answers to one instruction packet (both protocols).

Pure functions over :class:`EmulatedServo` objects: they apply the instruction
and return the status packets the servos send, in bus order, as
``[(servo id, bytes)]``. Honors Status Return Level (2.0: 0 = ping only,
1 = ping + read, 2 = all) and the broadcast rules (no reply to broadcast
WRITE / SYNC_WRITE).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from spm_console.devices.dynamixel import protocol1 as p1
from spm_console.devices.dynamixel import protocol2 as p2
from spm_console.devices.dynamixel.control_table import HARDWARE_MASK_P1
from spm_console.devices.dynamixel.protocol2 import ErrorNumber
from spm_console.devices.emulator.servo import EmulatedServo

Replies = list[tuple[int, bytes]]
Reply = Callable[[EmulatedServo, int, bytes], None]

_READS = {p2.Inst.READ, p2.Inst.SYNC_READ, p2.Inst.BULK_READ}


def _u16(b: bytes, i: int) -> int:
    return b[i] | (b[i + 1] << 8)


def _status2(s: EmulatedServo, err: int, params: bytes = b"") -> bytes:
    return p2.status(s.id, err | (p2.ALERT if s.hw_error else 0), params)


def _wants_reply2(s: EmulatedServo, inst: int) -> bool:
    level = s.get("status_return_level")
    return inst == p2.Inst.PING or level >= 2 or (level == 1 and inst in _READS)


def dispatch2(servos: Mapping[int, EmulatedServo], pkt: p2.Packet) -> Replies:
    """Apply a Protocol 2.0 instruction packet; the status packets sent back."""
    inst, prm = pkt.instruction, pkt.params
    bcast = pkt.id == p2.BROADCAST_ID
    out: Replies = []
    for s in ([servos[pkt.id]] if pkt.id in servos else list(servos.values()) if bcast else []):
        s.last_rx = s.t

    def reply(s: EmulatedServo, err: int, params: bytes = b"") -> None:
        if _wants_reply2(s, inst):
            out.append((s.id, _status2(s, err, params)))

    if inst == p2.Inst.PING:
        targets = sorted(servos.values(), key=lambda s: s.id) if bcast else (
            [servos[pkt.id]] if pkt.id in servos else [])
        for s in targets:
            model = s.get("model_number").to_bytes(2, "little")
            reply(s, 0, model + bytes((s.get("firmware_version"),)))
        return out
    if inst in (p2.Inst.SYNC_READ, p2.Inst.SYNC_WRITE, p2.Inst.BULK_READ):
        if not bcast:
            if pkt.id in servos:
                reply(servos[pkt.id], ErrorNumber.INSTRUCTION)
            return out
        _multi2(servos, inst, prm, reply)
        return out
    if pkt.id not in servos:
        if bcast and inst == p2.Inst.WRITE and len(prm) > 2:
            for s in servos.values():
                s.write(_u16(prm, 0), prm[2:])
        return out
    s = servos[pkt.id]
    if inst == p2.Inst.READ:
        if len(prm) != 4:
            reply(s, ErrorNumber.DATA_LENGTH)
        else:
            err, data = s.read(_u16(prm, 0), _u16(prm, 2))
            reply(s, err, data)
    elif inst == p2.Inst.WRITE:
        reply(s, ErrorNumber.DATA_LENGTH if len(prm) < 3 else s.write(_u16(prm, 0), prm[2:]))
    elif inst == p2.Inst.REBOOT:
        reply(s, 0)
        s.reboot()
    else:
        reply(s, ErrorNumber.INSTRUCTION)
    return out


def _multi2(servos: Mapping[int, EmulatedServo], inst: int, prm: bytes, send: Reply) -> None:
    if inst == p2.Inst.SYNC_READ:
        if len(prm) < 5:
            return
        addr, length = _u16(prm, 0), _u16(prm, 2)
        for ident in prm[4:]:
            if ident in servos:
                err, data = servos[ident].read(addr, length)
                send(servos[ident], err, data)
    elif inst == p2.Inst.SYNC_WRITE:
        if len(prm) < 4:
            return
        addr, length = _u16(prm, 0), _u16(prm, 2)
        body = prm[4:]
        if length == 0 or len(body) % (length + 1):
            return
        for k in range(0, len(body), length + 1):
            ident = body[k]
            if ident in servos:
                servos[ident].write(addr, body[k + 1 : k + 1 + length])
    elif inst == p2.Inst.BULK_READ:
        if not prm or len(prm) % 5:
            return
        for k in range(0, len(prm), 5):
            ident = prm[k]
            if ident in servos:
                err, data = servos[ident].read(_u16(prm, k + 1), _u16(prm, k + 3))
                send(servos[ident], err, data)


# --- Protocol 1.0 ---------------------------------------------------------------------

_P1_BITS = {
    ErrorNumber.NONE: 0,
    ErrorNumber.RESULT_FAIL: 0x08,
    ErrorNumber.INSTRUCTION: 0x40,
    ErrorNumber.CRC: 0x10,
    ErrorNumber.DATA_RANGE: 0x08,
    ErrorNumber.DATA_LENGTH: 0x08,
    ErrorNumber.DATA_LIMIT: 0x02,
    ErrorNumber.ACCESS: 0x08,
}


def _status1(s: EmulatedServo, err: ErrorNumber, params: bytes = b"") -> bytes:
    return p1.status(s.id, _P1_BITS[err] | (s.hw_error & HARDWARE_MASK_P1), params)


def dispatch1(servos: Mapping[int, EmulatedServo], pkt: p1.Packet) -> Replies:
    """Apply a Protocol 1.0 instruction packet; the status packets sent back."""
    inst, prm = pkt.instruction, pkt.params
    bcast = pkt.id == p1.BROADCAST_ID
    out: Replies = []

    def reply(s: EmulatedServo, err: ErrorNumber, params: bytes = b"") -> None:
        level = s.get("status_return_level")
        if inst == p1.Inst.PING or level >= 2 or (level == 1 and inst in (p1.Inst.READ,
                                                                         p1.Inst.BULK_READ)):
            out.append((s.id, _status1(s, err, params)))

    if inst == p1.Inst.SYNC_WRITE and bcast:
        if len(prm) >= 2 and prm[1] > 0 and (len(prm) - 2) % (prm[1] + 1) == 0:
            addr, length = prm[0], prm[1]
            for k in range(2, len(prm), length + 1):
                if prm[k] in servos:
                    servos[prm[k]].write(addr, prm[k + 1 : k + 1 + length])
        return out
    if inst == p1.Inst.BULK_READ and bcast:
        if len(prm) >= 4 and prm[0] == 0 and (len(prm) - 1) % 3 == 0:
            for k in range(1, len(prm), 3):
                length, ident, addr = prm[k], prm[k + 1], prm[k + 2]
                if ident in servos:
                    err, data = servos[ident].read(addr, length)
                    reply(servos[ident], err, data)
        return out
    if bcast:
        if inst == p1.Inst.WRITE and len(prm) >= 2:
            for s in servos.values():
                s.write(prm[0], prm[1:])
        return out
    if pkt.id not in servos:
        return out
    s = servos[pkt.id]
    if inst == p1.Inst.PING:
        reply(s, ErrorNumber.NONE)
    elif inst == p1.Inst.READ:
        if len(prm) != 2:
            reply(s, ErrorNumber.INSTRUCTION)
        else:
            err, data = s.read(prm[0], prm[1])
            reply(s, err, data)
    elif inst == p1.Inst.WRITE:
        reply(s, ErrorNumber.INSTRUCTION if len(prm) < 2 else s.write(prm[0], prm[1:]))
    else:
        reply(s, ErrorNumber.INSTRUCTION)
    return out
