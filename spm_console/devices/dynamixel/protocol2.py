"""Dynamixel Protocol 2.0 packets: pure encode/decode, no I/O.

Instruction packet: ``FF FF FD 00 ID LEN_L LEN_H INST PARAMS… CRC_L CRC_H`` with
LEN = stuffed(INST+PARAMS) + 2 CRC bytes. Status packet: INST = 0x55 followed by
ERR (bit 7 = Alert, bits 0–6 = error number) and the parameters. CRC-16 with
polynomial 0x8005, initial value 0, no reflection, over every byte before the CRC
(header included, after stuffing). Byte stuffing over INST..PARAMS turns every
``FF FF FD`` into ``FF FF FD FD``. (Vendor e-manual, "Protocol 2.0".)

:class:`Decoder2` is a streaming decoder: feed it bytes as they arrive, it yields
every packet whose CRC checks and resynchronizes on garbage and broken packets.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
STATUS = 0x55
MAX_ID = 0xFC
#: Largest LEN we accept (a longer one is garbage on any realistic bus).
MAX_LENGTH = 1024


class Inst(IntEnum):
    """Instruction codes of Protocol 2.0."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    BULK_READ = 0x92
    BULK_WRITE = 0x93


class ErrorNumber(IntEnum):
    """Error number of a status packet (ERR bits 0–6)."""

    NONE = 0
    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


ALERT = 0x80


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x8005) if c & 0x8000 else (c << 1)
        table.append(c & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/BUYPASS (poly 0x8005, init 0, no reflection); crc16(b"123456789") = 0xFEE8."""
    crc = 0
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ _CRC_TABLE[((crc >> 8) ^ b) & 0xFF]
    return crc


def stuff(body: bytes) -> bytes:
    """Insert 0xFD after every ``FF FF FD`` (applied to INST..PARAMS)."""
    if b"\xff\xff\xfd" not in body:
        return body
    out = bytearray()
    run = 0  # how many of FF FF FD we have just seen
    for b in body:
        out.append(b)
        if run == 2 and b == 0xFD:
            out.append(0xFD)
            run = 0
        elif b == 0xFF:
            run = 2 if run >= 1 else 1
        else:
            run = 0
    return bytes(out)


def unstuff(body: bytes) -> bytes | None:
    """Remove stuffing; None when a ``FF FF FD`` is not followed by the stuffing 0xFD."""
    if b"\xff\xff\xfd" not in body:
        return body
    out = bytearray()
    i, n = 0, len(body)
    while i < n:
        if body[i : i + 3] == b"\xff\xff\xfd":
            if i + 3 >= n or body[i + 3] != 0xFD:
                return None
            out += b"\xff\xff\xfd"
            i += 4
        else:
            out.append(body[i])
            i += 1
    return bytes(out)


def _frame(ident: int, body: bytes) -> bytes:
    stuffed = stuff(body)
    length = len(stuffed) + 2
    head = HEADER + bytes((ident, length & 0xFF, length >> 8))
    pkt = head + stuffed
    crc = crc16(pkt)
    return pkt + bytes((crc & 0xFF, crc >> 8))


def _check_id(ident: int) -> None:
    if not (0 <= ident <= MAX_ID or ident == BROADCAST_ID):
        raise ValueError(f"servo id {ident} out of range 0..252 (254 = broadcast)")


def instruction(ident: int, inst: int, params: bytes = b"") -> bytes:
    """Encode an instruction packet."""
    _check_id(ident)
    return _frame(ident, bytes((inst,)) + bytes(params))


def status(ident: int, error: int = 0, params: bytes = b"") -> bytes:
    """Encode a status packet (what a servo sends back)."""
    _check_id(ident)
    return _frame(ident, bytes((STATUS, error & 0xFF)) + bytes(params))


def _u16(v: int) -> bytes:
    return int(v).to_bytes(2, "little")


# --- instruction builders -------------------------------------------------------------


def ping(ident: int) -> bytes:
    return instruction(ident, Inst.PING)


def read(ident: int, address: int, length: int) -> bytes:
    return instruction(ident, Inst.READ, _u16(address) + _u16(length))


def write(ident: int, address: int, data: bytes) -> bytes:
    return instruction(ident, Inst.WRITE, _u16(address) + bytes(data))


def reboot(ident: int) -> bytes:
    return instruction(ident, Inst.REBOOT)


def sync_read(address: int, length: int, ids: Sequence[int]) -> bytes:
    return instruction(BROADCAST_ID, Inst.SYNC_READ, _u16(address) + _u16(length) + bytes(ids))


def sync_write(address: int, length: int, items: Iterable[tuple[int, bytes]]) -> bytes:
    """SYNC_WRITE of ``length`` bytes at ``address``: items are (id, data)."""
    params = bytearray(_u16(address) + _u16(length))
    for ident, data in items:
        if len(data) != length:
            raise ValueError(f"sync write to id {ident}: {len(data)} bytes, expected {length}")
        params.append(ident)
        params += data
    return instruction(BROADCAST_ID, Inst.SYNC_WRITE, bytes(params))


def bulk_read(items: Iterable[tuple[int, int, int]]) -> bytes:
    """BULK_READ: items are (id, address, length)."""
    params = bytearray()
    for ident, address, length in items:
        params.append(ident)
        params += _u16(address) + _u16(length)
    return instruction(BROADCAST_ID, Inst.BULK_READ, bytes(params))


# --- decoding -------------------------------------------------------------------------


@dataclass(frozen=True)
class Packet:
    """A decoded packet (stuffing removed). For a status packet ``error`` is set."""

    id: int
    instruction: int
    params: bytes
    error: int | None = None

    @property
    def is_status(self) -> bool:
        return self.instruction == STATUS

    @property
    def alert(self) -> bool:
        """Status only: the servo flags a hardware error (read Hardware Error Status)."""
        return bool(self.error is not None and self.error & ALERT)

    @property
    def error_number(self) -> int:
        return 0 if self.error is None else self.error & 0x7F


def describe_error(error_number: int) -> str:
    try:
        return ErrorNumber(error_number).name.lower().replace("_", " ") + " error"
    except ValueError:
        return f"unknown error {error_number}"


class Decoder2:
    """Streaming Protocol 2.0 decoder. ``feed(bytes) -> [Packet]``; keeps partial input.

    Rejected candidates (bad CRC, bad length, bad stuffing) are counted in
    ``rejected``; bytes skipped while hunting for a header in ``skipped``.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.rejected = 0
        self.skipped = 0

    def reset(self) -> None:
        self._buf.clear()

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a packet."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[Packet]:
        self._buf += data
        out: list[Packet] = []
        buf = self._buf
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # keep a possible partial header at the tail
                keep = 0
                for k in (3, 2, 1):
                    if len(buf) >= k and buf.endswith(HEADER[:k]):
                        keep = k
                        break
                self.skipped += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if start:
                self.skipped += start
                del buf[:start]
            if len(buf) < 7:
                break
            ident = buf[4]
            length = buf[5] | (buf[6] << 8)
            if length < 3 or length > MAX_LENGTH or ident > BROADCAST_ID or ident == 0xFD:
                self._reject(buf)
                continue
            total = 7 + length
            if len(buf) < total:
                break
            crc = buf[total - 2] | (buf[total - 1] << 8)
            if crc16(buf[: total - 2]) != crc:
                self._reject(buf)
                continue
            body = unstuff(bytes(buf[7 : total - 2]))
            if body is None or not body:
                self._reject(buf)
                continue
            inst = body[0]
            if inst == STATUS:
                if len(body) < 2:
                    self._reject(buf)
                    continue
                pkt = Packet(ident, inst, body[2:], body[1])
            else:
                pkt = Packet(ident, inst, body[1:])
            del buf[:total]
            out.append(pkt)
        return out

    def _reject(self, buf: bytearray) -> None:
        """Drop the first header byte and hunt for the next header."""
        self.rejected += 1
        del buf[:1]
