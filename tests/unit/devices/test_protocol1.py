"""Protocol 1.0 codec against the vendor e-manual's byte-exact examples ("Protocol 1.0" page)."""

from __future__ import annotations

import pytest

from spm_console.devices.dynamixel import protocol1 as p1


def h(text: str) -> bytes:
    return bytes.fromhex(text)


PING_1 = h("FF FF 01 02 01 FB")
PING_REPLY_1 = h("FF FF 01 02 00 FC")
READ_1 = h("FF FF 01 04 02 2B 01 CC")  # Present Temperature (43), 1 byte
READ_REPLY_1 = h("FF FF 01 03 00 20 DB")  # = 32
WRITE_BCAST = h("FF FF FE 04 03 03 01 F6")  # ID (3) := 1
REG_WRITE_1 = h("FF FF 01 05 04 1E F4 01 E2")  # Goal Position (30) := 500
SYNC_WRITE = h("FF FF FE 0E 83 1E 04 00 10 00 50 01 01 20 02 60 03 67")
BULK_READ = h("FF FF FE 09 92 00 02 01 1E 02 02 24 1D")
BULK_REPLY_1 = h("FF FF 01 04 00 00 80 7A")
BULK_REPLY_2 = h("FF FF 02 04 00 00 80 79")


def test_checksums_of_vendor_examples() -> None:
    for pkt in (PING_1, PING_REPLY_1, READ_1, READ_REPLY_1, WRITE_BCAST, REG_WRITE_1,
                SYNC_WRITE, BULK_READ, BULK_REPLY_1, BULK_REPLY_2):
        assert p1.checksum(pkt[2:-1]) == pkt[-1]


def test_encode_byte_exact() -> None:
    assert p1.ping(1) == PING_1
    assert p1.read(1, 0x2B, 1) == READ_1
    assert p1.write(p1.BROADCAST_ID, 3, b"\x01") == WRITE_BCAST
    assert p1.instruction(1, p1.Inst.REG_WRITE, bytes((0x1E, 0xF4, 0x01))) == REG_WRITE_1
    assert p1.sync_write(0x1E, 4, [(0, h("10 00 50 01")), (1, h("20 02 60 03"))]) == SYNC_WRITE
    assert p1.bulk_read([(1, 0x1E, 2), (2, 0x24, 2)]) == BULK_READ
    assert p1.status(1) == PING_REPLY_1
    assert p1.status(1, 0, b"\x20") == READ_REPLY_1
    assert p1.status(2, 0, h("00 80")) == BULK_REPLY_2


def test_decode_stream_with_garbage() -> None:
    dec = p1.Decoder1()
    pkts = dec.feed(b"\x12\xff" + BULK_REPLY_1 + b"\xff\xff\xff" + BULK_REPLY_2)
    assert [(p.id, p.error, p.params) for p in pkts] == [(1, 0, h("00 80")), (2, 0, h("00 80"))]


def test_decode_instruction() -> None:
    (pkt,) = p1.Decoder1().feed(SYNC_WRITE)
    assert pkt.id == 0xFE and pkt.instruction == p1.Inst.SYNC_WRITE
    assert pkt.params == SYNC_WRITE[5:-1]


def test_expected_length_rejects_other_frames() -> None:
    dec = p1.Decoder1(expect_params=2)
    assert dec.feed(READ_REPLY_1) == [] and dec.rejected == 1
    assert [p.id for p in dec.feed(BULK_REPLY_1)] == [1]


def test_bad_checksum_rejected() -> None:
    bad = bytearray(BULK_REPLY_1)
    bad[-1] ^= 0x10
    dec = p1.Decoder1()
    assert dec.feed(bytes(bad)) == [] and dec.rejected == 1
    assert [p.id for p in dec.feed(BULK_REPLY_2)] == [2]


def test_error_bits_survive() -> None:
    (pkt,) = p1.Decoder1().feed(p1.status(4, 0x24))  # overheat + overload
    assert pkt.error == 0x24


def test_invalid_arguments() -> None:
    with pytest.raises(ValueError):
        p1.ping(300)
    with pytest.raises(ValueError):
        p1.sync_write(30, 2, [(1, b"\x00")])
