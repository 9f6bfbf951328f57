"""Our DynamixelBus against the emulated MX-106 bus, over both of its links: a Unix-domain
socket (the default) and a real pseudo-terminal."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from spm_console.config.schema import Profile
from spm_console.core.servo.model import continuous
from spm_console.devices.base import CommError, ServoBus
from spm_console.devices.dynamixel.bus import DynamixelBus, LimitError, open_bus
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.errors import BusError

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)


def relaxed(profile: Profile, timeout_s: float = 0.03) -> Profile:
    """The profile with a 30 ms reply timeout: a loaded 2-core test machine can delay the
    emulator thread by more than the real 4 ms; these tests are not about timing."""
    return profile.model_copy(update={"bus": profile.bus.model_copy(
        update={"timeout_s": timeout_s})})


def protocol1(profile: Profile) -> Profile:
    bus = profile.bus.model_copy(update={"protocol": "1.0", "model_number": 320})
    return profile.model_copy(update={"bus": bus})


class RawClient:
    """Bytes to and from the emulated bus, below our transport: pyserial on the pty, a plain
    socket on the socket."""

    def __init__(self, em: EmulatorHandle) -> None:
        import serial

        self.ser: serial.Serial | None = None
        self.sock: socket.socket | None = None
        if em.link == "pty":
            self.ser = serial.Serial(em.port, 1_000_000, timeout=0.05)
        else:
            self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self.sock.connect(em.port.removeprefix("unix:"))
            self.sock.settimeout(0.05)

    def write(self, data: bytes) -> None:
        if self.ser is not None:
            self.ser.write(data)
        else:
            assert self.sock is not None
            self.sock.sendall(data)

    def read(self, n: int) -> bytes:
        if self.ser is not None:
            return bytes(self.ser.read(n))
        assert self.sock is not None
        got = b""
        end = time.perf_counter() + 0.5
        while len(got) < n and time.perf_counter() < end:
            try:
                got += self.sock.recv(n - len(got))
            except TimeoutError:
                continue
        return got

    def close(self) -> None:
        if self.ser is not None:
            self.ser.close()
        if self.sock is not None:
            self.sock.close()


@contextmanager
def raw_client(em: EmulatorHandle) -> Iterator[RawClient]:
    client = RawClient(em)
    try:
        yield client
    finally:
        client.close()


#: The e-manual's example READ of servo 1's Present Position (protocol 2.0).
READ_POSITION = bytes.fromhex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")


@pytest.fixture(params=[("2.0", "socket"), ("2.0", "pty"), ("1.0", "socket"), ("1.0", "pty")],
                ids=lambda p: f"{p[0]}-{p[1]}")
def rig(request: pytest.FixtureRequest, agile: Profile) -> Iterator[tuple[EmulatorHandle,
                                                                          DynamixelBus]]:
    protocol, link = request.param
    prof = agile if protocol == "2.0" else protocol1(agile)
    em = start_emulator(prof, link=link)
    bus = open_bus(relaxed(prof), em.port)
    yield em, bus
    bus.close()
    em.stop()


def test_bus_is_a_servo_bus(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    assert isinstance(rig[1], ServoBus)


def test_ping_all_checks_the_model(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    _em, bus = rig
    st = bus.ping_all()
    want = 321 if bus.protocol == "2.0" else 320
    assert [(s.id, s.model_number, s.hardware_error) for s in st] == [(i, want, 0) for i in (1, 2, 3)]


def test_wrong_model_and_absent_servo_are_bus_errors(rig: tuple[EmulatorHandle, DynamixelBus],
                                                     agile: Profile) -> None:
    em, bus = rig
    wrong = bus.profile.model_copy(update={"bus": bus.profile.bus.model_copy(
        update={"model_number": 1030})})
    other = open_bus(wrong, em.port, exclusive=False)  # beside the rig's own bus
    try:
        with pytest.raises(BusError, match="model"):
            other.ping_all()
    finally:
        other.close()
    t0 = time.perf_counter()
    with pytest.raises(BusError, match="no status packet from servo id 7"):
        bus.ping(7)
    assert time.perf_counter() - t0 < 0.5


def test_read_home_and_initial_pose(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    em, bus = rig
    assert np.allclose(bus.read_position_deg(), [135, 135, 135], atol=360 / 4096)
    em.set_joint_deg([100.0, 120.5, 150.25])
    assert np.allclose(bus.read_position_deg(), [100.0, 120.5, 150.25], atol=0.5 * 360 / 4096)


def test_goal_outside_limits_refused_not_clamped(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    em, bus = rig
    bus.set_torque(True)
    with pytest.raises(LimitError, match=r"joint 2.*outside its limits") as info:
        bus.write_goal_deg([135.0, 160.5, 135.0])
    assert info.value.joint == 2 and info.value.limits_deg == (60.0, 160.0)
    with pytest.raises(LimitError):
        bus.write_goal_deg([59.9, 135.0, 135.0])
    with pytest.raises(Exception, match="finite"):
        bus.write_goal_deg([float("nan"), 135.0, 135.0])
    time.sleep(0.05)
    assert [bus.read(i, "goal_position") for i in bus.ids] == [2048, 2048, 2048]
    assert np.allclose(em.joint_deg(), 135.0)


def test_torque_off_servo_does_not_move(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    em, bus = rig
    bus.write_goal_deg([140.0, 130.0, 135.0])
    time.sleep(0.15)
    assert np.allclose(em.joint_deg(), 135.0)
    assert bus.torque() == [False, False, False]


def test_step_follows_closed_loop_model(rig: tuple[EmulatorHandle, DynamixelBus],
                                        agile: Profile) -> None:
    em, bus = rig
    bus.set_torque(True)
    em.start_clock()
    bus.write_goal_deg([140.0, 130.0, 135.0])
    time.sleep(0.25)
    meas = bus.read_position_deg()
    truth = em.true_state()
    assert np.allclose(meas, [140.0, 130.0, 135.0], atol=0.1)  # settled (p = 32 rad/s)
    # every recorded step of the truth obeys exp(Ac dt) of model (27), independently computed
    Ac, _ = continuous(agile.servo.p)
    t, pos, vel = truth["t"], truth["position_deg"], truth["velocity_degps"]
    # the goal the servos got: whole ticks (140° is tick 2104.89 -> 2105 = 140.0098°)
    goal = np.array([m.to_deg(g) for m, g in zip(bus.maps, bus.goal_ticks([140, 130, 135]),
                                                  strict=True)])
    k0 = int(np.argmax(np.abs(vel[:, 0]) > 0))  # first sample after the goal arrived
    assert k0 > 0 and t[-1] - t[k0] > 0.2
    for k in range(k0, len(t) - 1):
        dt = t[k + 1] - t[k]
        Phi = expm(Ac * dt)
        for j in range(2):  # joints that moved
            x = np.array([pos[k, j] - goal[j], vel[k, j]])
            x1 = Phi @ x
            assert x1[0] + goal[j] == pytest.approx(pos[k + 1, j], abs=1e-9)
            assert x1[1] == pytest.approx(vel[k + 1, j], abs=1e-6)
    # measured = true position quantized to 4096 ticks per turn
    assert np.all(np.abs(meas - pos[-1]) <= 0.5 * 360 / 4096 + 1e-9)


def test_many_cycles_no_comm_error(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    em, bus = rig
    bus.set_torque(True)
    for k in range(100):
        theta = 135.0 + 5.0 * np.sin(0.1 * k + np.array([0.0, 2.0, 4.0]))
        bus.write_goal_deg(theta)
        bus.read_position_deg()
    assert em.stats.dropped == em.stats.corrupted == 0
    assert em.stats.rejected_bytes == 0


def test_register_access_rules(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    _em, bus = rig
    bus.write(1, "return_delay_time", 0)
    bus.set_torque(True)
    with pytest.raises(BusError, match=r"access error|range error"):
        bus.write(1, "return_delay_time", 5)  # EEPROM is locked while torque is on
    with pytest.raises(Exception, match="read-only"):
        bus.write(1, "present_position", 5)
    assert bus.read(2, "model_number") == (321 if bus.protocol == "2.0" else 320)


def test_comm_error_is_prompt_when_a_servo_is_missing(agile: Profile) -> None:
    prof = agile.model_copy(update={"bus": agile.bus.model_copy(update={"joints": (
        agile.bus.joints[0], agile.bus.joints[1],
        agile.bus.joints[2].model_copy(update={"id": 9}))})})
    with start_emulator(agile) as em:
        bus = open_bus(relaxed(prof), em.port)
        t0 = time.perf_counter()
        with pytest.raises(CommError, match="2 of 3"):
            bus.read_position_deg()
        assert time.perf_counter() - t0 < 3 * 0.03 + 0.1
        bus.close()


def test_open_bus_on_missing_port(agile: Profile) -> None:
    with pytest.raises(BusError, match="cannot open serial port /dev/does-not-exist"):
        open_bus(agile, "/dev/does-not-exist")
    with pytest.raises(BusError, match="no serial port"):
        open_bus(agile, "")


@pytest.mark.parametrize("link", ["socket", "pty"])
def test_emulator_survives_line_garbage(agile: Profile, link: str) -> None:
    with start_emulator(agile, link=link) as em:  # type: ignore[arg-type]
        with raw_client(em) as raw:
            raw.write(b"\xff\xff\xfd\x00\x01\xff\xff" + bytes(range(256)) + b"\xff\xff\xfd")
            raw.write(READ_POSITION)
            reply = raw.read(15)
        # the READ after the garbage is answered with a valid status (position 2048)
        assert reply[:9] == bytes.fromhex("FF FF FD 00 01 08 00 55 00")
        assert int.from_bytes(reply[9:13], "little") == 2048
        assert em.stats.rejected_bytes > 0 and em.running
        bus = open_bus(relaxed(agile), em.port)
        assert np.allclose(bus.read_position_deg(), 135.0)
        bus.close()


@pytest.mark.parametrize("link", ["socket", "pty"])
def test_a_stale_partial_header_does_not_hold_the_line(agile: Profile, link: str) -> None:
    with start_emulator(agile, link=link) as em:  # type: ignore[arg-type]
        with raw_client(em) as raw:
            raw.write(bytes.fromhex("FF FF FD 00 01 E8 03"))  # a header announcing 1000 bytes
            time.sleep(0.05)
            raw.write(READ_POSITION)  # on the same stream, after the firmware's byte timeout
            reply = raw.read(15)
        assert int.from_bytes(reply[9:13], "little") == 2048
        bus = open_bus(relaxed(agile), em.port)
        assert np.allclose(bus.read_position_deg(), 135.0)
        bus.close()


def test_one_lost_ping_reply_is_retried_not_a_missing_servo(
        rig: tuple[EmulatorHandle, DynamixelBus], monkeypatch: pytest.MonkeyPatch) -> None:
    _, bus = rig
    real_ping = bus.link.ping
    lost = {"n": 0}

    def flaky_ping(ident: int):  # type: ignore[no-untyped-def]
        if lost["n"] < 2:  # the first two replies are lost (fewer than the set-up tries)
            lost["n"] += 1
            raise CommError("no status packet (injected)")
        return real_ping(ident)

    monkeypatch.setattr(bus.link, "ping", flaky_ping)
    assert [s.id for s in bus.ping_all()] == [1, 2, 3]
    assert lost["n"] == 2
    lost["n"] = -10  # now every reply is lost: the servo is reported absent
    with pytest.raises(BusError, match="no status packet from servo id 1"):
        bus.ping(1)


def test_the_profile_names_the_link_and_the_socket_serves_clients_apart(agile: Profile) -> None:
    """``emulator.link`` picks the link; on the socket each client gets its own replies, and
    a client that leaves (even mid-packet) leaves the others served."""
    pty_profile = agile.model_copy(update={"emulator": agile.emulator.model_copy(
        update={"link": "pty"})})
    with start_emulator(pty_profile) as em:
        assert em.link == "pty" and em.port.startswith("/dev/")
    with start_emulator(agile) as em:
        assert em.link == "socket" and em.port.startswith("unix:")
        first = open_bus(relaxed(agile), em.port, exclusive=False)  # the emulator's serving;
        second = open_bus(relaxed(agile), em.port, exclusive=False)  # a product has one owner
        with raw_client(em) as leaving:
            leaving.write(READ_POSITION[:5])
        for _ in range(20):
            assert np.allclose(first.read_position_deg(), 135.0)
            assert np.allclose(second.read_position_deg(), 135.0)
        assert first.stale_replies == 0 and second.stale_replies == 0
        first.close()
        assert np.allclose(second.read_position_deg(), 135.0)
        second.close()
    with pytest.raises(BusError, match="cannot connect to the bus socket"):
        open_bus(agile, em.port)  # the emulator is gone, and its socket with it


@pytest.mark.parametrize("link", ["socket", "pty"])
def test_a_bus_whose_emulator_is_gone_fails_with_comm_errors(agile: Profile, link: str) -> None:
    """The far end closed (the emulator stopped), then our own end closed: every transaction
    fails promptly with CommError, never hangs, spins or raises something else."""
    em = start_emulator(agile, link=link)  # type: ignore[arg-type]
    bus = open_bus(relaxed(agile), em.port)
    assert np.allclose(bus.read_position_deg(), 135.0)
    em.stop()
    for _ in range(2):
        t0 = time.perf_counter()
        with pytest.raises(CommError):
            bus.read_position_deg()
        assert time.perf_counter() - t0 < 1.0
    bus.close()
    with pytest.raises(CommError):
        bus.read_position_deg()


def test_a_socket_folder_that_cannot_be_served_is_a_bus_error(
        agile: Profile, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A socket path over the 107-byte limit: refused as a BusError naming the remedy, and no
    folder is left behind."""
    from spm_console.devices.emulator import endpoint

    deep = tmp_path / ("d" * 100)
    deep.mkdir()
    monkeypatch.setattr(endpoint, "_short_tmp", lambda: str(deep))
    with pytest.raises(BusError, match='link = "pty"'):
        start_emulator(agile)
    assert list(deep.iterdir()) == []
