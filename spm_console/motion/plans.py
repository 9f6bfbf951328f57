"""Simple executor plans built here: straight-line moves (homing, approach) and a
clearly-named synthetic smooth plan for tests and benchmarks.

Optimal plans (MVN, minimum time) come from the planning module; these are the
plain motions the executor needs around them. Each plan carries the servo
model's positions and velocities under its references (model (28), at rest at the
start), like a solved plan. Degrees, deg/s, seconds.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import servo_limits_deg, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.polytope.region import Region
from spm_console.core.servo.estimation import ModelPredictor
from spm_console.store.plan_file import plan_hash

F = NDArray[np.float64]


def limits_region(profile: Profile) -> Region:
    """The box of the servo software limits (bus.joints min/max), deg."""
    lo, hi = servo_limits_deg(profile)
    return Region(np.vstack([np.eye(3), -np.eye(3)]), np.concatenate([hi, -lo]))


def settle_samples(profile: Profile) -> int:
    """Samples to hold the final reference: 10/p s, when (27)'s lag is below 1e-3 of a step
    (10 over the slowest mode's decay rate for an identified model), plus its delay."""
    m = servo_model_of(profile)
    return max(1, math.ceil((10.0 / m.dynamics.slowest_rate + m.delay_s) / m.ts))


def plan_from_references(
    profile: Profile,
    reference_deg: F,
    kind: Literal["synthetic", "homing", "jog", "experiment"],
    region: Region | None = None,
    notes: dict[str, float] | None = None,
) -> Plan:
    """Wrap references (N+1, 3) with the model's simulated positions and velocities.

    ``notes``: details kept in the plan (and its file's "extra") for people to read; the
    program never reads them back."""
    model = servo_model_of(profile)
    ref = np.asarray(reference_deg, float)
    pred = ModelPredictor(model, ref[0])
    pos = np.empty_like(ref)
    vel = np.empty_like(ref)
    for k in range(len(ref)):
        pos[k], vel[k] = pred.position_deg, pred.velocity_degps
        pred.advance(ref[k])
    return Plan(
        kind=kind, Ts=model.ts, reference_deg=ref, position_deg=pos, velocity_degps=vel,
        region=region if region is not None else limits_region(profile),
        model=model, profile_hash=plan_hash(profile), notes=dict(notes or {}),
    )


def quantization_speed_margin(profile: Profile) -> float:
    """Speed (deg/s) one tick of goal quantization can add: a 1-tick step into (27) peaks
    at tick·p/e in velocity (the double pole's step response, at t = 1/p; an identified
    model's own peak)."""
    tick = 360.0 / profile.bus.ticks_per_turn
    return tick * servo_model_of(profile).dynamics.step_peak_speed()


def line_plan(profile: Profile, start_deg: F, goal_deg: F, speed_degps: float,
              kind: Literal["homing", "jog"] = "homing") -> Plan:
    """Straight line in θ from start to goal, no joint faster than ``speed_degps``; ``kind``
    names it in plan files and run logs ("homing", or "jog" for a one-joint jog).

    References ramp at constant speed (all joints arrive together), then hold the
    goal for :func:`settle_samples`. The model (27) is critically damped, so its
    speed under a ramp rises monotonically to the ramp speed and never exceeds it (an
    underdamped model overshoots it by its step overshoot: the ramp is that much slower);
    the ramp runs :func:`quantization_speed_margin` below the bound because the
    servos receive whole ticks, not the exact ramp.
    """
    a = np.asarray(start_deg, float)
    b = np.asarray(goal_deg, float)
    ts = profile.servo.ts_s
    margin = quantization_speed_margin(profile)
    ramp = speed_degps - margin if speed_degps > 2 * margin else speed_degps / 2
    ramp /= 1.0 + servo_model_of(profile).dynamics.overshoot()
    dist = float(np.abs(b - a).max())
    n_move = max(1, math.ceil(dist / ramp / ts))
    s = np.minimum(np.arange(n_move + 1 + settle_samples(profile)) / n_move, 1.0)
    ref = a + s[:, None] * (b - a)
    return plan_from_references(profile, ref, kind,
                                notes={"speed_bound_degps": speed_degps, "ramp_degps": ramp,
                                       "move_samples": n_move})


def synthetic_plan(profile: Profile, start_deg: F, goal_deg: F, duration_s: float) -> Plan:
    """SYNTHETIC (not optimal): quintic minimum-jerk references from start to goal in
    ``duration_s``, then the goal held while the servos settle. For tests and benchmarks
    when no solved plan is at hand."""
    a = np.asarray(start_deg, float)
    b = np.asarray(goal_deg, float)
    ts = profile.servo.ts_s
    n_move = max(1, round(duration_s / ts))
    s = np.minimum(np.arange(n_move + 1 + settle_samples(profile)) / n_move, 1.0)
    shape = 10 * s**3 - 15 * s**4 + 6 * s**5
    ref = a + shape[:, None] * (b - a)
    return plan_from_references(profile, ref, "synthetic", notes={"duration_s": duration_s})


def plan_summary(plan: Plan, source: str | None = None) -> dict[str, object]:
    """What a run's meta.json records about a plan (angles in degrees): the summary's
    figures, and the ends of the references the servos were sent: θ*(0) and θ*(N), named
    for what they are (a plan's θ(0) is its start, which a reference need not equal)."""
    s = plan.summary()
    return {
        "source": source, **s.figures(), "first_reference_deg": list(s.first_reference_deg),
        "last_reference_deg": list(s.last_reference_deg), "halfspaces": s.halfspaces,
        "profile_hash": s.profile_hash,
    }
