"""The runtime's rules for every reference it streams, written once.

From the references alone and a given initial state, the motion of the servo model (27) is
simulated exactly (zero-order hold) at :data:`POINTS_PER_INTERVAL` instants in every interval
(the samples included) and checked, in this order, for the first violation:

1. the references are finite;
2. every reference lies inside the servo limits, to :data:`LIMIT_TOL_DEG`;
3. no reference changes by more than :data:`MAX_REFERENCE_STEP_DEG` from one sample to the
   next (and from the reference in use before the plan, when given);
4. every simulated position lies inside the servo limits, to :data:`LIMIT_TOL_DEG`;
4a. with a linear range (an identified servo's), no reference runs ahead of the model's
   position at its sample by more than it (+ :data:`SAMPLE_TOL`): beyond, the drive
   saturates and the model no longer describes the servo;
5. the model speed stays within vmax + :data:`SAMPLE_TOL` at the samples;
6. … and within vmax·(1 + :data:`BETWEEN_SPEED_ALLOWANCE`) at every instant checked
   (piecewise-constant references make the continuous speed overshoot the sampled one);
7. every simulated position is certified by the workspace (a set that certifies nothing
   is its own violation).

:class:`Rules` says which of 4–5 a caller applies (:data:`EXECUTE_RULES`: all of them;
:data:`FOLLOW_RULES`: the live follower's check of a re-planned horizon); a speed floor per
joint raises the speed bounds of 5–6 for a joint already faster than them; without a
membership the certification (7) is the caller's (straight lines checked exactly).

Pure (the membership is any object with ``empty`` and ``contains``); the wording of a
violation is the caller's. Degrees, deg/s, seconds.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.core.servo.model import Pole, simulate_continuous

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: Instants simulated per sampling interval (the samples included).
POINTS_PER_INTERVAL = 10
#: Largest change of a reference between two samples, deg (a 10° step is 500°/s of command).
MAX_REFERENCE_STEP_DEG = 10.0
#: Relative allowance on the speed bound between samples (not at the samples).
BETWEEN_SPEED_ALLOWANCE = 0.10
#: Tolerance on the servo-limit boundary, deg.
LIMIT_TOL_DEG = 1e-9
#: Round-off allowed on a constraint at the samples, deg or deg/s: a planned motion meets its
#: constraints at the samples to this, and the runtime holds the model speed at the samples
#: to vmax plus this.
SAMPLE_TOL = 1e-6
#: Longest plan accepted, samples (10 minutes at 20 ms).
MAX_SAMPLES = 30_000


class Rule(enum.Enum):
    """The rule a motion breaks (the module docstring's list)."""

    NOT_FINITE = "references not finite"
    REFERENCE_LIMIT = "reference outside the servo limits"
    STEP = "reference step too large"
    POSITION_LIMIT = "position outside the servo limits"
    SPEED_AT_SAMPLE = "speed above the bound at a sample"
    SPEED_BETWEEN = "speed above the bound between samples"
    NOTHING_CERTIFIED = "the workspace certifies nothing"
    NOT_CERTIFIED = "position not certified"
    LEAD = "reference ahead of the position beyond the servo's linear range"


class Membership(Protocol):
    """The certified set of a workspace (θ in degrees)."""

    @property
    def empty(self) -> bool: ...

    def contains(self, theta_deg: F) -> B: ...


@dataclass(frozen=True)
class Rules:
    """Which of the rules 4–5 a check applies (1–3 and 6 always; 7 when it is given the
    certified set)."""

    position_limits: bool = True
    """Hold the simulated positions to the servo limits (rule 4)."""
    speed_at_samples: bool = True
    """Hold the model speed at the samples to vmax + :data:`SAMPLE_TOL` (rule 5)."""


#: Every plan segment the executor runs.
EXECUTE_RULES = Rules()
#: A horizon re-planned while following live: its solver holds the samples to the speed
#: bound in the profile's own discretization and its positions to a region of the cover,
#: so the check holds the exact motion to the between-sample bound and the certified set.
FOLLOW_RULES = Rules(position_limits=False, speed_at_samples=False)


@dataclass(frozen=True)
class Violation:
    """The first rule a motion breaks and where."""

    rule: Rule
    index: int
    """Reference sample (NOT_FINITE, REFERENCE_LIMIT); the step from reference sample
    ``index`` to ``index + 1`` (STEP; −1: from the reference in use before); sample
    (SPEED_AT_SAMPLE); simulated point, between samples ``index // POINTS_PER_INTERVAL`` and
    the next (POSITION_LIMIT, SPEED_BETWEEN, NOT_CERTIFIED); 0 (NOTHING_CERTIFIED)."""
    joint: int
    """Joint 0..2; −1 when the rule is not one joint's (NOT_CERTIFIED, NOTHING_CERTIFIED)."""
    value: float
    """The offending angle (deg), step (deg) or speed (deg/s); NaN when none."""
    bound: float
    """The bound it passes: the servo limit, the largest step, the speed bound applied;
    NaN when none."""


@dataclass(frozen=True)
class MotionCheck:
    """The verdict on one motion and what was checked."""

    violation: Violation | None
    """The first violation, None when every rule holds."""
    positions_deg: F
    """(M, 3) simulated positions at the instants checked ((0, 3) when refused before)."""
    max_speed_degps: float
    """Largest model speed at the instants checked, deg/s (NaN when refused before)."""
    max_step_deg: float
    """Largest reference step, deg."""

    @property
    def ok(self) -> bool:
        return self.violation is None

    @property
    def points(self) -> int:
        """Simulated instants checked."""
        return int(self.positions_deg.shape[0])


def _first(bad: B) -> tuple[int, int]:
    """(row, column) of the first True of a 2-D mask, row-major."""
    k, i = (int(x) for x in np.argwhere(bad)[0])
    return k, i


def _limits(rule: Rule, th: F, lo: F, hi: F) -> Violation | None:
    below, above = th < lo - LIMIT_TOL_DEG, th > hi + LIMIT_TOL_DEG
    bad = below | above
    if not bad.any():
        return None
    k, i = _first(bad)
    return Violation(rule, k, i, float(th[k, i]), float(lo[i] if below[k, i] else hi[i]))


def _speed(rule: Rule, speed: F, cap: F) -> Violation | None:
    """The fastest of the points (M, 3) above ``cap`` ((3,), per joint), if any."""
    bad = speed > cap
    if not bad.any():
        return None
    k, i = (int(x) for x in np.unravel_index(int(np.argmax(np.where(bad, speed, -np.inf))),
                                             speed.shape))
    return Violation(rule, k, i, float(speed[k, i]), float(cap[i]))


def check_motion(p: Pole, ts: float, x0: F, references_deg: F, lo_deg: F, hi_deg: F,
                 vmax_degps: float, certified: Membership | None, *,
                 rules: Rules = EXECUTE_RULES, previous_reference_deg: F | None = None,
                 hold_samples: int = 0, speed_floor_degps: F | None = None,
                 lead_max_deg: float | None = None, samples: F | None = None) -> MotionCheck:
    """Check the motion of (27) with pole ``p`` (rad/s; or ωn, ζ as :class:`Dynamics`) and period ``ts`` (s) from state
    ``x0`` ((3, 2): θ deg, θ̇ deg/s) under ``references_deg`` ((N+1, 3)) against the rules
    (module docstring).

    ``lo_deg``/``hi_deg``: servo limits (3,); ``vmax_degps``: speed bound; ``certified``:
    the workspace's certified set, None when the caller certifies the positions itself;
    ``previous_reference_deg``: the reference in use before (its step counts);
    ``hold_samples``: samples the last reference is held after the plan (a settling tail,
    simulated and checked like the plan); ``speed_floor_degps``: per joint, a speed the
    bounds never fall below (a joint already faster may not get faster); ``samples``: the
    exact (ZOH) states at the samples ((N+1, 3, 2)) from ``x0`` under ``references_deg``
    when the caller computed them already (a planner's report; never with ``hold_samples``).
    """
    ref = np.asarray(references_deg, float)
    lo, hi = np.asarray(lo_deg, float), np.asarray(hi_deg, float)
    none = np.zeros((0, 3))
    head = ref if previous_reference_deg is None else np.vstack(
        [np.asarray(previous_reference_deg, float)[None], ref])
    steps = np.abs(np.diff(head, axis=0))
    step = float(steps.max()) if steps.size else 0.0

    def refused(v: Violation) -> MotionCheck:
        return MotionCheck(v, none, float("nan"), step)

    if not np.all(np.isfinite(ref)):
        k, i = _first(~np.isfinite(ref))
        return refused(Violation(Rule.NOT_FINITE, k, i, float(ref[k, i]), float("nan")))
    if (v := _limits(Rule.REFERENCE_LIMIT, ref, lo, hi)) is not None:
        return refused(v)
    if step > MAX_REFERENCE_STEP_DEG:
        k, i = (int(x) for x in np.unravel_index(int(np.argmax(steps)), steps.shape))
        shift = 0 if previous_reference_deg is None else 1
        return refused(Violation(Rule.STEP, k - shift, i, float(steps[k, i]), MAX_REFERENCE_STEP_DEG))

    full = np.concatenate([ref, np.repeat(ref[-1:], hold_samples, axis=0)])
    if samples is not None and (hold_samples or np.shape(samples) != (len(ref), 3, 2)):
        raise ValueError("samples: the (N+1, 3, 2) states at the samples, without a hold")
    _, xs = simulate_continuous(p, ts, np.asarray(x0, float), full, POINTS_PER_INTERVAL, samples)
    pos, speed = xs[..., 0], np.abs(xs[..., 1])
    floor = np.zeros(3) if speed_floor_degps is None else np.asarray(speed_floor_degps, float)
    violation = (
        (_limits(Rule.POSITION_LIMIT, pos, lo, hi) if rules.position_limits else None)
        or (_lead(ref, pos[::POINTS_PER_INTERVAL][: len(ref)], lead_max_deg)
            if lead_max_deg is not None else None)
        or (_speed(Rule.SPEED_AT_SAMPLE, speed[::POINTS_PER_INTERVAL],
                   np.maximum(vmax_degps + SAMPLE_TOL, floor)) if rules.speed_at_samples else None)
        or _speed(Rule.SPEED_BETWEEN, speed,
                  np.maximum(vmax_degps * (1.0 + BETWEEN_SPEED_ALLOWANCE), floor))
        or _certify(certified, pos))
    return MotionCheck(violation, pos, float(speed.max()), step)


def _lead(ref: F, at_samples: F, bound: float) -> Violation | None:
    """The largest |θ*(k) − θ(k)| above ``bound`` + :data:`SAMPLE_TOL` (the model's θ at the
    samples, k = 0..N−1: the last reference is the goal, held), if any."""
    lead = np.abs(ref[:-1] - at_samples[:-1]) if len(ref) > 1 else np.zeros((0, 3))
    bad = lead > bound + SAMPLE_TOL
    if not bad.any():
        return None
    k, i = (int(x) for x in np.unravel_index(int(np.argmax(np.where(bad, lead, -np.inf))),
                                             lead.shape))
    return Violation(Rule.LEAD, k, i, float(lead[k, i]), bound)


def _certify(certified: Membership | None, pos: F) -> Violation | None:
    if certified is None:
        return None
    if certified.empty:
        return Violation(Rule.NOTHING_CERTIFIED, 0, -1, float("nan"), float("nan"))
    ok = certified.contains(pos)
    if ok.all():
        return None
    return Violation(Rule.NOT_CERTIFIED, int(np.argmin(ok)), -1, float("nan"), float("nan"))
