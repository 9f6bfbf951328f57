"""Small, slow, effort-limited moves of a wrist not yet commissioned (run by the motion
process that owns the bus, like every motion).

While the servos' legs, directions and horn offsets are unknown nothing may be planned: the
profile's tick map may be off by tens of degrees. What is allowed is this: each servo, by id,
moved to at most :data:`BALL_DEG` from where it rested when the first nudge began (its *rest*,
read here, never taken from the client), at most :data:`MAX_SPEED_DEGPS`, with its PWM Limit
lowered to :data:`PWM_LIMIT` (an EEPROM register: written with torque off; Position Control
mode's effort bound). Once the effort is lowered the servos are watched holding their rest:
a wrist its load pulls more than :data:`TRACK_TOL_DEG` from it is not nudged. Every cycle the
commanded and present positions are compared; a servo that does not follow (stalled, blocked,
reversed against another leg, or a load too heavy for the lowered effort) stops the nudge.
After such a stop the servos get their full effort back and go back to their rests, slowly,
and hold there (an E-stop holds where they are instead). Ticks and degrees of the servo's own
counting (not joint angles: those need the map this stage is finding).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

from spm_console.devices.base import CommError
from spm_console.devices.dynamixel.bus import DynamixelBus
from spm_console.errors import BadInputError, BusError

#: Farthest any servo is moved from its rest, deg (the issue's ball before map and zero).
BALL_DEG = 2.0
#: Fastest a nudge moves a servo, deg/s.
MAX_SPEED_DEGPS = 5.0
#: PWM Limit during commissioning, of 885 (a third of the drive's full effort).
PWM_LIMIT = 300
#: Largest lag of a servo behind its commanded ramp before the nudge is stopped, deg.
TRACK_TOL_DEG = 1.0
#: Wait at the end of a nudge for the servos to settle, s.
SETTLE_S = 0.3
#: How long the servos are watched holding their rest once their effort is lowered, s.
HOLD_WATCH_S = 0.3
#: Cycle of a nudge's ramp, s.
CYCLE_S = 0.02
#: Most time one cycle advances the ramp by, s: a cycle that took longer (a slow read) moves
#: the goal no farther than two cycles' worth, so no step of the goal exceeds the speed bound
#: times this (the ramp then takes longer).
MAX_ADVANCE_S = 2 * CYCLE_S
#: Quick reads of the servos' positions before a patient one (a lost reply is read again at
#: once, as the servo loop tolerates isolated losses).
READ_TRIES = 3


@dataclass
class NudgeState:
    """What the motion process remembers between nudges: each servo's rest and saved PWM
    Limit (restored when the nudging ends)."""

    rest_ticks: dict[int, int] = field(default_factory=dict)
    saved_pwm: dict[int, int] = field(default_factory=dict)
    goal_ticks: dict[int, int] = field(default_factory=dict)


@dataclass(frozen=True)
class NudgeResult:
    """One nudge's outcome (ticks by servo id, in the servos' own counting)."""

    ids: tuple[int, ...]
    rest_ticks: tuple[int, ...]
    """Where each servo rested when the first nudge began."""
    goal_ticks: tuple[int, ...]
    reached_ticks: tuple[int, ...]
    """Present Position after the settling wait."""
    max_lag_deg: float
    """Largest lag of a servo behind the commanded ramp."""
    stopped: str = ""
    """Why the nudge stopped early (empty: it completed)."""
    duration_s: float = 0.0
    max_away_deg: float = 0.0
    """Farthest any servo was seen from its rest, deg (the commanded offset included)."""
    returned: bool = False
    """After a stop: the servos went back to their rests, at full effort, and hold there."""

    @property
    def ok(self) -> bool:
        return not self.stopped


def check_moves(moves: Sequence[tuple[int, float]], ids: Sequence[int], speed_degps: float) -> None:
    """Refuse what no nudge may do (BadInputError): an unknown id, an offset beyond the ball
    or not finite, a speed above the bound."""
    if not moves:
        raise BadInputError("nudge: no servo to move")
    if not (math.isfinite(speed_degps) and 0.0 < speed_degps <= MAX_SPEED_DEGPS):
        raise BadInputError(f"nudge: speed {speed_degps:g}°/s must be in (0, {MAX_SPEED_DEGPS:g}]")
    seen: set[int] = set()
    for ident, offset in moves:
        if ident not in ids:
            raise BadInputError(f"nudge: servo id {ident} is not on this bus's joints {list(ids)}")
        if ident in seen:
            raise BadInputError(f"nudge: servo id {ident} given twice")
        seen.add(ident)
        if not (math.isfinite(offset) and abs(offset) <= BALL_DEG):
            raise BadInputError(f"nudge: servo {ident}: {offset:g}° from its rest is beyond the "
                                f"{BALL_DEG:g}° allowed before the wrist is commissioned")


def _ticks(bus: DynamixelBus) -> list[int]:
    """Present Position of the joints' servos: a lost reply read again at once
    (:data:`READ_TRIES` quick tries); when they all fail (a burst of late replies), as a
    set-up read (:meth:`DynamixelBus.set_up`: up to three more tries, the line quiet before
    each, with more patience: about 0.35 s on a dead line) before the nudge gives up on the
    bus. The goal does not advance meanwhile."""
    for _ in range(READ_TRIES):
        try:
            return bus.read_ticks()
        except CommError:
            bus.drain_input(0.002)
    return bus.set_up(bus.read_ticks)


def _begin(bus: DynamixelBus, state: NudgeState) -> None:
    """First nudge: torque off, PWM Limit saved and lowered, the rest read, hold, torque on."""
    ids = list(bus.ids)
    bus.set_up(lambda: bus.set_torque(False, ids))
    for ident in ids:
        if ident not in state.saved_pwm:  # a begin or release cut short saved it already
            state.saved_pwm[ident] = int(bus.set_up(partial(bus.read, ident, "pwm_limit")))
        bus.set_up(partial(bus.write, ident, "pwm_limit", min(PWM_LIMIT, state.saved_pwm[ident])))
    ticks = _ticks(bus)
    state.rest_ticks = dict(zip(ids, ticks, strict=True))
    state.goal_ticks = dict(state.rest_ticks)
    bus.sync_write("goal_position", state.goal_ticks)
    bus.set_up(lambda: bus.set_torque(True, ids))


def _away_from(rest: dict[int, int], present: dict[int, int], tpd: float) -> float:
    """Farthest servo of ``present`` from its ``rest``, deg."""
    return max(abs(present[i] - rest[i]) / tpd for i in present)


def _watch_hold(bus: DynamixelBus, state: NudgeState, tpd: float, stop_asked: Callable[[], str],
                clock: Callable[[], float], sleep: Callable[[float], None]) -> tuple[str, float]:
    """The servos holding their rest at the lowered effort for :data:`HOLD_WATCH_S`: why not
    (empty: they held) and how far they went from it, deg."""
    ids = list(bus.ids)
    away = 0.0
    t_end = clock() + HOLD_WATCH_S
    while True:
        reason = stop_asked()
        if reason:
            return f"stopped: {reason}", away
        away = max(away, _away_from(state.rest_ticks,
                                   dict(zip(ids, _ticks(bus), strict=True)), tpd))
        if away > TRACK_TOL_DEG:
            return (f"the wrist left its rest by {away:.2f}° (more than {TRACK_TOL_DEG:g}°) with "
                    f"the servos' effort lowered to a PWM Limit of {PWM_LIMIT}: its load is too "
                    "heavy for the limited nudges here (bring it nearer home, or support the "
                    "platform)"), away
        if clock() >= t_end:
            return "", away
        sleep(CYCLE_S)


def _restore_limits(bus: DynamixelBus, state: NudgeState) -> None:
    """The saved PWM Limits written back (an EEPROM register: the caller switched torque
    off); each is forgotten once written, so a cut-short restore keeps the rest."""
    for ident, pwm in list(state.saved_pwm.items()):
        bus.set_up(partial(bus.write, ident, "pwm_limit", pwm))
        del state.saved_pwm[ident]


@dataclass
class _Ramp:
    """Goals (ticks by servo id) on a straight ramp from ``start`` to ``target`` taking
    ``seconds``; each cycle advances it by the time the cycle took, at most
    :data:`MAX_ADVANCE_S` (a slow cycle makes the ramp longer, never a goal jump)."""

    start: dict[int, int]
    target: dict[int, int]
    seconds: float
    t_last: float
    s: float = 0.0

    @classmethod
    def of(cls, start: dict[int, int], target: dict[int, int], tpd: float, speed_degps: float,
           now: float) -> _Ramp:
        """At ``speed_degps`` for the servo that moves farthest (``tpd``: ticks per degree)."""
        seconds = max(abs(target[i] - start[i]) / tpd for i in start) / speed_degps
        return cls(start, target, seconds, now)

    @property
    def done(self) -> bool:
        return self.s >= 1.0

    def goal(self, now: float) -> dict[int, int]:
        """The goal of the cycle at ``now``."""
        step = min(now - self.t_last, MAX_ADVANCE_S) / self.seconds if self.seconds > 0 else 1.0
        self.s, self.t_last = min(1.0, self.s + step), now
        return {i: round(self.start[i] + self.s * (self.target[i] - self.start[i]))
                for i in self.start}


def _full_effort(bus: DynamixelBus, state: NudgeState, held: dict[int, int]) -> None:
    """PWM Limits restored (an EEPROM register: torque off for the writes), then torque on
    holding ``held``; nothing is switched when no limit is left to restore."""
    ids = list(bus.ids)
    if state.saved_pwm:
        bus.set_up(lambda: bus.set_torque(False, ids))
        _restore_limits(bus, state)
    bus.sync_write("goal_position", held)
    state.goal_ticks = dict(held)
    bus.set_up(lambda: bus.set_torque(True, ids))


def _back_to_rest(bus: DynamixelBus, state: NudgeState, tpd: float,
                  stop_asked: Callable[[], str], clock: Callable[[], float],
                  sleep: Callable[[float], None]) -> tuple[bool, float, str]:
    """After a stop that was not an E-stop: the full effort back, holding where the servos
    are, then every servo back to its rest on a ramp at :data:`MAX_SPEED_DEGPS` (each goal
    between where it was held and its rest), holding there. An E-stop meanwhile holds where
    they are. Returns whether they got back (within :data:`TRACK_TOL_DEG`), the farthest any
    was from its rest (deg) and what to add to the stop's reason. The nudging then ends: the
    next nudge begins again, whatever happens here."""
    ids = list(bus.ids)
    rest = dict(state.rest_ticks)
    state.rest_ticks.clear()
    present = dict(zip(ids, _ticks(bus), strict=True))
    away = _away_from(rest, present, tpd)
    _full_effort(bus, state, present)
    ramp = _Ramp.of(present, rest, tpd, MAX_SPEED_DEGPS, clock())
    while not ramp.done:
        reason = stop_asked()
        if reason:  # an E-stop: hold where the servos are
            held = dict(zip(ids, _ticks(bus), strict=True))
            bus.sync_write("goal_position", held)
            state.goal_ticks = held
            return False, max(away, _away_from(rest, held, tpd)), (
                f"; then, going back, stopped: {reason}")
        sleep(CYCLE_S)
        goal = ramp.goal(clock())
        bus.sync_write("goal_position", goal)
        state.goal_ticks = goal
    sleep(SETTLE_S)
    off = _away_from(rest, dict(zip(ids, _ticks(bus), strict=True)), tpd)
    if off > TRACK_TOL_DEG:
        return False, max(away, off), (f"; going back at full effort, a servo stayed {off:.2f}° "
                                       "from its rest")
    return True, away, ""


def release(bus: DynamixelBus, state: NudgeState, hold: bool = False) -> None:
    """End the nudging: PWM Limits restored (an EEPROM register: torque off to write it);
    then, with ``hold``, torque on again holding where each servo was before torque went off
    (read first, while the servos still held; the last goal sent where that read fails), at
    its full effort (torque is not switched at all when no limit is left to restore), else
    left off (the wrist rests as it was found). Torque is off for the few milliseconds of the
    writes. BusError when the servos do not answer (the PWM Limits not restored are kept, to
    restore at the next release)."""
    ids = list(bus.ids)
    last_goal = [state.goal_ticks.get(i) for i in ids]
    state.rest_ticks.clear()  # the next nudge begins again, whatever happens here
    try:
        if hold:
            try:
                held = _ticks(bus)
            except CommError:
                if all(g is not None for g in last_goal):
                    held = [int(g) for g in last_goal if g is not None]
                else:
                    raise
            _full_effort(bus, state, dict(zip(ids, held, strict=True)))
        else:
            bus.set_up(lambda: bus.set_torque(False, ids))
            _restore_limits(bus, state)
        state.goal_ticks.clear()
    except CommError as exc:
        raise BusError(f"ending the nudges on {bus.port}: {exc}; the servos may be left with "
                       "torque off and their PWM Limits lowered: check the cable and power, "
                       "then run commission again") from None


def run_nudge(bus: DynamixelBus, state: NudgeState, moves: Sequence[tuple[int, float]],
              speed_degps: float, stop_asked: Callable[[], str],
              clock: Callable[[], float] = time.monotonic,
              sleep: Callable[[float], None] = time.sleep) -> NudgeResult:
    """Move each listed servo to ``offset`` deg from its rest (0: back to it), the others
    holding, on a ramp at ``speed_degps`` (slower when the bus is: :data:`MAX_ADVANCE_S`);
    ``stop_asked()`` returns a reason to stop (an E-stop).
    ``clock`` and ``sleep``: the wall clock's, or a simulated clock's in lockstep."""
    ids = list(bus.ids)
    check_moves(moves, ids, speed_degps)
    tpd = bus.maps[0].ticks_per_turn / 360.0
    t0 = clock()
    lag = away = 0.0
    stopped = ""
    returned = False
    try:
        if not state.rest_ticks:  # the first nudge, or the first since a release
            _begin(bus, state)
            stopped, away = _watch_hold(bus, state, tpd, stop_asked, clock, sleep)
        rest = dict(state.rest_ticks)
        if not stopped:
            stopped, lag, away = _ramp(bus, state, moves, speed_degps, tpd, stop_asked, clock,
                                       sleep)
        if stopped.startswith("stopped: "):  # an E-stop: hold where the servos are
            present = dict(zip(ids, _ticks(bus), strict=True))
            bus.sync_write("goal_position", present)
            state.goal_ticks = present
        elif stopped:
            returned, back_away, note = _back_to_rest(bus, state, tpd, stop_asked, clock, sleep)
            away, stopped = max(away, back_away), stopped + note
        else:
            sleep(SETTLE_S)
        reached = _ticks(bus)
    except CommError as exc:
        raise BusError(f"nudge on {bus.port}: {exc}") from None
    away = max(away, max(abs(reached[j] - rest[i]) / tpd for j, i in enumerate(ids)))
    return NudgeResult(tuple(ids), tuple(rest[i] for i in ids),
                       tuple(state.goal_ticks[i] for i in ids), tuple(reached), lag, stopped,
                       clock() - t0, away, returned)


def _ramp(bus: DynamixelBus, state: NudgeState, moves: Sequence[tuple[int, float]],
          speed_degps: float, tpd: float, stop_asked: Callable[[], str],
          clock: Callable[[], float], sleep: Callable[[float], None]) -> tuple[str, float, float]:
    """The nudge's ramp from the goals held to the moves' targets: why it stopped (empty: it
    reached them), the largest lag behind it and the farthest any servo went from its rest,
    deg."""
    ids = list(bus.ids)
    start = dict(state.goal_ticks)
    target = dict(start)
    for ident, offset in moves:
        target[ident] = round(state.rest_ticks[ident] + offset * tpd)
    ramp = _Ramp.of(start, target, tpd, speed_degps, clock())
    lag = away = 0.0
    while True:
        reason = stop_asked()
        if reason:
            return f"stopped: {reason}", lag, away
        goal = ramp.goal(clock())
        bus.sync_write("goal_position", goal)
        state.goal_ticks = goal
        present = dict(zip(ids, _ticks(bus), strict=True))
        lag = max(lag, max(abs(goal[i] - present[i]) / tpd for i in ids))
        away = max(away, _away_from(state.rest_ticks, present, tpd))
        if lag > TRACK_TOL_DEG:
            return (f"a servo lags {lag:.2f}° behind the nudge (more than {TRACK_TOL_DEG:g}°): "
                    "stalled, blocked, pushed by another leg or too heavily loaded for the "
                    f"lowered effort (PWM Limit {PWM_LIMIT})"), lag, away
        if away > BALL_DEG + 1.5 / tpd:  # ahead of its goal (half a tick of the target's
            # rounding and a tick of the servo's allowed): the load pulls it the nudge's way
            return (f"a servo went {away:.2f}° from its rest, beyond the {BALL_DEG:g}° "
                    "allowed: its load pulls it harder than the lowered effort (PWM Limit "
                    f"{PWM_LIMIT}) holds"), lag, away
        if ramp.done:
            return "", lag, away
        sleep(CYCLE_S)
