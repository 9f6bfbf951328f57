"""Static loads on the motor joints: the regressor of the weight of the wrist's bodies.

Every body of a spherical wrist turns about the centre, so body b's centre of mass is
R_b(θ)·c_b, with c_b where it sits at home, and its potential energy is m_b·g·upᵀR_b(θ)c_b.
The weight's torque on motor joint j is then linear in the bodies' first moments of mass
s_b = m_b·c_b (the classical linear-in-parameters form of a manipulator's gravity, e.g.
Khalil and Dombre, *Modeling, Identification and Control of Robots*, ch. 12):

    τ_j(θ) = −∂U/∂θ_j = −g Σ_b Σ_k (upᵀ ∂R_b/∂θ_j e_k) s_b,k ,

so the regressor Y(θ) (3 joints × 7 bodies · 3 components) needs only the kinematics. Bodies:
the three proximal links, the three distal links, the platform (:data:`BODIES`). The
derivatives are central differences of the bodies' rotations, the platform's from the
continuation step of the unique FK (eq. 1-13), to O(h²).

Angles in radians; the regressor is per radian of θ_j.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.continuation import continuation_step
from spm_console.core.kinematics.joint_states import body_rotations
from spm_console.core.kinematics.model import SpmModel

F = NDArray[np.float64]

GRAVITY_MPS2 = 9.81
"""Standard gravity, m/s² (along the base's −z in the emulated wrist and the descriptions)."""

BODIES = ("proximal 1", "proximal 2", "proximal 3", "distal 1", "distal 2", "distal 3",
          "platform")
"""The bodies whose weight loads the motors, in the regressor's order."""
PARAMETERS = 3 * len(BODIES)
"""First-moment components: (body, x/y/z at home) flattened body-major."""
DIFF_STEP_RAD = 1e-5
"""Step of the central differences, rad (errors O(h²) ≈ 1e-10 of the regressor)."""
STEP_RAD = math.radians(1.0)
"""Largest continuation step along a path, rad."""
MAX_BATCH_SUBSTEPS = 8
"""Largest gap between two rows, in steps, that the batched check follows (else the walk)."""
SAME_POSE = 1e-8
"""Rotations that agree to this (entries) are the same pose (Newton's tolerance is 1e-10)."""


def gravity_regressor(model: SpmModel, theta: F, R: F, up: F) -> F:
    """Y(θ) of the poses θ (n, 3) rad, platform rotations R (n, 3, 3): (n, 3, 21), with
    Y[n, j, 3b + k] = ∂(upᵀ R_b e_k)/∂θ_j at pose n. The weight's torque on the motors is
    −g·Y·s for first moments s (kg·m, home frame) and ``up`` the unit vector against
    gravity in the base frame."""
    th = np.asarray(theta, float).reshape(-1, 3)
    rot = np.asarray(R, float).reshape(-1, 3, 3)
    up = np.asarray(up, float) / float(np.linalg.norm(up))
    n = th.shape[0]
    # the six perturbed poses of every row (+h, −h on each joint) in one batched FK step
    steps = np.concatenate([DIFF_STEP_RAD * np.eye(3), -DIFF_STEP_RAD * np.eye(3)])  # (6, 3)
    t = (th[None, :, :] + steps[:, None, :]).reshape(-1, 3)
    th6 = np.broadcast_to(th, (6, n, 3)).reshape(-1, 3)
    rot6 = np.broadcast_to(rot, (6, n, 3, 3)).reshape(-1, 3, 3)
    bodies = body_rotations(model, t, continuation_step(model, th6, rot6, t).R)
    bodies = bodies.reshape(6, n, len(BODIES), 3, 3)
    d = (bodies[:3] - bodies[3:]) / (2.0 * DIFF_STEP_RAD)  # (3 joints, n, 7, 3, 3)
    out = np.einsum("a,jnbak->njbk", up, d)
    return np.asarray(out.reshape(n, 3, PARAMETERS), float)


def path_rotations(model: SpmModel, theta: F, R0: F | None = None,
                   theta0: F | None = None) -> F:
    """The platform's rotation at every row of a path θ (n, 3) rad, by continuation from
    (θ0, R0) (default home) through the rows in turn, each subdivided to steps ≤ 1°
    (:func:`walk_rotations`). Raises ValueError where the path leaves the home modes (a
    singularity on the way).

    Batched where that gives the walk's answer: every row is reached straight from the start
    at once (one batched step per degree of the largest move), then batched continuation
    steps (≤ 1°) from each row's pose to the next row check it — the walk's own steps between
    rows: they must converge, stay in the home modes above ζ's floor and land on the batch's
    pose. Anything else (a gap above 8°, a row the batch cannot reach, a step that
    disagrees) is walked row after row."""
    th = np.asarray(theta, float).reshape(-1, 3)
    start = model.theta_home if theta0 is None else np.asarray(theta0, float)
    R_start = np.eye(3) if R0 is None else np.asarray(R0, float)
    steps = math.ceil(float(np.abs(np.diff(th, axis=0)).max(initial=0.0)) / STEP_RAD)
    if th.shape[0] > 1 and steps <= MAX_BATCH_SUBSTEPS:
        res = model.track_batch(th, start, R_start, max_step=STEP_RAD)
        if all(r.ok and r.pose is not None for r in res):
            R = np.stack([r.pose.R for r in res if r.pose is not None])
            if _walk_agrees(model, th, R, max(steps, 1)):
                return R
    return walk_rotations(model, th, R_start, start)


def _walk_agrees(model: SpmModel, th: F, R: F, steps: int) -> bool:
    """Whether continuing from every row's pose R[n] to the next row, in ``steps`` equal
    steps (each ≤ 1°), stays in the home modes above ζ's floor and lands on R[n + 1]."""
    d = th[1:] - th[:-1]
    cur_t, cur_R = th[:-1], R[:-1]
    for k in range(1, steps + 1):
        nxt = th[:-1] + d * (k / steps)
        st = continuation_step(model, cur_t, cur_R, nxt)
        if not bool(st.good().all()):
            return False
        cur_t, cur_R = nxt, st.R
    return float(np.abs(cur_R - R[1:]).max()) <= SAME_POSE


def walk_rotations(model: SpmModel, theta: F, R0: F, theta0: F) -> F:
    """:func:`path_rotations` row after row along the path (each from the one before)."""
    th = np.asarray(theta, float).reshape(-1, 3)
    cur_t, cur_R = np.asarray(theta0, float), np.asarray(R0, float)
    out = np.empty((th.shape[0], 3, 3))
    for n, target in enumerate(th):
        res = model.track(target, cur_t, cur_R, max_step=STEP_RAD)
        if not res.ok or res.pose is None:
            raise ValueError(f"no FK along the path at row {n}: {res.reason}")
        cur_t, cur_R = target, res.pose.R
        out[n] = cur_R
    return out
