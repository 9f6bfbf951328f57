"""Protocol links: one bus transaction = one instruction packet + its checked replies.

:class:`Link2` (Protocol 2.0) and :class:`Link1` (Protocol 1.0) offer the same
small set of calls to the servo bus. Every reply is checked: it must come from
the expected id, in order, be a status packet and carry exactly the expected
number of bytes; anything else is a :class:`CommError`, as is a timeout. The
error field is returned to the caller (``Reply.error`` in 2.0 form: error number
in bits 0–6, Alert in bit 7; 1.0 status bits are translated, see ``Link1``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from spm_console.devices import protocol1 as p1
from spm_console.devices import protocol2 as p2
from spm_console.devices.base import CommError
from spm_console.devices.control_table import HARDWARE_MASK_P1
from spm_console.devices.transport import SerialTransport
from spm_console.errors import BusError


@dataclass(frozen=True)
class Reply:
    """A checked status: the servo id, its data, and its error/alert field."""

    id: int
    data: bytes
    error_number: int = 0
    """0 = fine; otherwise the 2.0 error number (1.0 instruction/range bits mapped)."""
    hardware: int = 0
    """Hardware fault flags seen in this status (2.0: Alert → 0x80; 1.0: the status bits)."""


class Link(Protocol):
    protocol: str

    def ping(self, ident: int) -> tuple[int, int | None, Reply]: ...
    def read(self, ident: int, address: int, length: int) -> Reply: ...
    def write(self, ident: int, address: int, data: bytes) -> Reply: ...
    def sync_write(self, address: int, length: int, items: Sequence[tuple[int, bytes]]) -> None: ...
    def read_many(self, address: int, length: int, ids: Sequence[int]) -> list[Reply]: ...
    def reboot(self, ident: int) -> Reply: ...


def _expect(replies: Sequence[object], ids: Sequence[int]) -> None:
    if len(replies) != len(ids):
        raise CommError(f"expected {len(ids)} status packets, got {len(replies)}")


class Link2:
    """Protocol 2.0 transactions."""

    protocol = "2.0"

    def __init__(self, transport: SerialTransport) -> None:
        self.tr = transport
        self.dec = p2.Decoder2()

    def _replies(self, packet: bytes, ids: Sequence[int], length: int | None) -> list[Reply]:
        pkts = self.tr.transact(packet, self.dec, len(ids))
        _expect(pkts, ids)
        out = []
        for pkt, ident in zip(pkts, ids, strict=True):
            if not pkt.is_status or pkt.id != ident:
                raise CommError(f"unexpected packet from id {pkt.id} (instruction "
                                f"0x{pkt.instruction:02X}) while waiting for id {ident}")
            err = pkt.error_number
            if length is not None and err == 0 and len(pkt.params) != length:
                raise CommError(f"id {ident}: {len(pkt.params)} data bytes, expected {length}")
            out.append(Reply(ident, pkt.params, err, 0x80 if pkt.alert else 0))
        return out

    def ping(self, ident: int) -> tuple[int, int | None, Reply]:
        r = self._replies(p2.ping(ident), [ident], 3)[0]
        return r.data[0] | (r.data[1] << 8), r.data[2], r

    def read(self, ident: int, address: int, length: int) -> Reply:
        return self._replies(p2.read(ident, address, length), [ident], length)[0]

    def write(self, ident: int, address: int, data: bytes) -> Reply:
        return self._replies(p2.write(ident, address, data), [ident], 0)[0]

    def sync_write(self, address: int, length: int, items: Sequence[tuple[int, bytes]]) -> None:
        self.tr.send(p2.sync_write(address, length, items))

    def read_many(self, address: int, length: int, ids: Sequence[int]) -> list[Reply]:
        """SYNC_READ: one status per id, in order."""
        return self._replies(p2.sync_read(address, length, ids), ids, length)

    def reboot(self, ident: int) -> Reply:
        return self._replies(p2.reboot(ident), [ident], 0)[0]


#: 1.0 status bits → (2.0 error number) for instruction-level errors.
_P1_ERRORS = ((0x40, p2.ErrorNumber.INSTRUCTION), (0x10, p2.ErrorNumber.CRC),
              (0x08, p2.ErrorNumber.DATA_RANGE), (0x02, p2.ErrorNumber.DATA_LIMIT))


class Link1:
    """Protocol 1.0 transactions (no sync read: BULK_READ, or one READ per servo)."""

    protocol = "1.0"

    def __init__(self, transport: SerialTransport) -> None:
        self.tr = transport

    def _replies(self, packet: bytes, ids: Sequence[int], length: int) -> list[Reply]:
        pkts = self.tr.transact(packet, p1.Decoder1(expect_params=length), len(ids))
        _expect(pkts, ids)
        out = []
        for pkt, ident in zip(pkts, ids, strict=True):
            if pkt.id != ident:
                raise CommError(f"unexpected packet from id {pkt.id} while waiting for id {ident}")
            bits = pkt.error
            err = next((int(num) for bit, num in _P1_ERRORS if bits & bit), 0)
            out.append(Reply(ident, pkt.params, err, bits & HARDWARE_MASK_P1))
        return out

    def ping(self, ident: int) -> tuple[int, int | None, Reply]:
        """PING, then the model number and firmware (1.0 pings carry no data)."""
        self._replies(p1.ping(ident), [ident], 0)
        r = self._replies(p1.read(ident, 0, 3), [ident], 3)[0]
        return r.data[0] | (r.data[1] << 8), r.data[2], r

    def read(self, ident: int, address: int, length: int) -> Reply:
        return self._replies(p1.read(ident, address, length), [ident], length)[0]

    def write(self, ident: int, address: int, data: bytes) -> Reply:
        return self._replies(p1.write(ident, address, data), [ident], 0)[0]

    def sync_write(self, address: int, length: int, items: Sequence[tuple[int, bytes]]) -> None:
        self.tr.send(p1.sync_write(address, length, items))

    def read_many(self, address: int, length: int, ids: Sequence[int]) -> list[Reply]:
        """BULK_READ of the same register from every id."""
        return self._replies(p1.bulk_read([(i, address, length) for i in ids]), ids, length)

    def reboot(self, ident: int) -> Reply:
        raise BusError(f"servo id {ident}: Protocol 1.0 has no REBOOT instruction; "
                       "power-cycle the servo to clear its error")
