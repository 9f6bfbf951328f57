"""Protocol 2.0 codec against the vendor e-manual's byte-exact examples ("Protocol 2.0" page)."""

from __future__ import annotations

import pytest

from spm_console.devices.dynamixel import protocol2 as p2


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# e-manual, Protocol 2.0: instruction packets (XM430-W210 examples)
PING_1 = h("FF FF FD 00 01 03 00 01 19 4E")
PING_BCAST = h("FF FF FD 00 FE 03 00 01 31 42")
PING_REPLY_1 = h("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D")  # model 1030, firmware 38
PING_REPLY_2 = h("FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D")
READ_1 = h("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")  # Present Position (132), 4 bytes
READ_REPLY_1 = h("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0")  # = 166
WRITE_1 = h("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89")  # Goal Position (116) = 512
EMPTY_STATUS_1 = h("FF FF FD 00 01 04 00 55 00 A1 0C")
REBOOT_1 = h("FF FF FD 00 01 03 00 08 2F 4E")
SYNC_READ = h("FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA")
SYNC_READ_REPLY_2 = h("FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE")  # = 2079
SYNC_WRITE = h("FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87")
BULK_READ = h("FF FF FD 00 FE 0D 00 92 01 90 00 02 00 02 92 00 01 00 1A 05")
BULK_REPLY_1 = h("FF FF FD 00 01 06 00 55 00 77 00 C3 69")  # Present Input Voltage = 119
BULK_REPLY_2 = h("FF FF FD 00 02 05 00 55 00 24 8B A9")  # Present Temperature = 36


def test_crc16_check_value() -> None:
    assert p2.crc16(b"123456789") == 0xFEE8  # CRC-16/BUYPASS check value
    assert p2.crc16(b"") == 0


@pytest.mark.parametrize("packet", [PING_1, PING_BCAST, PING_REPLY_1, PING_REPLY_2, READ_1,
                                    READ_REPLY_1, WRITE_1, EMPTY_STATUS_1, REBOOT_1, SYNC_READ,
                                    SYNC_READ_REPLY_2, SYNC_WRITE, BULK_READ, BULK_REPLY_1,
                                    BULK_REPLY_2])
def test_crc_of_every_vendor_example(packet: bytes) -> None:
    crc = p2.crc16(packet[:-2])
    assert packet[-2:] == bytes((crc & 0xFF, crc >> 8))


def test_encode_instructions_byte_exact() -> None:
    assert p2.ping(1) == PING_1
    assert p2.ping(p2.BROADCAST_ID) == PING_BCAST
    assert p2.read(1, 132, 4) == READ_1
    assert p2.write(1, 116, (512).to_bytes(4, "little")) == WRITE_1
    assert p2.reboot(1) == REBOOT_1
    assert p2.sync_read(132, 4, [1, 2]) == SYNC_READ
    assert p2.sync_write(116, 4, [(1, (150).to_bytes(4, "little")),
                                  (2, (170).to_bytes(4, "little"))]) == SYNC_WRITE
    assert p2.bulk_read([(1, 144, 2), (2, 146, 1)]) == BULK_READ


def test_encode_status_byte_exact() -> None:
    assert p2.status(1, 0, bytes((0x06, 0x04, 0x26))) == PING_REPLY_1
    assert p2.status(2, 0, bytes((0x06, 0x04, 0x26))) == PING_REPLY_2
    assert p2.status(1, 0, (166).to_bytes(4, "little")) == READ_REPLY_1
    assert p2.status(2, 0, (2079).to_bytes(4, "little")) == SYNC_READ_REPLY_2
    assert p2.status(1) == EMPTY_STATUS_1
    assert p2.status(1, 0, (119).to_bytes(2, "little")) == BULK_REPLY_1
    assert p2.status(2, 0, bytes((36,))) == BULK_REPLY_2


def test_decode_status_stream() -> None:
    dec = p2.Decoder2()
    pkts = dec.feed(READ_REPLY_1 + SYNC_READ_REPLY_2)
    assert [(p.id, p.is_status, p.error, int.from_bytes(p.params, "little")) for p in pkts] == [
        (1, True, 0, 166), (2, True, 0, 2079)]
    ping = dec.feed(PING_REPLY_1)[0]
    assert (ping.params[0] | ping.params[1] << 8, ping.params[2]) == (1030, 38)


def test_decode_instruction() -> None:
    (pkt,) = p2.Decoder2().feed(SYNC_WRITE)
    assert pkt.id == p2.BROADCAST_ID and pkt.instruction == p2.Inst.SYNC_WRITE
    assert pkt.params == SYNC_WRITE[8:-2] and pkt.error is None


def test_byte_by_byte_and_garbage_resync() -> None:
    dec = p2.Decoder2()
    stream = b"\x00\xff\xff\x13" + READ_REPLY_1 + b"\xff\xff\xfd" + BULK_REPLY_2
    got = []
    for b in stream:
        got += dec.feed(bytes((b,)))
    assert [p.id for p in got] == [1, 2]
    assert dec.pending == 0


def test_error_and_alert_bits() -> None:
    raw = p2.status(3, p2.ALERT | p2.ErrorNumber.DATA_LIMIT)
    (pkt,) = p2.Decoder2().feed(raw)
    assert pkt.alert and pkt.error_number == 6
    assert p2.describe_error(6) == "data limit error"
    (ok,) = p2.Decoder2().feed(p2.status(3, p2.ALERT))
    assert ok.alert and ok.error_number == 0


def test_byte_stuffing_roundtrip_and_length() -> None:
    data = bytes((0xFF, 0xFF, 0xFD, 0x00))
    raw = p2.write(1, 0x0200, data)
    # INST 03, address 00 02, then FF FF FD FD 00: one stuffed byte, LEN = 1 + 2 + 5 + 2
    assert raw[7:15] == bytes((0x03, 0x00, 0x02, 0xFF, 0xFF, 0xFD, 0xFD, 0x00))
    assert raw[5] | raw[6] << 8 == 10
    (pkt,) = p2.Decoder2().feed(raw)
    assert pkt.params == bytes((0x00, 0x02)) + data
    assert p2.unstuff(p2.stuff(b"\xff\xff\xfd\xfd\xff\xff\xfd")) == b"\xff\xff\xfd\xfd\xff\xff\xfd"
    assert p2.stuff(b"\xff\xff\xff\xfd") == b"\xff\xff\xff\xfd\xfd"


def test_unstuffed_pattern_inside_body_rejected() -> None:
    # a body holding FF FF FD 01 (missing stuffing byte) with a correct CRC is still invalid
    body = bytes((0x03, 0x00, 0x00, 0xFF, 0xFF, 0xFD, 0x01))
    head = p2.HEADER + bytes((1, len(body) + 2, 0))
    crc = p2.crc16(head + body)
    dec = p2.Decoder2()
    assert dec.feed(head + body + bytes((crc & 0xFF, crc >> 8))) == []
    assert dec.rejected >= 1


def test_corrupted_crc_rejected_and_next_packet_kept() -> None:
    bad = bytearray(READ_REPLY_1)
    bad[-1] ^= 0x01
    dec = p2.Decoder2()
    pkts = dec.feed(bytes(bad) + SYNC_READ_REPLY_2)
    assert [p.id for p in pkts] == [2] and dec.rejected == 1


def test_invalid_arguments() -> None:
    with pytest.raises(ValueError):
        p2.ping(253)
    with pytest.raises(ValueError):
        p2.sync_write(116, 4, [(1, b"\x00\x00")])
