"""The vendor's dynamixel-sdk as an independent client of the emulated bus (both protocols).

The SDK builds and parses its own packets (its own CRC, stuffing and framing), so
these tests check the emulator speaks the real protocol, not just our codec.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

dxl = pytest.importorskip("dynamixel_sdk")

from spm_console.config.schema import Profile  # noqa: E402
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator  # noqa: E402
from spm_console.devices.emulator.faults import FaultSpec  # noqa: E402

OK = dxl.COMM_SUCCESS


def protocol1(profile: Profile) -> Profile:
    bus = profile.bus.model_copy(update={"protocol": "1.0", "model_number": 320})
    return profile.model_copy(update={"bus": bus})


@pytest.fixture
def em2(agile: Profile) -> Iterator[EmulatorHandle]:
    with start_emulator(agile, link="pty") as em:
        yield em


@pytest.fixture
def em1(agile: Profile) -> Iterator[EmulatorHandle]:
    with start_emulator(protocol1(agile), link="pty") as em:
        yield em


def open_sdk(port: str, version: float) -> tuple[object, object]:
    ph = dxl.PortHandler(port)
    assert ph.openPort()
    assert ph.setBaudRate(1_000_000)
    return ph, dxl.PacketHandler(version)


def test_sdk_protocol2_ping_read_write(em2: EmulatorHandle) -> None:
    port, pk = open_sdk(em2.port, 2.0)
    try:
        for ident in (1, 2, 3):
            model, res, err = pk.ping(port, ident)
            assert (model, res, err) == (321, OK, 0)
        _, res, _ = pk.ping(port, 9)
        assert res == dxl.COMM_RX_TIMEOUT
        ids, res = pk.broadcastPing(port)
        assert res == OK and sorted(ids) == [1, 2, 3] and ids[2][0] == 321
        pos, res, err = pk.read4ByteTxRx(port, 1, 132)
        assert (pos, res, err) == (2048, OK, 0)
        res, err = pk.write1ByteTxRx(port, 2, 64, 1)  # torque on
        assert (res, err) == (OK, 0)
        res, err = pk.write4ByteTxRx(port, 2, 116, 2100)
        assert (res, err) == (OK, 0)
        time.sleep(0.3)
        pos, res, _ = pk.read4ByteTxRx(port, 2, 132)
        assert res == OK and pos == 2100
        # EEPROM write with torque on: Access Error, reported in the status packet
        res, err = pk.write1ByteTxRx(port, 2, 9, 0)
        assert res == OK and err == 7
        res, err = pk.reboot(port, 2)
        assert (res, err) == (OK, 0)
        torque, res, _ = pk.read1ByteTxRx(port, 2, 64)
        assert (torque, res) == (0, OK)
    finally:
        port.closePort()


def test_sdk_protocol2_sync_write_and_sync_read(em2: EmulatorHandle) -> None:
    port, pk = open_sdk(em2.port, 2.0)
    try:
        for ident in (1, 2, 3):
            assert pk.write1ByteTxRx(port, ident, 64, 1) == (OK, 0)
        sw = dxl.GroupSyncWrite(port, pk, 116, 4)
        goals = {1: 1900, 2: 2048, 3: 2200}
        for ident, g in goals.items():
            assert sw.addParam(ident, list(g.to_bytes(4, "little")))
        assert sw.txPacket() == OK
        time.sleep(0.3)
        sr = dxl.GroupSyncRead(port, pk, 132, 4)
        for ident in goals:
            assert sr.addParam(ident)
        assert sr.txRxPacket() == OK
        got = {i: sr.getData(i, 132, 4) for i in goals}
        assert got == goals
        truth = em2.joint_deg()
        assert np.allclose(truth, [em2.maps[i].to_deg(goals[i + 1]) for i in range(3)], atol=0.01)
    finally:
        port.closePort()


def test_sdk_sees_the_hardware_error_alert(agile: Profile) -> None:
    with start_emulator(agile, faults=[FaultSpec("hwerror", joint=3)], link="pty") as em:
        port, pk = open_sdk(em.port, 2.0)
        try:
            time.sleep(0.02)
            _, res, err = pk.read4ByteTxRx(port, 3, 132)
            assert res == OK and err & 0x80  # Alert bit
            status, res, _ = pk.read1ByteTxRx(port, 3, 70)
            assert res == OK and status == 0x20  # overload
            _, res, err = pk.read4ByteTxRx(port, 1, 132)
            assert res == OK and err == 0
        finally:
            port.closePort()


def test_sdk_rejects_corrupted_replies(agile: Profile) -> None:
    with start_emulator(agile, faults=[FaultSpec("corrupt", rate=1.0)], link="pty") as em:
        port, pk = open_sdk(em.port, 2.0)
        try:
            _, res, _ = pk.read4ByteTxRx(port, 1, 132)
            assert res != OK
            assert em.stats.corrupted >= 1
        finally:
            port.closePort()


def test_sdk_protocol1_ping_read_write_bulk(em1: EmulatorHandle) -> None:
    port, pk = open_sdk(em1.port, 1.0)
    try:
        for ident in (1, 2, 3):
            model, res, err = pk.ping(port, ident)
            assert (model, res, err) == (320, OK, 0)
        pos, res, err = pk.read2ByteTxRx(port, 1, 36)
        assert (pos, res, err) == (2048, OK, 0)
        for ident in (1, 2, 3):
            assert pk.write1ByteTxRx(port, ident, 24, 1) == (OK, 0)
        sw = dxl.GroupSyncWrite(port, pk, 30, 2)
        goals = {1: 2000, 2: 2100, 3: 1950}
        for ident, g in goals.items():
            assert sw.addParam(ident, list(g.to_bytes(2, "little")))
        assert sw.txPacket() == OK
        time.sleep(0.3)
        br = dxl.GroupBulkRead(port, pk)
        for ident in goals:
            assert br.addParam(ident, 36, 2)
        # GroupBulkRead.txPacket of dynamixel-sdk 4.1.0 calls the 1.0 bulkReadTx with one
        # argument too many; use the SDK's own lower layers (makeParam, bulkReadTx, rxPacket)
        br.makeParam()
        assert pk.bulkReadTx(port, br.param, len(br.param)) == OK
        assert br.rxPacket() == OK
        assert {i: br.getData(i, 36, 2) for i in goals} == goals
    finally:
        port.closePort()


def test_the_bus_benchmark_compares_with_the_sdk_on_a_link_it_can_open() -> None:
    """``python -m benchmarks bus`` runs to its end: the SDK's side of the comparison opens a
    pty (it cannot open the default link's ``unix:`` socket), and every row has its figure."""
    from benchmarks import bench_bus

    rows = bench_bus.run()
    sdk_row = next(r for r in rows if r.name.startswith("bus: cycles whose reply timed out"))
    assert sdk_row.baseline == 0  # every sync read of the vendor SDK succeeded
    assert all(np.isfinite(r.value) for r in rows)
