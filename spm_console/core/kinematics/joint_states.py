"""Every joint of the wrist, actuated and passive, from one solved pose: what a tree model of
the closed chain (URDF) needs to draw the whole wrist, and what the logs publish.

All joint axes pass through the centre, and every link's frame is the world's frame in the
home configuration, where every joint angle is 0 (the product-of-exponentials form). Leg i:

* the motor joint turns the proximal link about −u_i by q_i = θ_i − θ_home,i (eq. 1: θ_i grows
  by a rotation about −u_i);
* the distal link turns about w_i(θ_home) by φ_i, so that it carries v_i(home) to v_i (eq. 2);
* the platform, seen from leg i, turns about v_i(home) by ψ_i: R = P_i D_i Rot(v_i⁰, ψ_i),
  with P_i, D_i the two rotations above.

Angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.model import SpmModel, platform_axes
from spm_console.core.kinematics.rotations import expm_so3

F = NDArray[np.float64]


@dataclass(frozen=True)
class JointStates:
    """The wrist's joints, rad: each (..., 3), leg i at index i (one row per pose)."""

    motor: F
    """q_i = θ_i − θ_home,i: the proximal link about −u_i."""
    distal: F
    """φ_i: the distal link about w_i(θ_home), relative to the proximal link."""
    platform: F
    """ψ_i: the platform about v_i(home), relative to leg i's distal link."""


def signed_angle(axis: F, a: F, b: F) -> F:
    """The angle (rad) of the rotation about unit ``axis`` that takes ``a`` to ``b``'s direction
    in the plane normal to the axis (each (..., 3))."""
    a_n = a - axis * np.sum(axis * a, axis=-1, keepdims=True)
    b_n = b - axis * np.sum(axis * b, axis=-1, keepdims=True)
    return np.asarray(np.arctan2(np.sum(axis * np.cross(a_n, b_n), axis=-1),
                                 np.sum(a_n * b_n, axis=-1)))


def _legs(model: SpmModel, theta: F, R: F) -> tuple[F, F, F, F]:
    """(q, φ, proximal rotations P_i, distal rotations D_i) of poses (each leg's (..., 3)
    angles, (..., 3, 3, 3) rotations from home)."""
    w0 = model.geom.w(model.theta_home)
    v0 = model.v_home
    v = platform_axes(R, v0)  # (..., 3 legs, 3)
    q = np.asarray(theta, float) - model.theta_home
    prox = expm_so3(-model.u * q[..., None])  # (..., 3 legs, 3, 3)
    t = np.einsum("...lba,...lb->...la", prox, v)  # Pᵀ v_i
    phi = signed_angle(w0, v0, t)
    return q, phi, prox, prox @ expm_so3(w0 * phi[..., None])


def body_rotations(model: SpmModel, theta: F, R: F) -> F:
    """Every body's rotation from home (..., 7, 3, 3): proximal links 1-3, distal links 1-3,
    the platform (R)."""
    _, _, prox, dist = _legs(model, theta, R)
    return np.concatenate([prox, dist, np.asarray(R, float)[..., None, :, :]], axis=-3)


def joint_states(model: SpmModel, theta: F, R: F) -> JointStates:
    """The joints of poses: θ rad (..., 3), platform rotations R from home (..., 3, 3)."""
    w0 = model.geom.w(model.theta_home)
    v0 = model.v_home
    q, phi, _, dist = _legs(model, theta, R)
    rel = np.einsum("...lba,...bc->...lac", dist, R)  # Dᵀ R: about v_i(home) on a closed chain
    ref = np.cross(v0, w0)
    psi = signed_angle(v0, ref, np.einsum("...lab,lb->...la", rel, ref))
    return JointStates(q, phi, psi)
