"""A wrist its load pulls away at the nudges' lowered effort: the nudging does not go on; the
servos get their full effort back and return, slowly, to where they rested, and the result
says how far they went (it used to hold wherever the sag had taken them and say that
nothing else moved)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

from spm_console.motion.nudge import (
    BALL_DEG,
    MAX_ADVANCE_S,
    MAX_SPEED_DEGPS,
    PWM_LIMIT,
    TRACK_TOL_DEG,
    NudgeState,
    release,
    run_nudge,
)
from tests.unit.motion.test_nudge_retry import ClockedBus

TPD = 4096 / 360.0
REST = 2048


@dataclass
class LoadedBus(ClockedBus):
    """Servos in a simulated clock that reach their goal at once when their effort suffices;
    a servo whose PWM Limit is below ``need`` (by id) while it holds more than ``loaded_from``
    ticks from its rest sags by ``sag`` ticks per 20 ms instead (torque off: it stays put)."""

    need: dict[int, int] = field(default_factory=dict)
    loaded_from: int = 0
    sag: int = 6
    t_moved: float = 0.0
    pos: dict[int, int] = field(default_factory=lambda: dict.fromkeys((1, 2, 3), REST))
    held: list[bool] = field(default_factory=list)
    """Per goal written: it was where every servo stood (a hold, not a move)."""
    full: list[bool] = field(default_factory=list)
    """Per goal written: at full effort (the way back), not the nudges' lowered one."""
    jammed: set[int] = field(default_factory=set)
    """Servos that no longer move once their full effort is back (blocked on the way back)."""

    def _advance(self) -> None:
        steps = int((self.t - self.t_moved) / 0.02)
        if steps <= 0:
            return
        self.t_moved += steps * 0.02
        if not self.torque_on:
            return
        for i in self.ids:
            if i in self.jammed and self.pwm[i] == 885:
                continue
            weak = self.pwm[i] < self.need.get(i, 0)
            if weak and abs(self.goal[i] - REST) >= self.loaded_from:
                self.pos[i] -= steps * self.sag
            else:
                self.pos[i] = self.goal[i]

    def read_ticks(self) -> list[int]:
        self._advance()
        return [self.pos[i] for i in self.ids]

    def sync_write(self, name: str, values: dict[int, int]) -> None:
        self._advance()
        self.held.append(values == self.pos)
        self.full.append(all(v == 885 for v in self.pwm.values()))
        super().sync_write(name, values)


def _never() -> str:
    return ""


def _ramp_ok(bus: LoadedBus) -> None:
    """At the nudges' effort: no goal beyond the ball from the rest (a tick of rounding). On
    the way back, at full effort: each goal between where the servos were held and their rest
    (every joint's distance from its rest never grows). And no goal step faster than the
    nudges' (a goal where the servos stand holds them there: no move)."""
    back: dict[int, int] | None = None
    for g, held, full in zip(bus.goals, bus.held, bus.full, strict=True):
        if not full:
            assert held or all(abs(v - REST) / TPD <= BALL_DEG + 0.5 / TPD for v in g.values()), g
        elif back is not None:
            assert all(abs(g[i] - REST) <= abs(back[i] - REST) for i in g), (back, g)
        if full:
            back = g
    for (a, b), held in zip(itertools.pairwise(bus.goals), bus.held[1:], strict=True):
        step = max(abs(b[i] - a[i]) for i in a) / TPD
        assert held or step <= MAX_SPEED_DEGPS * MAX_ADVANCE_S + 1.0 / TPD, (a, b)


def test_a_wrist_that_sags_at_the_lowered_effort_is_not_nudged_and_goes_back_to_rest() -> None:
    bus = LoadedBus(lose=0, need={1: 2 * PWM_LIMIT})  # servo 1 holds its load at full effort
    state = NudgeState()
    r = run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert not r.ok and "left its rest" in r.stopped and f"PWM Limit of {PWM_LIMIT}" in r.stopped
    assert r.returned and bus.torque_on and bus.pwm == dict.fromkeys((1, 2, 3), 885)
    assert bus.pos == dict.fromkeys((1, 2, 3), REST) and r.reached_ticks == (REST,) * 3
    assert TRACK_TOL_DEG < r.max_away_deg <= TRACK_TOL_DEG + bus.sag / TPD
    assert all(g[2] == REST for g in bus.goals)  # servo 2 was never nudged
    _ramp_ok(bus)
    assert state.saved_pwm == {} and state.rest_ticks == {}
    release(bus, state, hold=True)  # type: ignore[arg-type]  # what the stage does next
    assert bus.torque_on and bus.pwm == dict.fromkeys((1, 2, 3), 885)
    assert bus.pos == dict.fromkeys((1, 2, 3), REST)


def test_a_servo_that_falls_behind_under_load_mid_nudge_goes_back_to_its_rest() -> None:
    """Servo 2 holds its rest at the lowered effort but not 1.2° from it: the nudge's lag
    stop takes it back, at full effort, to where it rested."""
    bus = LoadedBus(lose=0, need={2: 2 * PWM_LIMIT}, loaded_from=round(1.2 * TPD), sag=8)
    state = NudgeState()
    r = run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert not r.ok and "lags" in r.stopped and "too heavily loaded" in r.stopped
    assert r.returned and r.reached_ticks == (REST,) * 3 and bus.pwm[2] == 885
    assert r.max_away_deg <= BALL_DEG
    _ramp_ok(bus)


def test_an_e_stop_while_the_servos_are_watched_holds_where_they_are() -> None:
    bus = LoadedBus(lose=0, need={1: 2 * PWM_LIMIT})
    state = NudgeState()
    asked = iter(["", "", "E-stop: operator"])
    r = run_nudge(bus, state, ((2, 1.8),), 4.0,  # type: ignore[arg-type]
                  lambda: next(asked, "E-stop: operator"), clock=bus.clock, sleep=bus.sleep)
    assert r.stopped.startswith("stopped: E-stop") and not r.returned
    assert bus.goal[1] == bus.pos[1] < REST  # held where the sag had taken it, no move back
    release(bus, state, hold=True)  # type: ignore[arg-type]  # the full effort, holding there
    assert bus.pwm == dict.fromkeys((1, 2, 3), 885) and bus.torque_on


def test_a_wrist_that_holds_is_nudged_as_before() -> None:
    bus = LoadedBus(lose=0)
    state = NudgeState()
    r = run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert r.ok and not r.returned and r.reached_ticks[1] == REST + round(1.8 * TPD)
    assert abs(r.max_away_deg - round(1.8 * TPD) / TPD) < 1e-12
    assert bus.pwm == dict.fromkeys((1, 2, 3), PWM_LIMIT)
    _ramp_ok(bus)


@dataclass
class AheadBus(LoadedBus):
    """Servo 2, once nudged more than ``loaded_from`` ticks, runs ``ahead`` ticks past its goal
    (the load pulls it the nudge's way at the lowered effort)."""

    ahead: int = 0

    def _advance(self) -> None:
        super()._advance()
        if self.torque_on and self.pwm[2] < 885 and self.goal[2] - REST >= self.loaded_from:
            self.pos[2] = self.goal[2] + self.ahead


def test_a_servo_its_load_pulls_past_the_ball_the_nudges_way_is_stopped_and_brought_back() -> None:
    """A servo ahead of its goal by less than the lag tolerance, but past the ball: stopped
    there (the lag alone would have let it go 2.9° from its rest), and brought back."""
    bus = AheadBus(lose=0, loaded_from=round(1.0 * TPD), ahead=round(0.95 * TPD))
    state = NudgeState()
    r = run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert not r.ok and "beyond the 2° allowed" in r.stopped, r.stopped
    assert BALL_DEG < r.max_away_deg <= BALL_DEG + MAX_SPEED_DEGPS * MAX_ADVANCE_S + 2.0 / TPD
    assert r.returned and r.reached_ticks == (REST,) * 3
    _ramp_ok(bus)


def test_the_way_back_past_the_ball_only_comes_nearer_the_rest() -> None:
    """Held past the ball (a servo its load pulled ahead), the goals back start there and only
    come nearer the rest."""
    bus = AheadBus(lose=0, loaded_from=round(1.5 * TPD), ahead=round(0.99 * TPD))
    state = NudgeState()
    r = run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert not r.ok and r.returned and r.max_away_deg > BALL_DEG
    _ramp_ok(bus)


def test_a_servo_blocked_on_the_way_back_is_not_said_to_be_back() -> None:
    bus = LoadedBus(lose=0, need={1: 2 * PWM_LIMIT}, jammed={1})
    state = NudgeState()
    r = run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert not r.ok and not r.returned and "a servo stayed" in r.stopped
    assert r.reached_ticks[0] < REST and bus.pwm == dict.fromkeys((1, 2, 3), 885)


def test_an_e_stop_on_the_way_back_holds_where_the_servos_are_and_says_so() -> None:
    bus = LoadedBus(lose=0, need={1: 2 * PWM_LIMIT})
    state = NudgeState()
    calls = {"n": 0}

    def asked() -> str:
        calls["n"] += 1
        return "E-stop: operator" if bus.pwm[1] == 885 and bus.goals[-1] != bus.pos else ""

    r = run_nudge(bus, state, ((2, 1.8),), 4.0, asked,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert not r.ok and not r.returned and "then, going back, stopped: E-stop" in r.stopped
    assert bus.goal == bus.pos and bus.pos[1] < REST  # held where it was, not at the rest


def test_a_bus_lost_on_the_way_back_begins_the_next_nudge_again() -> None:
    """The torque-on of the way back unanswered: a BusError; the state then asks the next
    nudge to begin again (lower the effort, read the rest), never to move at full effort."""
    import pytest

    from spm_console.errors import BusError

    bus = LoadedBus(lose=0, need={1: 2 * PWM_LIMIT})
    state = NudgeState()
    real = bus.set_torque

    def dying(on: bool, ids: list[int]) -> None:
        if on and bus.pwm[1] == 885:
            bus.lose = 1
        real(on, ids)

    bus.set_torque = dying  # type: ignore[method-assign]
    with pytest.raises(BusError):
        run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert state.rest_ticks == {} and state.saved_pwm == {}
    bus.set_torque, bus.lose, bus.need = real, 0, {}  # type: ignore[method-assign]
    r = run_nudge(bus, state, ((2, 1.8),), 4.0, _never,  # type: ignore[arg-type]
                  clock=bus.clock, sleep=bus.sleep)
    assert r.ok and bus.pwm == dict.fromkeys((1, 2, 3), PWM_LIMIT)  # began again, effort lowered
