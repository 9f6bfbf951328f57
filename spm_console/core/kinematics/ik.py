"""Inverse kinematics: three uncoupled equations, two working modes per leg.

With w_i(θ) = P_i + Q_i cos θ + S_i sin θ (eq. 2), constraint (4) becomes
a cos θ + b sin θ + c = 0, a = Q_i·v_i, b = S_i·v_i, c = P_i·v_i − cos α2, whose
two roots are the leg's working modes; they have opposite signs of the J2 entry
(u_i × w_i)·v_i. The root kept is the one with the home's sign (profile home).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.jacobian import j2_diag
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.rotations import rpy_matrix
from spm_console.errors import BadInputError, UnreachableError

F = NDArray[np.float64]


@dataclass(frozen=True)
class IkResult:
    """θ for one platform orientation, in the home working modes."""

    theta: F
    """Motor angles (3,), rad, wrapped to within ±180° of home."""
    both: F
    """Both roots per leg (3, 2), rad; column 0 is the home working mode."""
    v: F
    """The orientation solved for (rows v1..v3)."""

    @property
    def theta_deg(self) -> F:
        return np.degrees(self.theta)


def check_orientation(model: SpmModel, v: F, tol: float = 1e-6) -> None:
    """Refuse rows that are not unit axes at the platform's pairwise angle α3."""
    v = np.asarray(v, float)
    if v.shape != (3, 3) or not np.all(np.isfinite(v)):
        raise BadInputError("orientation: expected nine finite numbers v1x v1y v1z … v3z")
    norms = np.linalg.norm(v, axis=1)
    if np.abs(norms - 1).max() > tol:
        raise BadInputError(f"orientation: rows must be unit vectors, norms are {np.round(norms, 6)}")
    c3 = model.geom.cos_alpha3
    dots = [v[0] @ v[1], v[0] @ v[2], v[1] @ v[2]]
    if max(abs(d - c3) for d in dots) > tol:
        raise BadInputError(
            f"orientation: v_i·v_j must equal cos α3 = {c3:.6f}, got {np.round(dots, 6)}"
        )
    chir = np.linalg.det(v) * np.linalg.det(model.v_home)
    if chir < 0:
        raise BadInputError("orientation: axes are a mirror image of the platform (wrong handedness)")


#: How far (each row, Euclidean) given axes may lie from an orientation of the platform and
#: still be taken as it (axes printed to four decimals lie within about 1e-4).
ROUNDED_AXES_TOL = 1e-3


def nearest_orientation(model: SpmModel, v: F) -> tuple[F, float]:
    """The platform's axes R v_home (rows) closest to ``v`` (rows v1..v3) in the least-squares
    sense (orthogonal Procrustes, R a rotation), and the largest row distance to ``v``."""
    v = np.asarray(v, float)
    U, _, Wt = np.linalg.svd(v.T @ model.v_home)
    D = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(U @ Wt)) or 1.0)])
    R = U @ D @ Wt
    out = np.asarray(model.v_home @ R.T)
    return out, float(np.linalg.norm(out - v, axis=1).max())


def ik(model: SpmModel, v: F) -> IkResult:
    """θ (rad) that places the top axes at ``v`` (rows v1..v3) in the home working modes."""
    v = np.asarray(v, float)
    check_orientation(model, v)
    P, Q, S = model.geom.ik_coeffs()
    a = (Q * v).sum(-1)
    b = (S * v).sum(-1)
    c = (P * v).sum(-1) - model.geom.cos_alpha2
    r = np.hypot(a, b)
    ratio = -c / np.where(r > 0, r, 1.0)
    bad = (r <= 1e-12) | (np.abs(ratio) > 1.0 + 1e-12)
    if bad.any():
        legs = ", ".join(str(i + 1) for i in np.flatnonzero(bad))
        raise UnreachableError(f"orientation out of reach: no motor angle places leg(s) {legs}")
    phi = np.arctan2(b, a)
    d = np.arccos(np.clip(ratio, -1.0, 1.0))
    roots = np.stack([phi + d, phi - d], -1)
    # wrap near home
    h = model.theta_home[:, None]
    roots = h + (roots - h + np.pi) % (2 * np.pi) - np.pi
    w0 = model.geom.w(roots[:, 0])
    w1 = model.geom.w(roots[:, 1])
    s0 = j2_diag(model.u, v, w0)
    s1 = j2_diag(model.u, v, w1)
    pick0 = np.where(np.abs(s0 - s1) < 1e-12, True, np.sign(s0) == model.working_signs)
    first = np.where(pick0, roots[:, 0], roots[:, 1])
    second = np.where(pick0, roots[:, 1], roots[:, 0])
    return IkResult(theta=first, both=np.stack([first, second], -1), v=v)


def ik_rpy(model: SpmModel, roll: float, pitch: float, yaw: float) -> IkResult:
    """θ for the platform rotated from home by R = Rz(yaw) Ry(pitch) Rx(roll) (radians)."""
    R = rpy_matrix(roll, pitch, yaw)
    return ik(model, model.v_home @ R.T)
