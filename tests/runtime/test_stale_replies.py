"""Late replies over the real protocol (our DynamixelBus on the emulator's pty, the profile's
4 ms reply timeout): whatever the reply delay, a reply read in a cycle is the answer to that
cycle's request or the read fails — never the previous cycle's reply taken as current.

Delays shorter than the timeout are slow-but-current replies. Longer ones make every read
fail, each late reply that lands in a later transaction is counted as stale, and the
executor stops with "communication lost" after the profile's 3 failed cycles.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.devices.base import CommError
from spm_console.devices.dynamixel.bus import DynamixelBus, open_bus
from spm_console.devices.dynamixel.reply_ledger import read_variants
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.devices.emulator.faults import FaultSpec
from spm_console.errors import ExitCode
from spm_console.motion.executor import Segment
from spm_console.motion.plans import synthetic_plan
from tests.support.exec_helpers import PAPER_START, run_on_emulator

pytestmark = pytest.mark.realtime  # about the wall clock (see tests/conftest.py)

TS = 0.02
NEAR = PAPER_START + np.array([-6.0, 8.0, 5.0])  # a short plan's goal
ONSET_K = 5
DELAYS = [0.001, 0.005, 0.010, 0.0195, 0.025, 0.040, 0.100]


def protocol1(profile: Profile) -> Profile:
    bus = profile.bus.model_copy(update={"protocol": "1.0", "model_number": 320})
    return profile.model_copy(update={"bus": bus})


@contextmanager
def rig(profile: Profile, delay_s: float, at_s: float) -> Iterator[tuple[EmulatorHandle,
                                                                          DynamixelBus]]:
    em = start_emulator(profile, [FaultSpec("delay", at_s, delay_s=delay_s)])
    bus = open_bus(profile, em.port)
    try:
        yield em, bus
    finally:
        bus.close()
        em.stop()


def _cycle_value(k: int) -> np.ndarray:
    """A different position in every cycle, so a reply tells which cycle it was read in."""
    return np.array([100.0, 110.0, 120.0]) + 0.5 * (k % 30)


def _cycles(em: EmulatorHandle, bus: DynamixelBus, n: int) -> list[bool]:
    """The executor's bus traffic every 20 ms (goal write, read, one retry) with the servos
    placed at a new position each cycle. Asserts that every accepted read is this cycle's."""
    ok = []
    t0 = time.perf_counter()
    em.start_clock()
    for k in range(n):
        time.sleep(max(0.0, t0 + k * TS - time.perf_counter()))
        value = _cycle_value(k)
        em.set_joint_deg(value)
        bus.write_goal_deg(value)
        good = False
        for _ in range(2):
            try:
                got = bus.read_position_deg()
            except CommError:
                continue
            assert np.allclose(got, value, atol=0.1), f"cycle {k}: read {got}, placed {value}"
            good = True
            break
        ok.append(good)
    return ok


@pytest.mark.parametrize("delay", DELAYS)
def test_no_stale_reply_is_taken_as_current(agile: Profile, delay: float) -> None:
    at = (ONSET_K - 0.25) * TS  # cycle ONSET_K is the first one delayed
    for _attempt in range(3):
        with rig(agile, delay, at) as (em, bus):
            n = ONSET_K + 4 + math.ceil(delay / TS)  # long enough for the late replies to land
            ok = _cycles(em, bus, n)  # asserts that every read accepted is its cycle's
            assert sum(ok[:ONSET_K]) >= ONSET_K - 1  # (one read may be lost to machine load)
            if delay < agile.bus.timeout_s:
                # slow but current: fine (a stale reply only after a read lost to machine load)
                assert sum(ok) >= n - 1 and (bus.stale_replies == 0 or not all(ok))
                return
            assert em.stats.delayed > 0
            if delay >= 2 * agile.bus.timeout_s:
                # every read from the onset on fails: 3 failed cycles in a row right away
                assert not any(ok[ONSET_K : ONSET_K + 3]), ok
                return
            # 1 ms past the timeout: a read that a loaded machine looks at late may still get
            # its own reply (slow but current: checked above, never stale); then 3 failed
            # cycles in a row. Only that scheduling luck is retried, never a stale read.
            late = "".join("x" if good else "-" for good in ok[ONSET_K:])
            if "---" in late[:6]:
                return
    raise AssertionError(f"no 3 failed cycles in a row within 6 cycles of the onset: {late}")


def _late_then_next(bus: DynamixelBus, delay: float) -> str:
    """A read whose replies come ``delay`` late, then the next read sent a few ms before
    they land and waiting less than ``delay`` (its own replies cannot come in time): it
    must fail. Returns its error. The alignment is retried if a loaded machine missed it."""
    for _ in range(3):
        t0 = time.perf_counter()
        bus.transport.timeout_s = 0.001
        with pytest.raises(CommError, match=r"no status packet|stale"):
            bus.read_position_deg()
        time.sleep(max(0.0, t0 + delay - 0.01 - time.perf_counter()))
        gap = t0 + delay - time.perf_counter()  # until the late replies land
        if gap > 0.0005:
            bus.transport.timeout_s = (gap + delay) / 2
            with pytest.raises(CommError) as exc:
                bus.read_position_deg()
            if "stale" in str(exc.value):
                return str(exc.value)
        time.sleep(2 * delay)  # let every late reply land, then try again
    raise AssertionError("the late replies never landed in the next read")


@pytest.mark.parametrize("delay", [*DELAYS[1:], 1.0])
def test_a_late_reply_landing_in_the_next_request_is_stale(agile: Profile, delay: float) -> None:
    """The worst alignment: the next request goes out just before the late replies land."""
    with rig(agile, delay, 0.0) as (_em, bus):
        assert re.match(r"stale reply from id 1: the late answer to a sync read at 132 "
                        r"\(\d+ bytes\) sent \d+\.\d ms ago", _late_then_next(bus, delay))
        bus.drain_input(0.05)  # the first stale reply failed the read: let the other two land
        assert bus.stale_replies >= 3


@pytest.mark.parametrize("delay", [0.0195, 0.1])
def test_protocol1_late_bulk_read_replies_are_stale(agile: Profile, delay: float) -> None:
    with rig(protocol1(agile), delay, 0.0) as (_em, bus):
        assert re.match(r"stale reply from id 1: the late answer to a bulk read at 36 "
                        r"\(\d+ bytes\)", _late_then_next(bus, delay))
        bus.drain_input(0.05)  # the first stale reply failed the read: let the other two land
        assert bus.stale_replies >= 3


def test_late_replies_drained_before_a_retry_are_counted_and_settled(agile: Profile) -> None:
    # replies 12 ms late (3 timeouts): late even when this thread is descheduled for a while
    with rig(agile, 0.012, 0.0) as (_em, bus):
        with pytest.raises(CommError, match="no status packet"):
            bus.read_position_deg()
        assert bus.link.ledger.requests  # type: ignore[attr-defined]
        assert bus.drain_input(0.05) > 0  # what a set-up retry does first
        assert bus.stale_replies == 3 and not bus.link.ledger.requests  # type: ignore[attr-defined]


@pytest.mark.parametrize("protocol", ["2.0", "1.0"])
def test_the_emulator_answers_every_widened_read(agile: Profile, protocol: str) -> None:
    """With the shorter reply lengths reserved (as if their replies were still due), the
    position read is widened step by step; the servos answer each with the right bytes."""
    profile = agile if protocol == "2.0" else protocol1(agile)
    overhead = 11 if protocol == "2.0" else 6  # status packet bytes around the data
    with start_emulator(profile) as em, open_bus(profile, em.port) as bus:
        em.set_joint_deg([100.0, 110.0, 120.0])
        reg = bus.table["present_position"]
        variants = read_variants(bus.table, reg.address, reg.size)
        led = bus.link.ledger  # type: ignore[attr-defined]
        for k, v in enumerate(variants):
            for w in variants[:k]:
                led.end(led.begin(bus.ids, w.length, time.perf_counter()))
            before = bus.transport.bytes_in
            got, failed = None, 0
            while got is None and failed < 3:  # (a read lost to machine load is retried)
                try:
                    got = bus.read_position_deg()
                except CommError:
                    failed += 1
            assert got is not None and np.allclose(got, [100.0, 110.0, 120.0], atol=0.1), v
            if not failed:  # exactly three replies of the widened length
                assert bus.transport.bytes_in - before == 3 * (overhead + v.length)
            assert led.requests == []  # the answer retired the reservations (FIFO)


# --- the executor -------------------------------------------------------------------------------

ONSET_S = 0.49  # the set-up before the loop must not see it (the fault clock restarts then)
FIRST_LATE_K = 25  # the first cycle whose requests are delayed (the loop starts 2 ms late)


@pytest.mark.parametrize("delay", [*DELAYS, 1.0])
def test_execute_with_late_replies_stops_within_three_cycles(
        agile: Profile, tmp_path: Path, delay: float) -> None:
    plan = synthetic_plan(agile, PAPER_START, NEAR, 0.8)
    run = run_on_emulator(agile, [Segment("plan", plan)], tmp_path,
                          faults=[FaultSpec("delay", ONSET_S, delay_s=delay)])
    res, st = run.result, run.result.stats
    if delay < agile.bus.timeout_s:
        assert res.ok, res.message
        # (a stale reply can only follow a read lost to machine load)
        assert st.stale_replies == 0 or st.read_retries > 0
        return
    assert res.exit_code == ExitCode.STOP_COMM, res.message
    assert "communication lost" in res.message
    assert res.stop is not None
    n = agile.safety.comm_failures
    good_late = [s.k for s in run.samples[FIRST_LATE_K:] if s.read_ok]
    if delay >= 2 * agile.bus.timeout_s:
        # every read from the first delayed cycle on fails: stopped at its 3rd cycle
        assert not good_late
        assert FIRST_LATE_K - 1 <= res.stop.k <= FIRST_LATE_K + n - 1
    else:
        # 1 ms past the 4 ms timeout: a reply read a little late by a loaded machine is
        # still this cycle's own (slow but current); the stop follows 3 failed cycles
        assert len(good_late) <= 3
        assert res.stop.k <= max(good_late, default=FIRST_LATE_K - 1) + n
    if delay <= 2 * TS:  # the late replies land within the run (in a read, or found
        assert st.stale_replies >= 1  # waiting by the next goal write), all counted


def test_protocol1_execute_with_late_replies_stops(agile: Profile, tmp_path: Path) -> None:
    plan = synthetic_plan(agile, PAPER_START, NEAR, 0.8)
    run = run_on_emulator(protocol1(agile), [Segment("plan", plan)], tmp_path,
                          faults=[FaultSpec("delay", ONSET_S, delay_s=0.0195)])
    assert run.result.exit_code == ExitCode.STOP_COMM, run.result.message
    assert run.result.stop is not None and run.result.stop.k <= FIRST_LATE_K + 2
