"""Every fault of the emulated bus, seen through our DynamixelBus (and the fault syntax)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.devices.base import CommError
from spm_console.devices.dynamixel.bus import DynamixelBus, open_bus
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.devices.emulator.faults import FaultSpec, parse_fault
from spm_console.errors import BadInputError, BusError

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)


@contextmanager
def rig(profile: Profile, *faults: str,
        timeout_s: float = 0.03) -> Iterator[tuple[EmulatorHandle, DynamixelBus]]:
    """Emulator + bus. The reply timeout is relaxed from the profile's 4 ms to 30 ms so
    that a loaded 2-core test machine does not add timeouts of its own to the faults."""
    em = start_emulator(profile, [parse_fault(f) for f in faults])
    bus = open_bus(profile.model_copy(update={"bus": profile.bus.model_copy(
        update={"timeout_s": timeout_s})}), em.port)
    try:
        yield em, bus
    finally:
        bus.close()
        em.stop()


# --- syntax -------------------------------------------------------------------------------

@pytest.mark.parametrize(("text", "spec"), [
    ("unplug@1.0", FaultSpec("unplug", 1.0)),
    ("stall:2@0.5", FaultSpec("stall", 0.5, joint=2)),
    ("drop:0.05", FaultSpec("drop", rate=0.05)),
    ("corrupt:0.02", FaultSpec("corrupt", rate=0.02)),
    ("delay:0.03@1.0", FaultSpec("delay", 1.0, delay_s=0.03)),
    ("hwerror:1@0.5", FaultSpec("hwerror", 0.5, joint=1)),
    (" UNPLUG ", FaultSpec("unplug")),
])
def test_parse_fault(text: str, spec: FaultSpec) -> None:
    assert parse_fault(text) == spec
    assert parse_fault(str(spec)) == spec


@pytest.mark.parametrize(("text", "why"), [
    ("", "empty"), ("explode@1", "unknown kind"), ("stall@1", "needs an argument"),
    ("stall:4", "joint"), ("stall:1.5", "joint"), ("drop:1.5", "rate"), ("drop:0", "rate"),
    ("drop:x", "not a decimal number"), ("unplug:3", "no argument"), ("unplug@-1", "≥ 0"),
    ("delay:0", "delay"), ("unplug@nan", "finite"), ("hwerror:0@1", "joint"),
])
def test_parse_fault_refuses_bad_text(text: str, why: str) -> None:
    with pytest.raises(BadInputError, match=why):
        parse_fault(text)


# --- behaviour ----------------------------------------------------------------------------

def test_drop_all_replies_is_a_prompt_comm_error(agile: Profile) -> None:
    with rig(agile, "drop:1.0", timeout_s=agile.bus.timeout_s) as (em, bus):
        t0 = time.perf_counter()
        with pytest.raises(CommError, match="0 of 3 received"):
            bus.read_position_deg()
        assert time.perf_counter() - t0 < 0.1  # 4 ms timeout: prompt, no long hang
        assert em.stats.dropped == 3


def test_low_rate_drops_fail_some_reads_and_spare_the_rest(agile: Profile) -> None:
    with rig(agile, "drop:0.05") as (em, bus):
        ok = failed = 0
        for _ in range(200):
            try:
                bus.read_position_deg()
                ok += 1
            except CommError:
                failed += 1
        # 3 replies per read at 5 %: P(read fails) = 1 - 0.95^3 ≈ 14 %
        assert 5 <= failed <= 60 and ok + failed == 200
        assert em.stats.dropped >= failed


def test_corrupt_replies_are_rejected_never_trusted(agile: Profile) -> None:
    with rig(agile, "corrupt:1.0") as (em, bus):
        with pytest.raises(CommError, match="3 corrupt"):
            bus.read_position_deg()
        assert em.stats.corrupted == 3


def test_low_rate_corruption(agile: Profile) -> None:
    with rig(agile, "corrupt:0.1") as (em, bus):
        em.set_joint_deg([100.0, 110.0, 120.0])
        failed = 0
        for _ in range(100):
            try:
                assert np.allclose(bus.read_position_deg(), [100, 110, 120], atol=0.05)
            except CommError:
                failed += 1
        assert failed > 0 and em.stats.corrupted >= failed


def test_delayed_replies_time_out_and_never_arrive_as_stale_data(agile: Profile) -> None:
    with rig(agile, "delay:0.05") as (em, bus):
        for _ in range(3):
            with pytest.raises(CommError):
                bus.read_position_deg()
            time.sleep(0.03)  # the late replies of the previous read land now
        assert em.stats.delayed >= 3
    with rig(agile, "delay:0.001") as (em, bus):  # a short delay within the timeout
        assert np.allclose(bus.read_position_deg(), 135.0)


def test_set_up_waits_longer_than_the_loop_but_not_forever(agile: Profile) -> None:
    """A bus slower than the link's timeout: the loop's reads time out, but set-up (ping,
    status) retries with more patience and finds the servos; a bus slower than the most
    patient try reports the servo absent."""
    with rig(agile, "delay:0.04", timeout_s=0.004) as (_, bus):
        assert [s.id for s in bus.ping_all()] == [1, 2, 3]
        time.sleep(0.1)  # the late replies of the set-up's first tries land and are dropped
        with pytest.raises(CommError):
            bus.read_position_deg()
        assert bus.transport.timeout_s == 0.004  # the patience ended with the set-up
    with rig(agile, "delay:0.6", timeout_s=0.004) as (_, bus), \
            pytest.raises(BusError, match="no status packet from servo id 1"):
        bus.ping(1)


def test_delay_starts_at_its_time(agile: Profile) -> None:
    with rig(agile, "delay:0.05@0.3") as (em, bus):
        em.start_clock()
        assert np.allclose(bus.read_position_deg(), 135.0)
        time.sleep(0.35)
        with pytest.raises(CommError):
            bus.read_position_deg()


def test_stall_freezes_one_joint(agile: Profile) -> None:
    with rig(agile, "stall:2@0.0") as (em, bus):
        bus.set_torque(True)
        bus.write_goal_deg([140.0, 140.0, 140.0])
        time.sleep(0.3)
        pos = bus.read_position_deg()
        assert pos[0] == pytest.approx(140.0, abs=0.1) and pos[2] == pytest.approx(140.0, abs=0.1)
        assert pos[1] == pytest.approx(135.0, abs=0.05)
        assert np.all(em.true_state()["velocity_degps"][:, 1] == 0.0)


def test_hardware_error_alert_drops_torque_until_reboot(agile: Profile) -> None:
    with rig(agile, "hwerror:1@0.1") as (em, bus):
        bus.set_torque(True)
        em.start_clock()
        assert bus.hardware_errors() == [0, 0, 0]
        time.sleep(0.15)
        bus.read_position_deg()
        assert bus.alerts[1] and not bus.alerts[2]  # Alert bit of every status from id 1
        assert bus.hardware_errors() == [0x20, 0, 0]
        assert bus.describe_hardware_error(0x20) == "overload"
        assert bus.torque() == [False, True, True]
        with pytest.raises(BusError, match="result fail"):
            bus.set_torque(True, [1])  # a latched error keeps torque off
        bus.reboot([1])
        assert bus.hardware_errors() == [0, 0, 0]
        bus.set_torque(True, [1])
        assert bus.torque() == [True, True, True]


def test_unplug_silences_the_bus(agile: Profile) -> None:
    with rig(agile, "unplug@0.1") as (em, bus):
        em.start_clock()
        bus.set_torque(True)
        assert len(bus.ping_all()) == 3
        time.sleep(0.15)
        bus.write_goal_deg([140.0, 140.0, 140.0])  # never reaches the servos
        with pytest.raises(CommError):
            bus.read_position_deg()
        with pytest.raises(BusError, match="no status packet"):
            bus.ping_all()
        time.sleep(0.1)
        assert np.allclose(em.joint_deg(), 135.0)
        assert em.stats.silenced >= 2


def test_fault_times_rebase_on_start_clock(agile: Profile) -> None:
    with rig(agile) as (em, bus):
        time.sleep(0.25)
        em.inject(FaultSpec("unplug", 0.2))
        em.start_clock()
        assert np.allclose(bus.read_position_deg(), 135.0)  # 0.2 s after the new clock start
        time.sleep(0.25)
        with pytest.raises(CommError):
            bus.read_position_deg()
        assert em.stats.faults_fired == ["unplug@0.2"]


def test_bus_watchdog_stops_a_servo_when_the_host_goes_quiet(agile: Profile) -> None:
    with rig(agile) as (_em, bus):
        assert bus.set_watchdog(100) == 5
        bus.set_torque(True)
        bus.write_goal_deg([150.0, 150.0, 150.0])
        time.sleep(0.3)  # quiet for longer than 100 ms while the servos move
        pos = bus.read_position_deg()
        assert bus.read(1, "bus_watchdog") == -1
        # stopped near where the watchdog fired (100 ms into the 15° step), not at 150°
        assert np.all(pos < 149.0) and np.all(pos > 140.0)
        bus.write_goal_deg([150.0, 150.0, 150.0])  # refused while the watchdog is tripped
        time.sleep(0.1)
        assert np.allclose(bus.read_position_deg(), pos, atol=0.1)
        assert bus.set_watchdog(100) == 5  # clears the trip (write 0, then the period)
        bus.write_goal_deg([150.0, 150.0, 150.0])
        for _ in range(20):  # keep talking: the watchdog stays quiet
            time.sleep(0.02)
            bus.read_position_deg()
        assert np.allclose(bus.read_position_deg(), 150.0, atol=0.1)


def test_protocol1_hardware_error_and_no_reboot(agile: Profile) -> None:
    prof = agile.model_copy(update={"bus": agile.bus.model_copy(
        update={"protocol": "1.0", "model_number": 320})})
    with rig(prof, "hwerror:2@0") as (_em, bus):
        time.sleep(0.02)
        bus.read_position_deg()
        assert bus.alerts == {1: 0, 2: 0x20, 3: 0}  # overload bit of the 1.0 status byte
        assert bus.hardware_errors() == [0, 0x20, 0]
        assert bus.describe_hardware_error(0x20) == "overload"
        with pytest.raises(BusError, match="no REBOOT"):
            bus.reboot()
        assert bus.set_watchdog(100) == 0  # no Bus Watchdog on 1.0


def test_position_noise_is_what_the_profile_says(agile: Profile) -> None:
    noisy = agile.model_copy(update={"emulator": agile.emulator.model_copy(
        update={"noise_deg": 0.3})})
    with rig(noisy) as (_em, bus):
        reads = np.array([bus.read_position_deg() for _ in range(300)])
    assert reads.std(axis=0) == pytest.approx([0.3, 0.3, 0.3], rel=0.2)
    assert abs(reads.mean() - 135.0) < 0.05
    steps = np.diff(np.unique(reads)) / (360 / 4096)  # readings are whole ticks
    assert np.allclose(steps, np.round(steps))
