"""The shared simulated clock: time moves only when told, never back, and not before the
emulator has answered what was sent."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator

import pytest

from spm_console.system.simclock import SimClock, attached


@pytest.fixture
def clock() -> Iterator[SimClock]:
    c = SimClock.create(5.0)
    yield c
    c.close()


def test_time_moves_only_forward_and_is_shared(clock: SimClock) -> None:
    other = SimClock.attach(clock.path)  # as another process maps it
    assert clock.now() == other.now() == 5.0
    clock.sleep(0.25)
    assert other.now() == 5.25
    other.advance_to(5.0)  # never back
    assert clock.now() == 5.25
    clock.sleep(-1.0)
    assert clock.now() == 5.25
    assert attached(clock.path) is attached(clock.path)
    assert clock.due == math.inf


def test_advance_waits_for_the_emulator_to_answer(clock: SimClock) -> None:
    clock.sent(10)
    assert not clock.caught_up()

    def emulator() -> None:
        time.sleep(0.05)
        clock.answered(10)

    threading.Thread(target=emulator).start()
    clock.advance_to(6.0)  # waits until the bytes were answered
    assert clock.caught_up() and clock.now() == 6.0


def test_a_silent_emulator_does_not_hold_time_for_ever(clock: SimClock) -> None:
    clock.sent(3)
    t0 = time.perf_counter()
    assert clock.catch_up(0.05) is False
    assert time.perf_counter() - t0 < 1.0


def test_a_reply_due_by_now_keeps_the_clock_waiting(clock: SimClock) -> None:
    clock.due = 5.5
    assert clock.caught_up()
    clock.advance_to(5.6)  # the emulator must write the held-back reply first
    assert not clock.caught_up()
    clock.due = math.inf
    assert clock.caught_up()


def test_the_creator_removes_the_file(tmp_path: object) -> None:
    import os

    c = SimClock.create()
    assert os.path.exists(c.path)
    c.close()
    assert not os.path.exists(c.path)


def test_paced_waits_keep_their_schedule_on_the_wall_clock(
        monkeypatch: pytest.MonkeyPatch) -> None:
    c = SimClock.create(0.0, rate=2.0)  # two simulated seconds per wall-clock second
    try:
        t0 = time.perf_counter()
        for _ in range(10):
            c.sleep(0.02)
        assert c.now() == pytest.approx(0.2)
        assert time.perf_counter() - t0 >= 0.099  # at least 0.1 s of wall clock
        slept: list[float] = []
        monkeypatch.setattr(time, "sleep", slept.append)
        c.sleep(0.5, rate=0.0)  # not paced: no wall-clock wait at all
        assert slept == [] and c.now() == pytest.approx(0.7)
    finally:
        c.close()


def test_a_bad_pace_is_refused() -> None:
    for rate in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError):
            SimClock.create(rate=rate)


def _advance_in_thread(clock: SimClock, t: float) -> threading.Thread:
    th = threading.Thread(target=clock.advance_to, args=(t,))
    th.start()
    return th


def test_time_waits_for_an_e_stop_sent_until_it_is_taken(clock: SimClock) -> None:
    """The front end counts an E-stop before stamping it; the motion process counts it once
    its loop has it: time does not move past the stamp before then."""
    front_end = SimClock.attach(clock.path)  # as the front end's process maps it
    front_end.stop_sent()
    assert clock.stops_pending() == 1
    mover = _advance_in_thread(clock, 6.0)
    time.sleep(0.05)
    assert mover.is_alive() and clock.now() == 5.0  # held at the stamp
    clock.stop_taken()
    mover.join(1.0)
    assert not mover.is_alive() and clock.now() == 6.0 and clock.stops_pending() == 0


def test_an_e_stop_that_could_not_be_sent_holds_nothing(clock: SimClock) -> None:
    clock.stop_sent()
    clock.stop_sent(-1)
    t0 = time.perf_counter()
    clock.advance_to(6.0)
    assert clock.now() == 6.0 and time.perf_counter() - t0 < 0.5


def test_the_thread_that_takes_e_stops_never_waits_for_them(clock: SimClock) -> None:
    clock.takes_stops()
    clock.stop_sent()
    t0 = time.perf_counter()
    clock.advance_to(6.0)  # (it could not take the stop while it waited)
    assert clock.now() == 6.0 and time.perf_counter() - t0 < 0.5
    mover = _advance_in_thread(clock, 7.0)  # any other thread waits
    time.sleep(0.05)
    assert mover.is_alive()
    clock.stop_taken()
    mover.join(1.0)
    assert clock.now() == 7.0


def test_an_e_stop_never_taken_holds_time_once_only(clock: SimClock,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("spm_console.system.simclock.CATCH_UP_S", 0.05)
    clock.stop_sent()
    t0 = time.perf_counter()
    clock.advance_to(6.0)
    assert clock.now() == 6.0 and 0.05 <= time.perf_counter() - t0 < 1.0
    assert clock.stops_pending() == 0  # counted lost: the next advance does not wait
    clock.stop_taken()  # taken late after all
    assert clock.stops_pending() == 0
    clock.stop_sent()  # a new one is waited for again
    assert clock.stops_pending() == 1


def test_a_new_motion_process_does_not_wait_for_e_stops_sent_before_it(clock: SimClock) -> None:
    clock.stop_sent(2)
    clock.stop_taken()
    late = SimClock.attach(clock.path)  # a motion process started after them
    late.takes_stops()
    assert late.stops_pending() == 0
    clock.stop_sent()
    assert late.stops_pending() == 1
