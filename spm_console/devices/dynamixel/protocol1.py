"""Dynamixel Protocol 1.0 packets: pure encode/decode, no I/O.

Instruction packet ``FF FF ID LEN INST P… CHK`` with LEN = params + 2 and
CHK = ~(ID + LEN + INST + params) & 0xFF. Status packet ``FF FF ID LEN ERR P… CHK``
where ERR is a bit field (0 voltage, 1 angle limit, 2 overheat, 3 range,
4 checksum, 5 overload, 6 instruction). No stuffing, no SYNC_READ; MX servos
support BULK_READ 0x92 (vendor e-manual, "Protocol 1.0").

The 1.0 checksum is a single byte and the header ``FF FF`` may occur inside a
packet, so :class:`Decoder1` can be told the status length it expects
(``expect_params``): the bus always knows it, and a frame of any other length is
rejected instead of being trusted.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass
from enum import IntEnum

HEADER = b"\xff\xff"
BROADCAST_ID = 0xFE
MAX_ID = 0xFD


class Inst(IntEnum):
    """Instruction codes of Protocol 1.0."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    RESET = 0x06
    SYNC_WRITE = 0x83
    BULK_READ = 0x92


def checksum(body: bytes | bytearray) -> int:
    """~(sum of ID, LEN, INST/ERR and params) & 0xFF."""
    return (~sum(body)) & 0xFF


def _frame(ident: int, first: int, params: bytes) -> bytes:
    if not (0 <= ident <= BROADCAST_ID):
        raise ValueError(f"servo id {ident} out of range 0..253 (254 = broadcast)")
    length = len(params) + 2
    if length > 255:
        raise ValueError("protocol 1.0 packet too long")
    body = bytes((ident, length, first)) + bytes(params)
    return HEADER + body + bytes((checksum(body),))


def instruction(ident: int, inst: int, params: bytes = b"") -> bytes:
    return _frame(ident, inst, params)


def status(ident: int, error: int = 0, params: bytes = b"") -> bytes:
    """A status packet as a servo sends it."""
    return _frame(ident, error & 0x7F, params)


def ping(ident: int) -> bytes:
    return instruction(ident, Inst.PING)


def read(ident: int, address: int, length: int) -> bytes:
    return instruction(ident, Inst.READ, bytes((address, length)))


def write(ident: int, address: int, data: bytes) -> bytes:
    return instruction(ident, Inst.WRITE, bytes((address,)) + bytes(data))


def sync_write(address: int, length: int, items: Iterable[tuple[int, bytes]]) -> bytes:
    """SYNC_WRITE of ``length`` bytes at ``address``: items are (id, data)."""
    params = bytearray((address, length))
    for ident, data in items:
        if len(data) != length:
            raise ValueError(f"sync write to id {ident}: {len(data)} bytes, expected {length}")
        params.append(ident)
        params += data
    return instruction(BROADCAST_ID, Inst.SYNC_WRITE, bytes(params))


def bulk_read(items: Iterable[tuple[int, int, int]]) -> bytes:
    """BULK_READ (MX series): items are (id, address, length); params 0x00, then (len, id, addr)."""
    params = bytearray((0x00,))
    for ident, address, length in items:
        params += bytes((length, ident, address))
    return instruction(BROADCAST_ID, Inst.BULK_READ, bytes(params))


@dataclass(frozen=True)
class Packet:
    """A decoded 1.0 packet. ``first`` is INST for instructions, ERR for status packets."""

    id: int
    first: int
    params: bytes

    @property
    def instruction(self) -> int:
        return self.first

    @property
    def error(self) -> int:
        return self.first


class Decoder1:
    """Streaming Protocol 1.0 decoder; resynchronizes on garbage and bad checksums.

    ``expect_params``: when set, only status frames with exactly that many
    parameters (or one of these counts) are accepted; frames of another length are
    rejected as corrupt.
    """

    def __init__(self, expect_params: int | Collection[int] | None = None) -> None:
        self._buf = bytearray()
        self.expect_params: frozenset[int] | None = (
            None if expect_params is None
            else frozenset((expect_params,) if isinstance(expect_params, int) else expect_params))
        self.rejected = 0
        self.skipped = 0

    def reset(self) -> None:
        self._buf.clear()

    @property
    def pending(self) -> int:
        return len(self._buf)

    def feed(self, data: bytes) -> list[Packet]:
        self._buf += data
        buf = self._buf
        out: list[Packet] = []
        while True:
            start = buf.find(HEADER)
            if start < 0:
                keep = 1 if buf.endswith(b"\xff") else 0
                self.skipped += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if start:
                self.skipped += start
                del buf[:start]
            # FF FF FF …: the header is the last two FFs (an ID is never 0xFF)
            if len(buf) >= 3 and buf[2] == 0xFF:
                self.skipped += 1
                del buf[:1]
                continue
            if len(buf) < 4:
                break
            ident, length = buf[2], buf[3]
            bad_len = length < 2 or (
                self.expect_params is not None and length - 2 not in self.expect_params
            )
            if ident == 0xFF or bad_len:
                self._reject(buf)
                continue
            total = 4 + length
            if len(buf) < total:
                break
            if checksum(buf[2 : total - 1]) != buf[total - 1]:
                self._reject(buf)
                continue
            out.append(Packet(ident, buf[4], bytes(buf[5 : total - 1])))
            del buf[:total]
        return out

    def _reject(self, buf: bytearray) -> None:
        self.rejected += 1
        del buf[:1]
