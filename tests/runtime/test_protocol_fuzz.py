"""Property tests of the streaming decoders: no crash on any input, no corrupted packet accepted.

Corruptions tested for Protocol 2.0 are those CRC-16 (poly 0x8005) is guaranteed to
catch: any single bit flip, and any burst of errors within 16 consecutive bits
(one or two adjacent bytes replaced by anything else), anywhere in the packet,
header and length included. Protocol 1.0 has a one-byte checksum and no byte
stuffing, so its guarantee is narrower and the test says exactly which: any single
byte changed in a status packet the bus expects (known parameter count, the
values a position/register read returns).
"""

from __future__ import annotations

from hypothesis import example, given, settings
from hypothesis import strategies as st

from spm_console.devices.dynamixel import protocol1 as p1
from spm_console.devices.dynamixel import protocol2 as p2

ids2 = st.integers(0, 252) | st.just(p2.BROADCAST_ID)
params = st.binary(max_size=40)
ff_heavy = st.lists(st.sampled_from([0xFF, 0xFD, 0x00, 0x55, 0x01]) | st.integers(0, 255),
                    max_size=40).map(bytes)


@st.composite
def packets2(draw: st.DrawFn) -> bytes:
    ident = draw(ids2)
    body = draw(params | ff_heavy)
    if draw(st.booleans()):
        return p2.status(ident if ident != p2.BROADCAST_ID else 1, draw(st.integers(0, 255)), body)
    return p2.instruction(ident, draw(st.integers(0, 255).filter(lambda i: i != p2.STATUS)), body)


def chunked(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    out, last = [], 0
    for c in [*points, len(data)]:
        out.append(data[last:c])
        last = c
    return out


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300) | ff_heavy, st.lists(st.integers(0, 400), max_size=8))
def test_decoder2_never_crashes_and_only_yields_crc_valid_packets(data: bytes,
                                                                  cuts: list[int]) -> None:
    dec = p2.Decoder2()
    out = []
    for chunk in chunked(data, cuts):
        out += dec.feed(chunk)
    for pkt in out:  # whatever it accepted was really in the stream, bit for bit
        raw = (p2.status(pkt.id, pkt.error, pkt.params) if pkt.error is not None
               else p2.instruction(pkt.id, pkt.instruction, pkt.params))
        assert raw in data


@settings(max_examples=300, deadline=None)
@given(st.lists(packets2(), min_size=1, max_size=5),
       st.lists(st.binary(max_size=12).map(lambda b: b.replace(b"\xff", b"\x00")),
                min_size=6, max_size=6),
       st.lists(st.integers(0, 400), max_size=6))
def test_decoder2_recovers_every_packet_between_garbage(pkts: list[bytes], junk: list[bytes],
                                                        cuts: list[int]) -> None:
    stream = b"".join(j + p for j, p in zip(junk, pkts, strict=False)) + junk[-1]
    dec = p2.Decoder2()
    got = []
    for chunk in chunked(stream, cuts):
        got += dec.feed(chunk)
    assert len(got) == len(pkts)
    for pkt, raw in zip(got, pkts, strict=True):
        assert p2.Decoder2().feed(raw) == [pkt]


@st.composite
def corrupted2(draw: st.DrawFn) -> tuple[bytes, bytes]:
    raw = draw(packets2())
    bad = bytearray(raw)
    if draw(st.booleans()):
        bit = draw(st.integers(0, 8 * len(raw) - 1))
        bad[bit // 8] ^= 1 << (bit % 8)
    else:
        i = draw(st.integers(0, len(raw) - 2))
        new = draw(st.binary(min_size=2, max_size=2).filter(lambda b: b != raw[i : i + 2]))
        bad[i : i + 2] = new
    return raw, bytes(bad)


@settings(max_examples=1000, deadline=None)
@given(corrupted2(), packets2())
def test_decoder2_rejects_every_corrupted_packet(pair: tuple[bytes, bytes], follower: bytes) -> None:
    _, bad = pair
    dec = p2.Decoder2()
    assert dec.feed(bad) == []
    # and the stream recovers: the next good packet is still decoded, alone
    # (unless the corruption grew the length field, which holds bytes back until rejected)
    got = dec.feed(follower)
    assert all(p2.Decoder2().feed(follower) == [g] for g in got)
    assert len(got) <= 1


# --- Protocol 1.0 -----------------------------------------------------------------------

@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300) | ff_heavy, st.lists(st.integers(0, 400), max_size=8),
       st.none() | st.integers(0, 8))
def test_decoder1_never_crashes_and_checksums_hold(data: bytes, cuts: list[int],
                                                   expect: int | None) -> None:
    dec = p1.Decoder1(expect_params=expect)
    out = []
    for chunk in chunked(data, cuts):
        out += dec.feed(chunk)
    for pkt in out:
        raw = p1.instruction(pkt.id, pkt.first, pkt.params)
        assert raw in data
        if expect is not None:
            assert len(pkt.params) == expect


@st.composite
def status1(draw: st.DrawFn) -> tuple[bytes, int]:
    """A status the bus expects: a position (0..4095, 2 bytes) or a 1-byte register < 0xFF."""
    ident = draw(st.integers(0, 253))
    err = draw(st.integers(0, 0x7F))
    if draw(st.booleans()):
        data = draw(st.integers(0, 4095)).to_bytes(2, "little")
    else:
        data = bytes((draw(st.integers(0, 0xFE)),))
    return p1.status(ident, err, data), len(data)


@settings(max_examples=1000, deadline=None)
@given(status1(), st.data())
def test_decoder1_rejects_any_single_byte_corruption(pair: tuple[bytes, int],
                                                     data: st.DataObject) -> None:
    raw, n = pair
    i = data.draw(st.integers(0, len(raw) - 1))
    new = data.draw(st.integers(0, 255).filter(lambda b: b != raw[i]))
    bad = bytearray(raw)
    bad[i] = new
    assert p1.Decoder1(expect_params=n).feed(bytes(bad)) == []


# --- the emulated servos answer any instruction without crashing -----------------------

@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([1, 2, 3, 7, p2.BROADCAST_ID]),
                          st.sampled_from([0x01, 0x02, 0x03, 0x08, 0x82, 0x83, 0x92])
                          | st.integers(0, 255).filter(lambda i: i != p2.STATUS),
                          params | ff_heavy), min_size=1, max_size=8))
@example([(1, 3, b"\x03\x00")])  # found by the search: protocol 1.0 writes servo 1's ID to 0
def test_emulated_servos_survive_any_instruction(cmds: list[tuple[int, int, bytes]]) -> None:
    from spm_console.devices.dynamixel.control_table import MX106_P1, MX106_P2
    from spm_console.devices.emulator.dispatch import dispatch1, dispatch2
    from spm_console.devices.emulator.servo import EmulatedServo

    for table, dispatch, codec, dec in ((MX106_P2, dispatch2, p2, p2.Decoder2()),
                                        (MX106_P1, dispatch1, p1, p1.Decoder1())):
        servos = {i: EmulatedServo(table, i, 32.22, 2048.0, 0.0) for i in (1, 2, 3)}
        for k, (ident, inst, body) in enumerate(cmds):
            if codec is p1 and len(body) > 250:
                continue
            raw = codec.instruction(ident, inst, body)
            (pkt,) = dec.feed(raw)
            for s in servos.values():
                s.advance(0.01 * (k + 1))
            for rid, reply in dispatch(servos, pkt):  # type: ignore[operator]
                assert rid in {s.id for s in servos.values()}  # a servo, by its current ID
                got = (p2.Decoder2() if codec is p2 else p1.Decoder1()).feed(reply)
                assert len(got) == 1 and got[0].id == rid
        for s in servos.values():
            assert 0.0 <= s.pos < 4096.0 or not s.torque
