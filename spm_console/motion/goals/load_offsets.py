"""What the runtime adds to each reference so that a loaded servo follows its model.

With an identified load (``[servo] load_deg_per_nm``, ``coulomb_deg``) the servo follows the
model of θ* − d, d its load's offset (:mod:`spm_console.core.servo.load`). The runtime sends
θ* + d, with d taken where the model of the verified references will be at the end of each
period (the weight's holding torque at that pose, the friction against the model's speed
there): the loaded servo then follows the model the plan was verified on. The last reference,
which the servos keep once the run ends, carries the offset at rest at the goal. The references as
sent are checked again here: finite, inside the servo limits (clipped onto them), steps
within the runtime's bound, every offset within :data:`MAX_OFFSET_DEG`.
Degrees, deg/s.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.core.kinematics.loads import path_rotations
from spm_console.core.plan_rules import MAX_REFERENCE_STEP_DEG
from spm_console.core.servo.load import LoadModel
from spm_console.core.servo.model import ServoModel, simulate
from spm_console.description.weight import Weight, holding_torque_nm
from spm_console.errors import PlanRefusedError

F = NDArray[np.float64]

MAX_OFFSET_DEG = 2.0
"""Largest load offset the runtime adds, deg: a model asking for more is not a load model
of a position servo holding a wrist (the MX-106 sags about 0.5° under this wrist's weight)."""


def load_model(profile: Profile) -> LoadModel | None:
    """The profile's load model (weight as deg per N·m of holding torque); None without one."""
    s = profile.servo
    if s.load_deg_per_nm is None and not s.coulomb_deg:
        return None
    return LoadModel(np.array([float(s.load_deg_per_nm or 0.0)]), float(s.coulomb_deg or 0.0))


def load_offsets(profile: Profile, model: ServoModel, refs: F, theta0: F) -> F | None:
    """d (n, 3) deg for the references (n, 3) of a run from rest at θ0 (deg); None without a
    load model. Raises PlanRefusedError when the offset is out of bounds or the model's path
    has no FK."""
    load = load_model(profile)
    if load is None:
        return None
    refs = np.asarray(refs, float)
    x0 = np.stack([np.asarray(theta0, float), np.zeros(3)], axis=1)
    states = simulate(model, x0, np.vstack([refs, refs[-1:]]))[1:]  # end of each period
    pos, vel = states[:, :, 0].copy(), states[:, :, 1].copy()
    # the last reference stays with the servos after the run: its offset is the one at rest
    # at the goal (the weight's alone), not the friction of a model still arriving
    if len(refs):
        pos[-1], vel[-1] = refs[-1], 0.0
    if load.moments_deg[0] != 0.0:
        try:
            hold = holding_torque_nm(profile, pos)
        except ValueError as exc:
            raise PlanRefusedError(f"the load's offset cannot be computed: {exc}") from None
    else:
        hold = np.zeros_like(pos)
    d = load.offset_deg(hold[:, :, None], vel)
    worst = float(np.abs(d).max()) if d.size else 0.0
    if not np.isfinite(worst) or worst > MAX_OFFSET_DEG:
        raise PlanRefusedError(f"the servo's load model asks for an offset of {worst:.3g}° "
                               f"(at most {MAX_OFFSET_DEG:g}°): check [servo] load_deg_per_nm "
                               "and coulomb_deg")
    return np.asarray(d, float)


def sent_references(refs: F, offsets: F | None, lo: F, hi: F, previous: F | None) -> F:
    """θ* + d clipped onto the servo limits [lo, hi], checked for the runtime's step bound
    (from ``previous``, the reference in use before, when given)."""
    if offsets is None:
        return refs
    sent = np.clip(np.asarray(refs, float) + offsets, lo, hi)
    chain = sent if previous is None else np.vstack([np.asarray(previous, float)[None], sent])
    steps = np.abs(np.diff(chain, axis=0))
    if steps.size and float(steps.max()) > MAX_REFERENCE_STEP_DEG:
        raise PlanRefusedError(f"with the load's offset a reference steps by "
                               f"{float(steps.max()):.3g}° (at most {MAX_REFERENCE_STEP_DEG:g}°)")
    return sent


class LoadTracker:
    """The load's offset at one pose after another (live following, which has no plan to
    compute it for ahead): the platform's FK continued from the last pose."""

    def __init__(self, profile: Profile, load: LoadModel, theta0_deg: F) -> None:
        self.load = load
        self.weight = Weight.of(profile)
        self.theta = np.radians(np.asarray(theta0_deg, float))
        self.R = path_rotations(self.weight.model, self.theta[None])[0]

    def offset(self, theta_deg: F, velocity_degps: F) -> F | None:
        """d (3,) deg at θ (deg) and the model's speed (deg/s); None where the FK from the
        last pose fails (nothing is added then)."""
        th = np.radians(np.asarray(theta_deg, float))
        if self.load.moments_deg[0] != 0.0:
            res = self.weight.model.track(th, self.theta, self.R)
            if not res.ok or res.pose is None:
                return None
            self.theta, self.R = th, res.pose.R
            hold = self.weight.torque_nm(th[None], self.R[None])
        else:
            hold = np.zeros((1, 3))
        d = self.load.offset_deg(hold[:, :, None], np.asarray(velocity_degps, float)[None])[0]
        return np.asarray(np.clip(d, -MAX_OFFSET_DEG, MAX_OFFSET_DEG), float)


def step_limited(previous: F | None, sent: F, lo: F, hi: F) -> F:
    """``sent`` clipped onto [lo, hi] and to within the runtime's reference step of
    ``previous`` (the reference sent before)."""
    out = np.clip(sent, lo, hi)
    if previous is not None:
        out = previous + np.clip(out - previous, -MAX_REFERENCE_STEP_DEG, MAX_REFERENCE_STEP_DEG)
    return np.asarray(out, float)
