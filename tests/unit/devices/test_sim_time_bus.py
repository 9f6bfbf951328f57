"""Our bus against the emulated bus in simulated time: replies and timeouts in simulated
seconds, each transaction taking its bytes' time on the wire, faults at their simulated
instants, and the same replies for the same requests at the same instants."""

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
from spm_console.devices.emulator.faults import parse_fault
from spm_console.system.simclock import SimClock


@contextmanager
def lockstep(profile: Profile, faults: tuple[str, ...] = ()
             ) -> Iterator[tuple[SimClock, EmulatorHandle, DynamixelBus]]:
    clock = SimClock.create(100.0)
    em = start_emulator(profile, [parse_fault(f) for f in faults], sim=clock)
    bus = open_bus(profile, em.port, sim=clock)
    try:
        yield clock, em, bus
    finally:
        bus.close()
        em.stop()
        clock.close()


def _wire_s(profile: Profile, n_bytes: int) -> float:
    return n_bytes * 10.0 / profile.bus.baud


def test_a_transaction_takes_its_bytes_time_on_the_wire(agile: Profile) -> None:
    with lockstep(agile) as (clock, _em, bus):
        bus.read_ticks()  # the reply shapes are settled on the first read
        out, inn, t = bus.transport.bytes_out, bus.transport.bytes_in, clock.now()
        bus.read_ticks()
        n = bus.transport.bytes_out - out + bus.transport.bytes_in - inn
        assert n > 0
        assert clock.now() - t == pytest.approx(_wire_s(agile, n), abs=1e-12)


def test_the_wrist_moves_only_as_simulated_time_passes(agile: Profile) -> None:
    with lockstep(agile) as (clock, _em, bus):
        start = bus.read_position_deg()
        bus.set_torque(True)
        bus.write_goal_deg(start + 5.0)
        time.sleep(0.3)  # wall time: nothing moves
        np.testing.assert_array_equal(bus.read_position_deg(), start)
        clock.sleep(1.0)  # one simulated second: the servos reach the goal
        np.testing.assert_allclose(bus.read_position_deg(), start + 5.0, atol=0.1)


def test_the_same_requests_at_the_same_instants_give_the_same_replies(agile: Profile) -> None:
    runs = []
    for _ in range(2):
        with lockstep(agile) as (clock, _em, bus):
            start = bus.read_position_deg()
            bus.set_torque(True)
            seen = []
            for k in range(40):
                bus.write_goal_deg(start + 3.0 * np.sin(0.2 * k))
                clock.advance_to(100.0 + 0.02 * (k + 1))
                seen.append(bus.read_ticks())
            runs.append(seen)
    assert runs[0] == runs[1]


def test_a_reply_delayed_within_the_timeout_comes_at_its_simulated_instant(
        agile: Profile) -> None:
    with lockstep(agile, ("delay:0.002",)) as (clock, _em, bus):
        t = clock.now()
        bus.read_ticks()
        assert clock.now() - t >= 0.002
        assert clock.now() - t < 0.002 + 0.001


def test_a_reply_later_than_the_timeout_fails_at_the_timeout_and_is_stale(
        agile: Profile) -> None:
    timeout = agile.bus.timeout_s
    with lockstep(agile, ("delay:0.01",)) as (clock, _em, bus):
        t, wall = clock.now(), time.perf_counter()
        with pytest.raises(CommError, match="simulated"):
            bus.link.read_many(*_present_position(bus), bus.ids)
        assert clock.now() - t == pytest.approx(timeout, abs=1e-9)
        assert time.perf_counter() - wall < 1.0  # nobody waited on the wall clock


def test_an_unplugged_bus_times_out_at_once_on_the_wall_clock(agile: Profile) -> None:
    with lockstep(agile, ("unplug",)) as (clock, _em, bus):
        t, wall = clock.now(), time.perf_counter()
        with pytest.raises(CommError):
            bus.link.read_many(*_present_position(bus), bus.ids)
        assert clock.now() - t == pytest.approx(agile.bus.timeout_s, abs=1e-9)
        assert time.perf_counter() - wall < 1.0


def _present_position(bus: DynamixelBus) -> tuple[int, int]:
    reg = bus.table["present_position"]
    return reg.address, reg.size


def test_a_torque_query_outlasts_replies_later_than_the_links_timeout(agile: Profile) -> None:
    """Replies 10 ms late (the link waits 4 ms): commissioning's torque query is a set-up
    transaction, tried again with more patience, not a lost bus."""
    from spm_console.motion.servo_query import BusQuery, answer

    with lockstep(agile, ("delay:0.01@0",)) as (_clock, _em, bus):
        with pytest.raises(CommError):
            bus.set_torque(False)  # one try: the reply comes after the link's timeout
        report = answer(bus, BusQuery("torque", on=True))
        assert report.torque_on is True
        assert bus.set_up(bus.torque) == [True, True, True]


@pytest.mark.parametrize(("protocol", "model"), [("2.0", 321), ("1.0", 320)])
def test_a_scan_lists_servos_whose_replies_come_after_its_ping_timeout(
        agile: Profile, protocol: str, model: int) -> None:
    """Every reply 6 ms late (a scan waits 4 ms per id): each servo's reply is seen on the
    line after its ping failed, so it is pinged again with more patience and listed."""
    from spm_console.motion.servo_query import BusQuery, answer

    profile = agile.model_copy(update={"bus": agile.bus.model_copy(
        update={"protocol": protocol, "model_number": model})})
    with lockstep(profile, ("delay:0.006@0",)) as (_clock, _em, bus):
        report = answer(bus, BusQuery("scan", ids=(0, 1, 2, 3, 4)))
        assert [(f.id, f.model_number) for f in report.found] == [(i, model) for i in bus.ids]
