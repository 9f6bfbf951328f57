"""The reply bookkeeping that tells a late reply from the current one, over a scripted line.

``FakeLine`` replaces the serial transport: three emulated MX-106 answer every request
with real status packets, and the test decides when those replies arrive (now, during a
later transaction, or never). No pty, no timing: each scenario is exact.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import pytest

from spm_console.devices.base import CommError
from spm_console.devices.dynamixel import protocol1 as p1
from spm_console.devices.dynamixel import protocol2 as p2
from spm_console.devices.dynamixel.control_table import MX106_P1, MX106_P2, table_for
from spm_console.devices.dynamixel.link import Link1, Link2
from spm_console.devices.dynamixel.reply_ledger import (
    MAX_READ_EXTRA,
    REPLY_HORIZON_S,
    ReplyLedger,
    Verdict,
    read_variants,
)
from spm_console.devices.dynamixel.transport import StreamDecoder
from spm_console.devices.emulator.dispatch import dispatch1, dispatch2
from spm_console.devices.emulator.servo import EmulatedServo

NEVER = 10**9
POS = 132  # Present Position (2.0)


class FakeLine:
    """A serial line with three servos; ``delay`` = in how many transactions the replies
    to the next request arrive (0 = at once, NEVER = lost); ``between``: late replies land
    before that transaction's request is sent rather than while it waits; ``lose`` = ids
    that do not answer. Replies arrive in order; input waiting before a request is sent is
    handed to ``on_late``, then discarded."""

    def __init__(self, protocol: str = "2.0") -> None:
        self.protocol = protocol
        table = table_for(protocol)
        self.servos = {i: EmulatedServo(table, i, 30.0, 2000.0 + 10 * i, 0.0) for i in (1, 2, 3)}
        self.lock = threading.RLock()
        self.timeout_s = 0.004
        self.delay = 0
        self.between = False
        self.lose: set[int] = set()
        self.sent: list[bytes] = []
        self._queue: list[tuple[int, bool, bytes]] = []  # (transaction, before its request, raw)
        self._dec: p2.Decoder2 | p1.Decoder1 = (p2.Decoder2() if protocol == "2.0"
                                                 else p1.Decoder1())

    def send(self, packet: bytes, on_late: Callable[[bytes], object] | None = None) -> None:
        n = len(self.sent) + 1
        waiting = [raw for due, early, raw in self._queue if due < n or (due == n and early)]
        self._queue = [q for q in self._queue if not (q[0] < n or (q[0] == n and q[1]))]
        if waiting and on_late is not None:
            on_late(b"".join(waiting))
        self.sent.append(packet)
        for pkt in self._dec.feed(packet):
            replies = (dispatch2(self.servos, pkt) if isinstance(pkt, p2.Packet)
                       else dispatch1(self.servos, pkt))
            for ident, raw in replies:
                if ident not in self.lose and self.delay != NEVER:
                    self._queue.append((n + self.delay, self.between and self.delay > 0, raw))

    def transact(self, packet: bytes, decoder: StreamDecoder[object], count: int,
                 timeout_s: float | None = None, check: Callable[[object], int] | None = None,
                 on_late: Callable[[bytes], object] | None = None) -> list[object]:
        decoder.reset()
        self.send(packet, on_late)
        n = len(self.sent)
        arriving = [raw for due, _early, raw in self._queue if due == n]
        self._queue = [q for q in self._queue if q[0] != n]
        got: list[object] = []
        settled = 0
        for k, raw in enumerate(arriving):
            if settled >= count:  # after the transaction: waiting at the next request
                self._queue += [(n, False, rest) for rest in arriving[k:]]
                break
            for pkt in decoder.feed(raw):
                m = 1 if check is None else check(pkt)
                if m:
                    got.append(pkt)
                    settled += m
        if settled < count:
            raise CommError(f"no status packet within 4.0 ms ({len(got)} of {count} received)")
        return got

    def sync_read_lengths(self) -> list[int]:
        """The length field of every SYNC_READ sent (2.0)."""
        out = []
        for raw in self.sent:
            (pkt,) = p2.Decoder2().feed(raw)
            if pkt.instruction == p2.Inst.SYNC_READ:
                out.append(pkt.params[2] | (pkt.params[3] << 8))
        return out


def link2(line: FakeLine) -> Link2:
    return Link2(line, MX106_P2)  # type: ignore[arg-type]


def ticks(reply_data: bytes) -> int:
    return int.from_bytes(reply_data, "little", signed=True)


# --- read variants -------------------------------------------------------------------------

def test_position_read_variants_stay_in_documented_registers() -> None:
    vs = read_variants(MX106_P2, POS, 4)
    assert [v.length for v in vs] == list(range(4, 4 + MAX_READ_EXTRA + 1))
    assert vs[0].start == POS and vs[0].offset == 0
    assert all(v.start + v.offset == POS for v in vs)  # the register is where it is
    assert vs[11].start == POS and vs[11].start + vs[11].length == 147  # following bytes first
    assert all(v.start >= 100 and v.start + v.length <= 147 for v in vs)  # 100..146 documented
    # Hardware Error Status: 68..70 are documented, 71..75 are not
    assert [(v.start, v.length) for v in read_variants(MX106_P2, 70, 1)] == [(70, 1), (69, 2),
                                                                            (68, 3)]
    # Protocol 1.0 Present Position: 30..44 documented (45 is not)
    v1 = read_variants(MX106_P1, 36, 2)
    assert v1[-1].start == 30 and v1[-1].start + v1[-1].length == 45
    assert read_variants(MX106_P2, 71, 2) == read_variants(MX106_P2, 71, 2)[:1]  # undocumented


def test_every_variant_returns_the_register() -> None:
    servo = EmulatedServo(MX106_P2, 1, 30.0, -1234.0, 0.0)
    for v in read_variants(MX106_P2, POS, 4):
        err, data = servo.read(v.start, v.length)
        assert err == 0 and len(data) == v.length
        assert ticks(data[v.offset : v.offset + 4]) == -1234


# --- over the scripted line ----------------------------------------------------------------

def test_a_healthy_line_reads_the_register_alone() -> None:
    line = FakeLine()
    link = link2(line)
    for _ in range(5):
        assert [ticks(r.data) for r in link.read_many(POS, 4, [1, 2, 3])] == [2010, 2020, 2030]
    assert line.sync_read_lengths() == [4] * 5
    assert link.ledger.requests == [] and link.stale_replies == 0


def test_a_late_reply_fails_the_next_transaction_and_is_counted() -> None:
    line = FakeLine()
    link = link2(line)
    line.delay = 1  # the replies to this read come during the next transaction
    with pytest.raises(CommError, match="no status packet"):
        link.read_many(POS, 4, [1, 2, 3])
    line.delay = 0
    line.servos[1].place(3000.0)  # the next answer differs from the late one
    with pytest.raises(CommError, match="stale reply from id 1: the late answer to a sync "
                                        r"read at 132 \(4 bytes\)"):
        link.read_many(POS, 4, [1, 2, 3])
    assert link.stale_replies == 3
    assert line.sync_read_lengths() == [4, 5]  # the second read used a length of its own
    # its own replies were collected too: nothing is left to arrive late, 4 bytes again
    assert [ticks(r.data) for r in link.read_many(POS, 4, [1, 2, 3])] == [3000, 2020, 2030]
    assert line.sync_read_lengths()[-1] == 4 and link.ledger.requests == []


def test_late_replies_waiting_before_a_request_are_counted_and_settle_theirs() -> None:
    line = FakeLine()
    link = link2(line)
    line.delay, line.between = 1, True  # the replies land between this read and the next
    with pytest.raises(CommError, match="no status packet"):
        link.read_many(POS, 4, [1, 2, 3])
    line.delay = 0
    # found waiting (and discarded) before the next read goes out: it is not disturbed
    assert [ticks(r.data) for r in link.read_many(POS, 4, [1, 2, 3])] == [2010, 2020, 2030]
    assert link.stale_replies == 3 and link.ledger.requests == []
    assert line.sync_read_lengths() == [4, 5]
    # also when the goal write (no reply) is what finds them
    line.delay = 1
    with pytest.raises(CommError, match="no status packet"):
        link.read_many(POS, 4, [1, 2, 3])
    line.delay = 0
    link.sync_write(116, 4, [(1, bytes(4))])
    assert link.stale_replies == 6 and link.ledger.requests == []


def test_a_constant_one_transaction_lag_never_yields_data() -> None:
    line = FakeLine()
    link = link2(line)
    line.delay = 1
    for k in range(40):
        with pytest.raises(CommError, match="no status packet" if k == 0 else "stale reply"):
            link.read_many(POS, 4, [1, 2, 3])
    assert link.stale_replies == 3 * 39
    assert set(line.sync_read_lengths()) == {4, 5}  # each stale answer frees its length


def test_replies_that_never_come_use_up_the_lengths_then_reads_are_refused() -> None:
    line = FakeLine()
    link = link2(line)
    line.delay = NEVER
    for _ in range(MAX_READ_EXTRA + 1):
        with pytest.raises(CommError, match="no status packet"):
            link.read_many(POS, 4, [1, 2, 3])
    # every length is reserved: a fence read (model number, a free length) goes out instead
    sent = len(line.sent)
    with pytest.raises(CommError, match="not sent: id 1, 2, 3 did not answer a fence read"):
        link.read_many(POS, 4, [1, 2, 3])
    (fence,) = p2.Decoder2().feed(line.sent[-1])
    assert len(line.sent) == sent + 1 and fence.instruction == p2.Inst.SYNC_READ
    assert fence.params[:2] == b"\x00\x00"
    # the fence may use 2 or 3 bytes (4..28 are reserved); then nothing is sent at all
    for _ in range(20):
        with pytest.raises(CommError, match="not sent"):
            link.read_many(POS, 4, [1, 2, 3])
    assert len(line.sent) == sent + 2 and link.ledger.refused == 21
    assert [p2.Decoder2().feed(raw)[0].params[2] for raw in line.sent[-2:]] == [2, 3]
    # after the horizon the lengths are free again
    t = [100.0]
    link.clock = lambda: t[0]
    for r in link.ledger.requests:
        r.t_sent = t[0] - REPLY_HORIZON_S - 0.01
    line.delay = 0
    assert len(link.read_many(POS, 4, [1, 2, 3])) == 3
    assert line.sync_read_lengths()[-1] == 4


def test_a_fence_answered_releases_the_lengths() -> None:
    line = FakeLine()
    link = link2(line)
    line.delay = NEVER
    for _ in range(MAX_READ_EXTRA + 1):
        with pytest.raises(CommError, match="no status packet"):
            link.read_many(POS, 4, [1, 2, 3])
    line.delay = 0  # the line is back: the fence is answered, the read goes out with 4 bytes
    assert [ticks(r.data) for r in link.read_many(POS, 4, [1, 2, 3])] == [2010, 2020, 2030]
    assert line.sync_read_lengths()[-2:] == [2, 4] and link.ledger.requests == []


def test_an_answer_from_a_servo_retires_its_older_unanswered_requests() -> None:
    line = FakeLine()
    link = link2(line)
    line.lose = {3}
    with pytest.raises(CommError, match="2 of 3 received"):
        link.read_many(POS, 4, [1, 2, 3])
    assert [r.pending for r in link.ledger.requests] == [[3]]
    line.lose = set()
    link.read_many(POS, 4, [1, 2, 3])  # id 3 answers a newer request: its old reply is lost
    assert link.ledger.requests == [] and line.sync_read_lengths() == [4, 5]
    link.read_many(POS, 4, [1, 2, 3])
    assert line.sync_read_lengths()[-1] == 4 and link.stale_replies == 0


def test_a_lost_reply_in_a_sync_read_is_not_a_stale_one() -> None:
    line = FakeLine()
    link = link2(line)
    line.lose = {1}
    with pytest.raises(CommError, match="from id 2 while waiting for id 1"):
        link.read_many(POS, 4, [1, 2, 3])
    assert link.stale_replies == 0 and link.ledger.requests == []  # id 1's turn has passed
    line.lose = set()
    link.read_many(POS, 4, [1, 2, 3])
    assert line.sync_read_lengths() == [4, 4]


def test_a_fixed_length_request_is_fenced_after_a_lost_reply() -> None:
    line = FakeLine()
    link = link2(line)
    line.delay = NEVER
    with pytest.raises(CommError):
        link.write(1, 65, b"\x01")  # LED on: its 0-byte reply is lost
    line.delay = 0
    n = len(line.sent)
    reply = link.write(1, 65, b"\x00")
    assert reply.id == 1 and reply.error_number == 0
    fence, write = [p2.Decoder2().feed(raw)[0] for raw in line.sent[n:]]
    assert fence.instruction == p2.Inst.READ and fence.params[:2] == b"\x00\x00"
    assert write.instruction == p2.Inst.WRITE
    assert link.ledger.requests == []
    # with nothing outstanding, no fence
    link.write(1, 65, b"\x01")
    assert len(line.sent) == n + 3


def test_protocol1_bulk_read_gets_the_same_treatment() -> None:
    line = FakeLine("1.0")
    for s in line.servos.values():
        s.place(1000.0 + s.id)
    link = Link1(line, MX106_P1)  # type: ignore[arg-type]
    assert [ticks(r.data) for r in link.read_many(36, 2, [1, 2, 3])] == [1001, 1002, 1003]
    line.delay = 1
    with pytest.raises(CommError, match="no status packet"):
        link.read_many(36, 2, [1, 2, 3])
    line.delay = 0
    with pytest.raises(CommError, match="stale reply from id 1"):
        link.read_many(36, 2, [1, 2, 3])  # the 2-byte replies decode and are recognised
    assert link.stale_replies == 3
    assert [ticks(r.data) for r in link.read_many(36, 2, [1, 2, 3])] == [1001, 1002, 1003]


# --- the ledger alone ----------------------------------------------------------------------

def test_classify_by_length_and_order() -> None:
    led = ReplyLedger()
    old = led.begin([1, 2], 4, 0.0, "old")
    led.end(old)
    cur = led.begin([1, 2], 5, 0.01, "cur")
    assert led.classify(cur, 1, 4) == (Verdict.STALE, old, 0)
    assert led.classify(cur, 1, 6) == (Verdict.UNEXPECTED, None, 0)
    assert led.classify(cur, 1, 5) == (Verdict.CURRENT, None, 1)
    assert led.stale == 2
    led.end(cur)
    assert [(r.what, r.pending) for r in led.requests] == [("old", [2]), ("cur", [2])]
    # id 2 answers the newest: by FIFO the older request will not hear from it any more
    nxt = led.begin([2], 6, 0.02, "next")
    assert led.classify(nxt, 2, 5) == (Verdict.STALE, cur, 0)
    assert [r.what for r in led.requests] == ["next"]


def test_an_error_status_is_current_only_when_unambiguous() -> None:
    led = ReplyLedger()
    cur = led.begin([1], 4, 0.0)
    assert led.classify(cur, 1, 0, error=True).verdict is Verdict.CURRENT
    led.end(cur)
    lost = led.begin([2], 4, 0.0)
    led.end(lost)
    cur = led.begin([2], 5, 0.0)
    assert led.classify(cur, 2, 0, error=True).verdict is Verdict.UNEXPECTED
    assert led.stale == 1


def test_lengths_in_use_and_expiry() -> None:
    led = ReplyLedger(horizon_s=1.0)
    a = led.begin([1, 2, 3], 4, 0.0)
    led.end(a)
    assert not led.is_free([3], 4) and led.is_free([4], 4) and led.is_free([1], 5)
    assert led.pick([1, 2, 3], [4, 5, 6]) == 5 and led.lengths() == {4}
    led.expire(0.9)
    assert led.requests == [a]
    led.expire(1.1)
    assert led.requests == [] and led.pick([1], [4, 5]) == 4
