"""Protocol links: one bus transaction = one instruction packet + its checked replies.

:class:`Link2` (Protocol 2.0) and :class:`Link1` (Protocol 1.0) offer the same
small set of calls to the servo bus. Every reply is checked as it arrives: it must
come from the expected id, in order, be a status packet and carry exactly the
expected number of bytes; anything else is a :class:`CommError`, as is a timeout.
The error field is returned to the caller (``Reply.error`` in 2.0 form: error
number in bits 0–6, Alert in bit 7; 1.0 status bits are translated, see ``Link1``).

Stale replies. Status packets carry no sequence number, so every transaction is
recorded in a :class:`~spm_console.devices.dynamixel.reply_ledger.ReplyLedger` and its replies
are made distinguishable by their length: a read asks for the register plus as many
neighbouring bytes as needed to use a reply length no unanswered request (sent in
the last ``REPLY_HORIZON_S``) expects from the same servo — the register alone when
the line is healthy, so a healthy bus pays nothing. A packet that answers an older
request (stale), or no request at all, fails the transaction and is counted in
``stale_replies``; the current request's own replies are still collected first, so
they do not turn up late in the next transaction. A request whose reply lengths are
all reserved — for one of fixed length (ping, write, reboot), its only length — first
sends a *fence*: a read of the same servos' model number with a free length, whose
answer proves (servos answer in order) that their older replies will not come. If
the fence fails too, the request is refused, not sent (a failed transaction).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

from spm_console.devices.base import CommError
from spm_console.devices.dynamixel import protocol1 as p1
from spm_console.devices.dynamixel import protocol2 as p2
from spm_console.devices.dynamixel.control_table import HARDWARE_MASK_P1, ControlTable
from spm_console.devices.dynamixel.reply_ledger import ReplyLedger, Request, Verdict, read_variants
from spm_console.devices.dynamixel.transport import StreamDecoder, Transport
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
    clock: Callable[[], float]
    """The clock replies are aged by, s (``time.perf_counter``; simulated time in lockstep)."""

    @property
    def stale_replies(self) -> int: ...
    def take_answered_late(self) -> set[int]: ...
    def late_input(self, data: bytes) -> None: ...
    def ping(self, ident: int) -> tuple[int, int | None, Reply]: ...
    def read(self, ident: int, address: int, length: int) -> Reply: ...
    def write(self, ident: int, address: int, data: bytes) -> Reply: ...
    def sync_write(self, address: int, length: int, items: Sequence[tuple[int, bytes]]) -> None: ...
    def read_many(self, address: int, length: int, ids: Sequence[int]) -> list[Reply]: ...
    def reboot(self, ident: int) -> Reply: ...


@dataclass(frozen=True)
class _Shape:
    """The reads that can fetch one register range: reply lengths, and where each starts."""

    lengths: tuple[int, ...]
    start: dict[int, int]
    offset: dict[int, int]


P = TypeVar("P", p1.Packet, p2.Packet)

#: 1.0 status bits → (2.0 error number) for instruction-level errors.
_P1_ERRORS = ((0x40, p2.ErrorNumber.INSTRUCTION), (0x10, p2.ErrorNumber.CRC),
              (0x08, p2.ErrorNumber.DATA_RANGE), (0x02, p2.ErrorNumber.DATA_LIMIT))


class _LedgerLink(Generic[P]):
    """What both protocols share: transactions recorded in the reply ledger."""

    protocol = ""

    def __init__(self, transport: Transport, table: ControlTable) -> None:
        self.tr = transport
        self.table = table
        self.ledger = ReplyLedger()
        self.clock: Callable[[], float] = time.perf_counter
        self._shapes: dict[tuple[int, int], _Shape] = {}
        fence = table["model_number"]
        self._fence_at = (fence.address, fence.size)

    @property
    def stale_replies(self) -> int:
        """Status packets that were not the answer to the request in flight."""
        return self.ledger.stale

    def take_answered_late(self) -> set[int]:
        """Ids whose status answered one of our requests late, since the last call."""
        ids = set(self.ledger.answered_late)
        self.ledger.answered_late.clear()
        return ids

    # --- protocol specifics --------------------------------------------------------------

    def _decoder(self) -> StreamDecoder[P]:
        raise NotImplementedError

    def _late_decoder(self) -> StreamDecoder[P]:
        raise NotImplementedError

    def _status(self, pkt: P) -> tuple[int, bytes, int, int]:
        """(id, data, error number, hardware flags) of a status packet; CommError otherwise."""
        raise NotImplementedError

    def _read_packet(self, ident: int, address: int, length: int) -> bytes:
        raise NotImplementedError

    def _many_packet(self, ids: Sequence[int], address: int, length: int) -> bytes:
        """The one-status-per-id read (2.0 SYNC_READ, 1.0 BULK_READ)."""
        raise NotImplementedError

    _many = ""

    # --- transactions -------------------------------------------------------------------

    def _shape(self, address: int, length: int) -> _Shape:
        key = (address, length)
        shape = self._shapes.get(key)
        if shape is None:
            vs = read_variants(self.table, address, length)
            shape = _Shape(tuple(v.length for v in vs), {v.length: v.start for v in vs},
                           {v.length: v.offset for v in vs})
            self._shapes[key] = shape
        return shape

    def _exchange(self, build: Callable[[int], bytes], ids: Sequence[int],
                  lengths: Sequence[int], what: str,
                  fence: bool = True) -> tuple[list[Reply], int]:
        """Send ``build(n)`` for the first free reply length n; its replies, in id order.

        No free length: a fence read first (when ``fence``), then the request is refused."""
        led = self.ledger
        with self.tr.lock:
            now = self.clock()
            led.expire(now)
            n = led.pick(ids, lengths)
            if n is None and fence:
                try:
                    self._fence(ids)
                except CommError as exc:
                    led.refused += 1
                    who = ", ".join(map(str, ids))
                    raise CommError(f"{what} not sent: id {who} did not answer a fence read "
                                    f"either ({exc}); an earlier request with the same reply "
                                    "length is unanswered and its late reply could not be "
                                    "told from this one's") from None
                now = self.clock()
                n = led.pick(ids, lengths)
            if n is None:
                if fence:  # (a fence that cannot be sent is counted by its caller)
                    led.refused += 1
                raise CommError(
                    f"{what} not sent: {len(led.requests)} earlier requests are still "
                    f"unanswered and every reply length it could use is reserved for their "
                    f"late replies (the link answers later than its {self.tr.timeout_s * 1e3:.0f}"
                    f" ms timeout)")
            req = led.begin(ids, n, now, what)
            problems: list[str] = []
            try:
                pkts = self.tr.transact(build(n), self._decoder(), len(ids),
                                        check=lambda pkt: self._check(req, pkt, problems),
                                        on_late=lambda data: self.late_input(
                                            data, len(led.requests) - 1))
            except CommError as exc:
                if problems:  # the first foreign packet says more than the timeout
                    raise CommError(f"{problems[0]}; then {exc}") from None
                raise
            finally:
                led.end(req)
        if problems:
            raise CommError(problems[0])
        if len(pkts) != len(ids):
            raise CommError(f"expected {len(ids)} status packets, got {len(pkts)}")
        return [Reply(*self._status(pkt)) for pkt in pkts], n

    def late_input(self, data: bytes, among: int | None = None) -> None:
        """Replies found waiting before a request goes out (late ones: they came after
        their transaction ended): counted as stale, and their requests settled. ``among``:
        how many of the ledger's requests were sent before (not the one going out)."""
        dec = self._late_decoder()
        for pkt in dec.feed(data):
            try:
                ident, params, _err, _hw = self._status(pkt)
            except CommError:
                continue
            self.ledger.late(ident, len(params), among)

    def _check(self, req: Request, pkt: P, problems: list[str]) -> int:
        """Classify one packet (see ReplyLedger.classify); a problem fails the transaction
        once the current request's replies are in (so they do not arrive later as stale)."""
        try:
            ident, data, err, _hw = self._status(pkt)
        except CommError as exc:
            problems.append(str(exc))
            return 0
        waiting = req.pending[0] if req.pending else None
        verdict, older, settled = self.ledger.classify(req, ident, len(data), bool(err))
        if verdict is Verdict.SKIPPED:
            problems.append(f"unexpected packet from id {ident} while waiting for id {waiting}"
                            " (its reply is lost)")
        elif verdict is Verdict.STALE and older is not None:
            age = (self.clock() - older.t_sent) * 1e3
            problems.append(f"stale reply from id {ident}: the late answer to {older.what} "
                            f"({older.length} bytes) sent {age:.1f} ms ago, while waiting for "
                            f"{req.what} ({req.length} bytes)")
        elif verdict is Verdict.UNEXPECTED:
            problems.append(f"unexpected reply from id {ident} ({len(data)} data bytes) while "
                            f"waiting for {req.what} ({req.length} bytes): no recent request "
                            "asked for it")
        return settled

    def _read(self, ids: Sequence[int], address: int, length: int, many: bool, what: str,
              fence: bool = True) -> list[Reply]:
        """A read of ``length`` bytes at ``address`` (widened for a free reply length)."""
        shape = self._shape(address, length)
        if many:
            def build(k: int) -> bytes:
                return self._many_packet(ids, shape.start[k], k)
        else:
            def build(k: int) -> bytes:
                return self._read_packet(ids[0], shape.start[k], k)
        replies, n = self._exchange(build, ids, shape.lengths, what, fence)
        off = shape.offset[n]
        if off == 0 and n == length:
            return replies
        return [Reply(r.id, r.data[off : off + length], r.error_number, r.hardware)
                for r in replies]

    def _fence(self, ids: Sequence[int]) -> None:
        """A read of the servos' model number with a free length: once each id has answered
        it, that id's replies to older requests will not come (servos answer in order)."""
        address, length = self._fence_at
        self._read(ids, address, length, len(ids) > 1, f"a fence read of id(s) "
                   f"{', '.join(map(str, ids))}", fence=False)

    def _fixed(self, ident: int, length: int, packet: bytes, what: str) -> Reply:
        """A request whose reply length cannot vary (fenced when that length is reserved)."""
        return self._exchange(lambda _n: packet, [ident], [length], what)[0][0]

    def read(self, ident: int, address: int, length: int) -> Reply:
        return self._read([ident], address, length, False, f"a read of id {ident} at {address}")[0]

    def read_many(self, address: int, length: int, ids: Sequence[int]) -> list[Reply]:
        """One status per id, in order (2.0 SYNC_READ, 1.0 BULK_READ)."""
        return self._read(list(ids), address, length, True, f"a {self._many} at {address}")


class Link2(_LedgerLink[p2.Packet]):
    """Protocol 2.0 transactions."""

    protocol = "2.0"

    def __init__(self, transport: Transport, table: ControlTable) -> None:
        super().__init__(transport, table)
        self.dec = p2.Decoder2()

    def _decoder(self) -> StreamDecoder[p2.Packet]:
        return self.dec

    def _late_decoder(self) -> StreamDecoder[p2.Packet]:
        return p2.Decoder2()

    def _status(self, pkt: p2.Packet) -> tuple[int, bytes, int, int]:
        if not pkt.is_status:
            raise CommError(f"unexpected packet from id {pkt.id} (instruction "
                            f"0x{pkt.instruction:02X}) while waiting for a status packet")
        return pkt.id, pkt.params, pkt.error_number, 0x80 if pkt.alert else 0

    def ping(self, ident: int) -> tuple[int, int | None, Reply]:
        r = self._fixed(ident, 3, p2.ping(ident), f"a ping of id {ident}")
        return r.data[0] | (r.data[1] << 8), r.data[2], r

    _many = "sync read"

    def _read_packet(self, ident: int, address: int, length: int) -> bytes:
        return p2.read(ident, address, length)

    def _many_packet(self, ids: Sequence[int], address: int, length: int) -> bytes:
        return p2.sync_read(address, length, ids)

    def write(self, ident: int, address: int, data: bytes) -> Reply:
        return self._fixed(ident, 0, p2.write(ident, address, data),
                           f"a write to id {ident} at {address}")

    def sync_write(self, address: int, length: int, items: Sequence[tuple[int, bytes]]) -> None:
        with self.tr.lock:
            self.tr.send(p2.sync_write(address, length, items), on_late=self.late_input)

    def reboot(self, ident: int) -> Reply:
        return self._fixed(ident, 0, p2.reboot(ident), f"a reboot of id {ident}")


class Link1(_LedgerLink[p1.Packet]):
    """Protocol 1.0 transactions (no sync read: BULK_READ, or one READ per servo)."""

    protocol = "1.0"

    def _decoder(self) -> StreamDecoder[p1.Packet]:
        # only the lengths some request expects: a frame of another length is corrupt
        return p1.Decoder1(expect_params=self.ledger.lengths())

    _late_decoder = _decoder

    def _status(self, pkt: p1.Packet) -> tuple[int, bytes, int, int]:
        bits = pkt.error
        err = next((int(num) for bit, num in _P1_ERRORS if bits & bit), 0)
        return pkt.id, pkt.params, err, bits & HARDWARE_MASK_P1

    def ping(self, ident: int) -> tuple[int, int | None, Reply]:
        """PING, then the model number and firmware (1.0 pings carry no data)."""
        self._fixed(ident, 0, p1.ping(ident), f"a ping of id {ident}")
        r = self.read(ident, 0, 3)
        return r.data[0] | (r.data[1] << 8), r.data[2], r

    _many = "bulk read"

    def _read_packet(self, ident: int, address: int, length: int) -> bytes:
        return p1.read(ident, address, length)

    def _many_packet(self, ids: Sequence[int], address: int, length: int) -> bytes:
        return p1.bulk_read([(i, address, length) for i in ids])

    def write(self, ident: int, address: int, data: bytes) -> Reply:
        return self._fixed(ident, 0, p1.write(ident, address, data),
                           f"a write to id {ident} at {address}")

    def sync_write(self, address: int, length: int, items: Sequence[tuple[int, bytes]]) -> None:
        with self.tr.lock:
            self.tr.send(p1.sync_write(address, length, items), on_late=self.late_input)

    def reboot(self, ident: int) -> Reply:
        raise BusError(f"servo id {ident}: Protocol 1.0 has no REBOOT instruction; "
                       "power-cycle the servo to clear its error")
