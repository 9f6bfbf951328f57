"""Commissioning's nudges on the emulated bus: a servo moved by id within the ball around its
rest, slowly, its PWM Limit lowered and restored; what no nudge may do is refused before
anything moves; a blocked servo stops the nudge."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from spm_console.config.schema import Profile
from spm_console.devices.dynamixel.bus import DynamixelBus, open_bus
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import BadInputError, BusError
from spm_console.motion.nudge import BALL_DEG, PWM_LIMIT, NudgeState, release, run_nudge
from tests.runtime.test_bus_emulator import relaxed

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

START = (128.0, 141.0, 133.0)


@pytest.fixture
def rig(agile: Profile) -> Iterator[tuple[EmulatorHandle, DynamixelBus]]:
    em = start_emulator(agile, record=False, initial_deg=START)
    bus = open_bus(relaxed(agile), em.port)
    yield em, bus
    bus.close()
    em.stop()


def _never() -> str:
    return ""


def test_a_nudge_moves_one_servo_by_its_own_ticks_and_the_others_hold(
        rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    _em, bus = rig
    state = NudgeState()
    ident = bus.ids[1]
    r = run_nudge(bus, state, ((ident, 1.5),), 5.0, _never)
    assert r.ok, r.stopped
    tpd = bus.maps[0].ticks_per_turn / 360.0
    moved = [(b - a) / tpd for a, b in zip(r.rest_ticks, r.reached_ticks, strict=True)]
    assert moved[1] == pytest.approx(1.5, abs=0.1)
    assert abs(moved[0]) < 0.1 and abs(moved[2]) < 0.1
    assert r.duration_s >= 1.5 / 5.0  # no faster than the bound
    assert all(bus.read(i, "pwm_limit") == PWM_LIMIT for i in bus.ids)
    back = run_nudge(bus, state, ((ident, 0.0),), 5.0, _never)
    assert back.ok and abs(back.reached_ticks[1] - back.rest_ticks[1]) <= 2
    release(bus, state)
    assert all(bus.read(i, "pwm_limit") == 885 for i in bus.ids)
    assert bus.torque() == [False, False, False]


@pytest.mark.parametrize(("moves", "speed", "match"), [
    (((1, BALL_DEG + 0.1),), 5.0, "beyond"),
    (((1, float("nan")),), 5.0, "beyond"),
    (((99, 1.0),), 5.0, "not on this bus"),
    (((1, 1.0), (1, -1.0)), 5.0, "twice"),
    (((1, 1.0),), 5.5, "speed"),
    ((), 5.0, "no servo"),
])
def test_what_no_nudge_may_do_is_refused_before_anything_moves(
        rig: tuple[EmulatorHandle, DynamixelBus], moves: tuple[tuple[int, float], ...],
        speed: float, match: str) -> None:
    _em, bus = rig
    state = NudgeState()
    with pytest.raises(BadInputError, match=match):
        run_nudge(bus, state, moves, speed, _never)
    assert state.saved_pwm == {} and bus.torque() == [False, False, False]


def test_a_blocked_servo_stops_the_nudge_holding(agile: Profile) -> None:
    em = start_emulator(agile, [parse_fault("stall:1@0")], record=False, initial_deg=START)
    bus = open_bus(relaxed(agile), em.port)
    try:
        state = NudgeState()
        r = run_nudge(bus, state, ((bus.ids[0], 2.0),), 5.0, _never)
        assert not r.ok and "lags" in r.stopped
        release(bus, state)
    finally:
        bus.close()
        em.stop()


def test_an_estop_stops_the_nudge(rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    _em, bus = rig
    state = NudgeState()
    asked = threading.Event()
    threading.Timer(0.1, asked.set).start()
    r = run_nudge(bus, state, ((bus.ids[2], 2.0),), 2.0, lambda: "E-stop" if asked.is_set() else "")
    assert not r.ok and "E-stop" in r.stopped
    tpd = bus.maps[0].ticks_per_turn / 360.0
    assert abs(r.reached_ticks[2] - r.rest_ticks[2]) / tpd < 1.0
    release(bus, state)


def test_a_scan_lists_every_servo_on_the_bus_in_about_a_second(
        rig: tuple[EmulatorHandle, DynamixelBus]) -> None:
    from spm_console.motion.servo_query import BusQuery, answer

    _em, bus = rig
    report = answer(bus, BusQuery("scan"))
    assert [(f.id, f.model_number) for f in report.found] == [(i, 321) for i in sorted(bus.ids)]
    assert len(report.ids) == 253


@pytest.mark.parametrize("ids", [(0, 1, 2, 3), (3,)])
def test_a_scan_lists_servos_answering_later_than_an_adapters_latency_timer(
        agile: Profile, ids: tuple[int, ...]) -> None:
    """Every reply 20 ms late on the wall clock (a USB adapter's latency timer is 16 ms by
    default; the scan waits 4 ms per id): each servo is still listed, the last one too."""
    from spm_console.motion.servo_query import BusQuery, answer

    em = start_emulator(agile, [parse_fault("delay:0.02@0")], record=False, initial_deg=START)
    bus = open_bus(agile, em.port)  # the profile's own 4 ms reply timeout
    try:
        report = answer(bus, BusQuery("scan", ids=ids))
        assert [f.id for f in report.found] == [i for i in ids if i in bus.ids]
    finally:
        bus.close()
        em.stop()


def test_a_bus_lost_before_the_release_is_a_bus_error_not_an_internal_one(
        agile: Profile) -> None:
    """The servos stop answering between the last nudge and the release: the release says
    so (BusError, which the motion process reports as a refusal, not as a bug) and keeps the
    PWM Limits it could not restore."""
    t0 = time.monotonic()
    em = start_emulator(agile, [parse_fault("unplug@1.5")], record=False, initial_deg=START)
    bus = open_bus(relaxed(agile), em.port)
    try:
        state = NudgeState()
        assert run_nudge(bus, state, ((bus.ids[0], 0.5),), 5.0, _never).ok
        time.sleep(max(0.0, t0 + 1.8 - time.monotonic()))
        with pytest.raises(BusError, match="ending the nudges"):
            release(bus, state)
        assert set(state.saved_pwm) == set(bus.ids)
    finally:
        bus.close()
        em.stop()


def test_a_nudge_completes_on_a_link_that_answers_later_than_its_timeout(
        agile: Profile) -> None:
    """Every reply 20 ms late (a USB adapter's default latency timer is 16 ms), the profile's
    own 4 ms timeout: the nudge's position reads wait out the late replies and try again with
    the set-up transactions' patience, as its register writes do, instead of failing the
    commissioning on the first late burst."""
    em = start_emulator(agile, [parse_fault("delay:0.02@0")], record=False, initial_deg=START)
    bus = open_bus(agile, em.port)
    try:
        state = NudgeState()
        ident = bus.ids[0]
        r = run_nudge(bus, state, ((ident, 1.0),), 5.0, _never)
        assert r.ok, r.stopped
        tpd = bus.maps[0].ticks_per_turn / 360.0
        assert (r.reached_ticks[0] - r.rest_ticks[0]) / tpd == pytest.approx(1.0, abs=0.1)
        release(bus, state)
        assert all(bus.set_up(lambda i=i: bus.read(i, "pwm_limit")) == 885 for i in bus.ids)
    finally:
        bus.close()
        em.stop()
