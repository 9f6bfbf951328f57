"""Which request a status packet answers: the ledger of unanswered requests.

Dynamixel status packets carry no sequence number, so a late reply to an earlier
request looks exactly like the reply to the current one. Two facts make them
distinguishable without one:

* the reply's data length is the length the request asked for, and a read may ask
  for more than the register it needs (:func:`read_variants`: the register plus
  neighbouring documented bytes; the extra bytes are read and ignored);
* each servo answers its requests in the order it received them, and the serial
  line delivers bytes in order (per-id FIFO).

:class:`ReplyLedger` keeps every request sent within :data:`REPLY_HORIZON_S` that
still waits for a reply, as (send time, reply length, ids not yet heard from). A
new request may only use a reply length that no unanswered request expects from
the same id (:meth:`ReplyLedger.pick`); when none is free the link first tries a
fence read (``devices/dynamixel/link.py``), then refuses the request (a failed transaction,
nothing sent). Each status packet that arrives during a transaction is classified
(:meth:`ReplyLedger.classify`): it answers the current request only if it comes
from one of its ids with its length; one that matches an older request is *stale*,
one that matches no request *unexpected*; both are counted in ``stale`` and fail
the transaction. Replies found waiting before a request goes out are late too
(:meth:`ReplyLedger.late`): counted, and discarded. A reply from id i (current or
late) retires older requests' claims on id i — by FIFO their replies can no longer
come — and, within a sync/bulk read answered in list order, the claims of the ids
listed before i.

Guarantee: a status packet is accepted as the answer to a request only if it is
not the reply to another request sent within the horizon before it — provided
servos answer in order and with the length asked for. Replies delayed by more than
the horizon are not covered. Pure bookkeeping, no I/O, no clock of its own: a few
microseconds per transaction.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

from spm_console.devices.dynamixel.control_table import ControlTable

#: How long an unanswered request keeps its reply length reserved, s. Replies later
#: than this are not guaranteed to be recognised (the target is delays up to 1 s).
REPLY_HORIZON_S = 1.5

#: At most this many extra bytes widen a read (24 bytes ≈ 0.24 ms per reply at 1 Mbps).
MAX_READ_EXTRA = 24


@dataclass(frozen=True)
class ReadVariant:
    """Read ``length`` bytes from ``start``; the wanted bytes begin at ``offset``."""

    start: int
    length: int
    offset: int


def _documented(table: ControlTable) -> bytearray:
    covered = bytearray(table.size + 1)
    for reg in table.registers.values():
        covered[reg.address : reg.address + reg.size] = b"\x01" * reg.size
    return covered[: table.size]


def read_variants(table: ControlTable, address: int, size: int,
                  max_extra: int = MAX_READ_EXTRA) -> tuple[ReadVariant, ...]:
    """Reads that contain ``[address, address + size)``, one per reply length, shortest
    first: the bytes that follow are added first, then the bytes before, never leaving
    the run of documented registers around it (no reserved addresses). A range that is
    not all documented gets only its exact read."""
    covered = _documented(table)
    end = address + size
    if size <= 0 or address < 0 or end > len(covered) or not all(covered[address:end]):
        return (ReadVariant(address, size, 0),)
    lo, hi = address, end
    while lo > 0 and covered[lo - 1]:
        lo -= 1
    while hi < len(covered) and covered[hi]:
        hi += 1
    out = []
    for extra in range(min(max_extra, hi - lo - size) + 1):
        after = min(extra, hi - end)
        before = extra - after
        out.append(ReadVariant(address - before, size + extra, before))
    return tuple(out)


class Verdict(Enum):
    """What a status packet is, seen from the current request."""

    CURRENT = "current"
    """One of the current request's replies, in order."""
    SKIPPED = "skipped"
    """A current reply, but an earlier id of the request has not answered (a lost reply)."""
    STALE = "stale"
    """The late reply to an older request."""
    UNEXPECTED = "unexpected"
    """A reply no recorded request asked for (older than the horizon, or never sent by us)."""


class Classified(NamedTuple):
    """A verdict on one status packet."""

    verdict: Verdict
    answers: Request | None
    """STALE: the older request it answers."""
    settled: int
    """How many of the current request's expected replies it settles (0: none of them)."""


@dataclass
class Request:
    """One request whose replies are (partly) still to come."""

    seq: int
    t_sent: float
    length: int
    """Data bytes each reply carries."""
    pending: list[int]
    """Ids not heard from yet, in bus order."""
    what: str = ""


class ReplyLedger:
    """Unanswered requests, oldest first (the one in flight last). See module docstring."""

    def __init__(self, horizon_s: float = REPLY_HORIZON_S) -> None:
        self.horizon_s = horizon_s
        self.requests: list[Request] = []
        self.stale = 0
        """Status packets that were not the answer to the request in flight."""
        self.refused = 0
        """Requests not sent: every reply length they could use was still reserved."""
        self.answered_late: set[int] = set()
        """Ids whose status answered one of our requests after its transaction ended (a scan
        asks them again with more patience). At most one entry per id (it is not emptied
        between scans, so it stays that small); the reader clears it."""
        self._seq = 0

    def expire(self, now: float) -> None:
        """Forget requests sent more than the horizon ago."""
        reqs = self.requests
        if reqs and now - reqs[0].t_sent > self.horizon_s:
            self.requests = [r for r in reqs if now - r.t_sent <= self.horizon_s]

    def is_free(self, ids: Iterable[int], length: int) -> bool:
        """No unanswered request expects a reply of ``length`` bytes from one of ``ids``."""
        return not any(r.length == length and any(i in r.pending for i in ids)
                       for r in self.requests)

    def pick(self, ids: Sequence[int], lengths: Iterable[int]) -> int | None:
        """The first of ``lengths`` free for every id (None: all reserved)."""
        if not self.requests:
            return next(iter(lengths), None)
        for n in lengths:
            if self.is_free(ids, n):
                return n
        return None

    def lengths(self) -> set[int]:
        """Reply lengths still expected (a decoder that filters on length keeps these)."""
        return {r.length for r in self.requests}

    def begin(self, ids: Sequence[int], length: int, now: float, what: str = "") -> Request:
        """Record a request about to be sent; it becomes the current one."""
        self._seq += 1
        req = Request(self._seq, now, length, list(ids), what)
        self.requests.append(req)
        return req

    def end(self, req: Request) -> None:
        """The transaction is over: a fully answered request is forgotten, others stay."""
        if not req.pending:
            self._drop(req)

    def classify(self, req: Request, ident: int, length: int,
                 error: bool = False) -> Classified:
        """What a status from ``ident`` with ``length`` data bytes is while ``req`` is current.

        ``error``: the status carries an error number (its data may be missing), so it
        is taken as current only if no older request still waits for that id. A reply
        from the k-th id of a request also settles the ids before it (a sync/bulk read is
        answered in list order: theirs would have come first).
        """
        if not self.requests or self.requests[-1] is not req:
            raise ValueError("classify() is for the request in flight (the last begun)")
        older = self.requests[:-1]
        if ident in req.pending and (length == req.length or (
                error and not any(ident in o.pending for o in older))):
            k = req.pending.index(ident)
            del req.pending[: k + 1]
            self._retire(ident, older, keep=req)
            return Classified(Verdict.CURRENT if k == 0 else Verdict.SKIPPED, None, k + 1)
        o = self.late(ident, length, len(older))
        return Classified(Verdict.UNEXPECTED if o is None else Verdict.STALE, o, 0)

    def late(self, ident: int, length: int, among: int | None = None) -> Request | None:
        """A status that is not the current request's (also one found waiting before a
        request is sent): counted in ``stale``. The newest of the first ``among`` requests
        expecting ``length`` bytes from ``ident`` is the one it answers (returned): that
        request — and, by FIFO, every older one — has heard from ``ident``."""
        self.stale += 1
        reqs = self.requests if among is None else self.requests[:among]
        for j in range(len(reqs) - 1, -1, -1):
            o = reqs[j]
            if o.length == length and ident in o.pending:
                self.answered_late.add(ident)
                del o.pending[: o.pending.index(ident) + 1]
                self._retire(ident, reqs[: j + 1], keep=None if among is None else
                             self.requests[-1])
                return o
        return None

    def _retire(self, ident: int, requests: Collection[Request],
                keep: Request | None = None) -> None:
        """``ident`` answered something newer: by FIFO it will not answer these. Requests
        left with no pending id are forgotten (except ``keep``, the one in flight)."""
        for r in requests:
            if ident in r.pending:
                r.pending.remove(ident)
        if any(not r.pending for r in requests):
            self.requests = [r for r in self.requests if r.pending or r is keep]

    def _drop(self, req: Request) -> None:
        self.requests = [r for r in self.requests if r is not req]
