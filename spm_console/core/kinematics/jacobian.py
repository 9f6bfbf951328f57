"""Jacobians J1, J2, J (11)-(13) and the conditioning index ζ (14)-(17).

Sign note: with w_i(θ) of eq. (2), ∂w_i/∂θ_i = w_i × u_i, so differentiating the
constraint w_i·v_i = cos α2 gives J1 ω − J2 θ̇ = 0 (eq. 10 up to the sign of J2).
The condition number κ = ‖J‖‖J⁻¹‖ (and so ζ) does not depend on that sign, nor on
whether J or J⁻¹ is called "the" Jacobian. We return J = J1⁻¹ J2 as printed in (13).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]


def j1_matrix(v: F, w: F) -> F:
    """J1 (11): rows (v_i × w_i)ᵀ. v, w (..., 3, 3) -> (..., 3, 3)."""
    return np.cross(v, w)


def j2_diag(u: F, v: F, w: F) -> F:
    """Diagonal of J2 (12): (u_i × w_i)·v_i. -> (..., 3)."""
    return np.einsum("...ij,...ij->...i", np.cross(np.broadcast_to(u, w.shape), w), v)


def _adj3(M: F) -> F:
    """Adjugate of 3×3 matrices (..., 3, 3) (so M @ adj(M) = det(M) I)."""
    c = np.empty_like(M)
    for i in range(3):
        for j in range(3):
            r = [k for k in range(3) if k != i]
            s = [k for k in range(3) if k != j]
            minor = M[..., r[0], s[0]] * M[..., r[1], s[1]] - M[..., r[0], s[1]] * M[..., r[1], s[0]]
            c[..., j, i] = (-1) ** (i + j) * minor
    return c


def jacobian(u: F, v: F, w: F) -> F:
    """J = J1⁻¹ J2 (13); NaN where J1 is singular."""
    J1 = j1_matrix(v, w)
    J2 = j2_diag(u, v, w)
    det1 = np.linalg.det(J1)
    with np.errstate(divide="ignore", invalid="ignore"):
        J = (_adj3(J1) * J2[..., None, :]) / det1[..., None, None]
    return np.asarray(J)


def conditioning_index(u: F, v: F, w: F) -> F:
    """ζ = 1/κ(J) with ‖J‖ = sqrt(tr(Jᵀ W J)), W = I/3 (14)-(17). Exactly 0 at singularities.

    Computed without inverting anything: with M = adj(J1) J2 = det(J1) J and
    M' = adj(J2) J1 = det(J2) J⁻¹,  ζ = |det J1| |det J2| / (‖M‖ ‖M'‖).
    """
    J1 = j1_matrix(v, w)
    d2 = j2_diag(u, v, w)
    det1 = np.abs(np.linalg.det(J1))
    det2 = np.abs(np.prod(d2, axis=-1))
    M = _adj3(J1) * d2[..., None, :]
    adj2 = np.stack(
        [d2[..., 1] * d2[..., 2], d2[..., 0] * d2[..., 2], d2[..., 0] * d2[..., 1]], -1
    )
    Mp = adj2[..., :, None] * J1
    nM = np.sqrt(np.sum(M * M, axis=(-2, -1)) / 3.0)
    nMp = np.sqrt(np.sum(Mp * Mp, axis=(-2, -1)) / 3.0)
    den = nM * nMp
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(den > 0.0, det1 * det2 / np.where(den > 0.0, den, 1.0), 0.0)
    return np.asarray(np.clip(z, 0.0, 1.0))
