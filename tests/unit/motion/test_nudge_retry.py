"""The nudges' register transactions on a bus that loses a reply now and then: each is tried
again, by the bus's own set-up retry (a write sets a register to a value: done twice, the
same), and a bus that stops answering is a BusError that keeps the PWM Limits it could not
restore."""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any, TypeVar

import pytest

from spm_console.devices.base import CommError
from spm_console.devices.dynamixel.bus import SETUP_TIMEOUTS_S, DynamixelBus
from spm_console.errors import BusError
from spm_console.motion.nudge import (
    MAX_ADVANCE_S,
    PWM_LIMIT,
    READ_TRIES,
    NudgeState,
    release,
    run_nudge,
)

T = TypeVar("T")


@dataclass
class LossyBus:
    """Three servos whose every ``lose``-th transaction's reply is lost (0: none; 1: all)."""

    lose: int
    ids: tuple[int, ...] = (1, 2, 3)
    port: str = "lossy"
    maps: list[Any] = field(default_factory=lambda: [SimpleNamespace(ticks_per_turn=4096)])
    pwm: dict[int, int] = field(default_factory=lambda: dict.fromkeys((1, 2, 3), 885))
    torque_on: bool = False
    goal: dict[int, int] = field(default_factory=lambda: dict.fromkeys((1, 2, 3), 2048))
    n: int = 0

    def _transaction(self) -> None:
        self.n += 1
        if self.lose and self.n % self.lose == 0:
            raise CommError("no status packet within 4.0 ms (0 of 1 received, 0 corrupt)")

    def set_torque(self, on: bool, ids: list[int]) -> None:
        self.torque_on = on  # the servo acts on the write whether or not its reply arrives
        self._transaction()

    def read(self, ident: int, name: str) -> int:
        assert name == "pwm_limit"
        self._transaction()
        return self.pwm[ident]

    def write(self, ident: int, name: str, value: int) -> None:
        assert name == "pwm_limit"
        self.pwm[ident] = value
        self._transaction()

    def read_ticks(self) -> list[int]:
        self._transaction()
        return [self.goal[i] for i in self.ids]

    def sync_write(self, name: str, values: dict[int, int]) -> None:
        self.goal.update(values)  # no reply to lose

    def drain_input(self, _s: float) -> None:
        pass

    transport: Any = field(default_factory=lambda: SimpleNamespace(
        patience=lambda _timeout_s: contextlib.nullcontext()))

    def set_up(self, fn: Callable[[], T]) -> T:
        """The bus's own set-up retry (:meth:`DynamixelBus.set_up`) on this bus."""
        return DynamixelBus.set_up(self, fn)  # type: ignore[arg-type]


def _never() -> str:
    return ""


def test_lost_replies_are_tried_again_and_the_nudging_ends_as_it_began() -> None:
    bus = LossyBus(lose=3)  # every third transaction's reply lost
    state = NudgeState()
    r = run_nudge(bus, state, ((2, 0.5),), 5.0, _never,  # type: ignore[arg-type]
                  clock=iter(range(10_000)).__next__, sleep=lambda _s: None)
    assert r.ok and bus.torque_on and bus.pwm == dict.fromkeys((1, 2, 3), PWM_LIMIT)
    release(bus, state, hold=True)  # type: ignore[arg-type]
    assert bus.pwm == dict.fromkeys((1, 2, 3), 885) and bus.torque_on
    assert state.saved_pwm == {}


def test_a_bus_that_stops_answering_is_a_bus_error_keeping_the_limits_to_restore() -> None:
    bus = LossyBus(lose=0)
    state = NudgeState()
    assert run_nudge(bus, state, ((2, 0.5),), 5.0, _never,  # type: ignore[arg-type]
                     clock=iter(range(10_000)).__next__, sleep=lambda _s: None).ok
    bus.lose = 1
    with pytest.raises(BusError, match="ending the nudges on lossy"):
        release(bus, state)  # type: ignore[arg-type]
    assert set(state.saved_pwm) == {1, 2, 3} and bus.n >= len(SETUP_TIMEOUTS_S)


def test_a_begin_cut_short_begins_again_and_restores_the_limits_it_first_saved() -> None:
    """The bus stops answering while the first nudge lowers the PWM Limits: that nudge is a
    BusError; once the bus answers again the next nudge begins again (torque, limits, rest)
    and the release restores each servo's own limit, never the lowered one it left."""
    bus = LossyBus(lose=0)
    state = NudgeState()
    real_write = bus.write
    calls = {"n": 0}

    def dying_write(ident: int, name: str, value: int) -> None:
        calls["n"] += 1
        if calls["n"] >= 2:  # servo 1's limit lowered, then nothing answers
            bus.lose = 1
        real_write(ident, name, value)

    bus.write = dying_write  # type: ignore[method-assign]
    with pytest.raises(BusError):
        run_nudge(bus, state, ((2, 0.5),), 5.0, _never,  # type: ignore[arg-type]
                  clock=iter(range(10_000)).__next__, sleep=lambda _s: None)
    assert bus.pwm[1] == PWM_LIMIT and state.saved_pwm[1] == 885
    bus.write, bus.lose = real_write, 0  # type: ignore[method-assign]
    r = run_nudge(bus, state, ((2, 0.5),), 5.0, _never,  # type: ignore[arg-type]
                  clock=iter(range(10_000)).__next__, sleep=lambda _s: None)
    assert r.ok and bus.torque_on and set(bus.pwm.values()) == {PWM_LIMIT}
    release(bus, state)  # type: ignore[arg-type]
    assert bus.pwm == dict.fromkeys((1, 2, 3), 885) and not bus.torque_on


@dataclass
class ClockedBus(LossyBus):
    """A bus on a simulated clock (``t``, s) that records every goal sent, in order."""

    t: float = 0.0
    goals: list[dict[int, int]] = field(default_factory=list)

    def sync_write(self, name: str, values: dict[int, int]) -> None:
        super().sync_write(name, values)
        self.goals.append(dict(values))

    def clock(self) -> float:
        return self.t

    def sleep(self, s: float) -> None:
        self.t += s


@dataclass
class SlowBus(ClockedBus):
    """Replies that come late in bursts: from every ``every``-th position read, the quick
    tries fail, and the patient set-up read that follows takes ``slow_s`` of the clock."""

    every: int = 4
    slow_s: float = 0.3
    reads: int = 0
    patient: int = 0

    burst: int = 0

    def read_ticks(self) -> list[int]:
        self.reads += 1
        if self.reads % self.every == 0:
            self.burst = READ_TRIES  # this read and the quick tries after it fail
        if self.burst and not self.patient:
            self.burst -= 1
            raise CommError("stale reply from id 1: the late answer to a sync read")
        return [self.goal[i] for i in self.ids]

    def set_up(self, fn: Callable[[], T]) -> T:
        self.patient += 1
        self.t += self.slow_s
        try:
            return fn()
        finally:
            self.patient -= 1


def test_a_burst_of_late_replies_slows_the_ramp_and_never_steps_its_goal_past_the_speed() -> None:
    """Position reads whose quick tries all fail are read once more with patience (not a
    BusError that ends the commissioning); a read that took 0.3 s does not let the goal jump
    by 0.3 s of ramp: no step of the goal exceeds the speed times MAX_ADVANCE_S."""
    bus = SlowBus(lose=0, every=READ_TRIES + 2)
    state = NudgeState()
    speed = 5.0
    r = run_nudge(bus, state, ((2, 2.0),), speed, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert r.ok and bus.patient == 0 and bus.t > 0.3 * 3  # three bursts at least
    tpd = 4096 / 360.0
    ramp = [g[2] for g in bus.goals]
    steps = [abs(b - a) / tpd for a, b in itertools.pairwise(ramp)]
    assert ramp[-1] - ramp[0] == round(2.0 * tpd)
    assert max(steps) <= speed * MAX_ADVANCE_S + 1.0 / tpd  # a tick of rounding
    assert r.duration_s > 2.0 / speed  # the slow reads made the ramp longer, not faster


@dataclass
class RecordingBus(LossyBus):
    """A bus that records what reached the servos, in order; ``dead_reads``: position reads
    fail (every try)."""

    dead_reads: bool = False
    log: list[str] = field(default_factory=list)

    def set_torque(self, on: bool, ids: list[int]) -> None:
        self.log.append(f"torque {'on' if on else 'off'}")
        super().set_torque(on, ids)

    def read_ticks(self) -> list[int]:
        self.log.append("read")
        if self.dead_reads:
            raise CommError("no status packet within 4.0 ms (0 of 3 received, 0 corrupt)")
        return super().read_ticks()

    def sync_write(self, name: str, values: dict[int, int]) -> None:
        self.log.append(f"goal {values[2]}")
        super().sync_write(name, values)


def test_a_holding_release_reads_where_the_wrist_is_before_torque_goes_off() -> None:
    """The wrist (its jig lifted) is unsupported only for the EEPROM writes: the position it
    will hold is read while the servos still hold it, not after torque went off (a patient
    read there took up to a few hundred ms, the wrist sagging); when that read fails, the
    last goal sent is held."""
    bus = RecordingBus(lose=0)
    state = NudgeState()
    assert run_nudge(bus, state, ((2, 1.0),), 5.0, _never,  # type: ignore[arg-type]
                     clock=iter(range(10_000)).__next__, sleep=lambda _s: None).ok
    goal = state.goal_ticks[2]
    bus.log.clear()
    release(bus, state, hold=True)  # type: ignore[arg-type]
    off = bus.log.index("torque off")
    assert "read" in bus.log[:off] and "read" not in bus.log[off:]
    assert bus.log[-2:] == [f"goal {goal}", "torque on"] and bus.torque_on

    bus = RecordingBus(lose=0)
    state = NudgeState()
    assert run_nudge(bus, state, ((2, 1.0),), 5.0, _never,  # type: ignore[arg-type]
                     clock=iter(range(10_000)).__next__, sleep=lambda _s: None).ok
    goal = state.goal_ticks[2]
    bus.dead_reads = True
    release(bus, state, hold=True)  # type: ignore[arg-type]
    assert bus.log[-2:] == [f"goal {goal}", "torque on"] and bus.torque_on
