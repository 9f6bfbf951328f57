"""What sits on the platform, from the offsets at which the servos hold it.

A position servo holding a load settles where its drive balances the load's torque: the
reference θ* less k·τ, k the drive's compliance (deg/(N·m), the inverse of its stiffness;
:mod:`spm_console.core.servo.load`). The torque that holds the wrist is linear in the bodies'
first moments of mass (:mod:`spm_console.core.kinematics.loads`): the wrist's own, τ_w(θ)
from the profile's masses, plus a payload's, g·Y_p(θ)·s with s = m·c its first moment in the
platform's frame at home and Y_p the platform's columns of the regressor. When the runtime
already sends θ* + k_c·τ_w (a profile with a load model), the offset held is

    θ* − θ = (k − k_c)·τ_w(θ) + k·g·Y_p(θ)·s ,

linear in a = k − k_c and b = k·s: four unknowns, fitted by least squares over poses held
across the workspace (three equations each), then k = a + k_c and s = b / k. The wrist's own
weight and a payload above the platform load the joints differently enough (the distal links
and the platform's offsets from the centre differ) for both to be determined from a few dozen
poses about home.

What statics cannot see: the payload's mass alone. A point mass at the centre of rotation
loads no joint; only m·c is observable (the mass needs the payload's inertia, from a dynamic
experiment). The offsets also carry the gear's Coulomb friction: a joint that came to rest
moving up stops short by the friction's offset f, one that came down overshoots by it. Given
the direction each joint approached its pose from, f is a fifth unknown (its column the
approach signs, which a tour visiting poses on both sides of each other varies); without,
it is left in the residual. A tick's quantization remains: the fit's standard errors say how
well the data determine each component.

Pure: degrees, N·m, kg·m; the regressors come from the caller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.loads import GRAVITY_MPS2

F = NDArray[np.float64]


@dataclass(frozen=True)
class HoldingFit:
    """The payload's first moment and the drive's compliance, from holding offsets."""

    first_moment_kgm: F
    """(3,) m·c of the payload, kg·m, in the platform's frame at home."""
    first_moment_std_kgm: F
    """(3,) standard errors (first order, from the residual's spread)."""
    compliance_deg_per_nm: float
    """k, deg/(N·m): the drive's offset per N·m of holding torque."""
    compliance_std: float
    residual_rms_deg: float
    """RMS of the offsets the fit leaves unexplained, deg (friction, quantization)."""
    singular_values: F
    """Of the least-squares matrix with unit-norm columns (wrist, payload x, y, z and, with
    the approach directions, friction): how independently the data see each unknown."""
    poses: int
    friction_deg: float | None = None
    """f, deg: the offset θ* − θ at rest per unit of the approach's sign: positive, the drive
    stops short of its goal (friction); negative, past it (the gear's play, the drive's
    overshoot). None: not fitted (no approach directions given)."""


def fit_holding(offsets_deg: F, wrist_torque_nm: F, payload_regressor: F,
                compensated_deg_per_nm: float = 0.0, approach: F | None = None) -> HoldingFit:
    """Fit a and b (see the module docstring) to the offsets θ* − θ (n, 3) deg held at n
    poses, given there the wrist's holding torque τ_w (n, 3) N·m and the platform's columns
    of the regressor Y_p (n, 3, 3) per kg·m (without g); ``compensated_deg_per_nm``: the
    runtime's k_c (0 when the profile has no load model); ``approach``: the sign (n, 3) of
    each joint's last motion before it came to rest there (−1, 0, 1), which adds the
    friction's offset f. ValueError with fewer than two poses (three with friction) or data
    that do not determine k."""
    r = np.asarray(offsets_deg, float).reshape(-1)
    tw = np.asarray(wrist_torque_nm, float).reshape(-1)
    yp = GRAVITY_MPS2 * np.asarray(payload_regressor, float).reshape(-1, 3)
    n = len(r) // 3
    cols = [tw[:, None], yp]
    if approach is not None:
        sg = np.sign(np.asarray(approach, float)).reshape(-1)
        if len(sg) != len(r):
            raise ValueError("fit_holding: one approach direction per joint and pose")
        cols.append(sg[:, None])
    if n < (3 if approach is not None else 2) or not (len(tw) == len(r) == len(yp)):
        raise ValueError("fit_holding: at least two poses, with a torque and regressor each")
    if not (np.isfinite(r).all() and np.isfinite(tw).all() and np.isfinite(yp).all()):
        raise ValueError("fit_holding: the offsets, torques and regressors must be finite")
    A = np.column_stack(cols)
    scale = np.linalg.norm(A, axis=0)
    if (scale == 0).any():
        raise ValueError("fit_holding: a column of the fit is zero (no pose loads it)")
    An = A / scale
    x_n, *_ = np.linalg.lstsq(An, r, rcond=None)
    x = x_n / scale
    resid = r - A @ x
    dof = max(1, len(r) - A.shape[1])
    sigma2 = float(resid @ resid) / dof
    cov_all = sigma2 * np.linalg.inv(An.T @ An) / np.outer(scale, scale)
    cov = cov_all[:4, :4]
    a, b = float(x[0]), x[1:4]
    friction = float(x[4]) if approach is not None else None
    k = a + compensated_deg_per_nm
    if not (math.isfinite(k) and k > 0.0):
        raise ValueError(f"fit_holding: the data give no positive compliance (k = {k:.4g} "
                         "deg/(N·m)): do the servos hold the wrist?")
    s = b / k
    # first order: s = b / k, with k's variance that of a (k_c is given)
    jac = np.column_stack([-s / k, np.eye(3) / k])  # ∂s/∂(a, b)
    cov_s = jac @ cov @ jac.T
    sv = np.linalg.svd(An, compute_uv=False)
    return HoldingFit(np.asarray(s, float), np.sqrt(np.clip(np.diag(cov_s), 0.0, None)), k,
                      math.sqrt(max(float(cov[0, 0]), 0.0)),
                      math.sqrt(float(resid @ resid) / len(r)), np.asarray(sv, float), n,
                      friction)


def predicted_offsets_deg(fit: HoldingFit, wrist_torque_nm: F, payload_regressor: F,
                          compensated_deg_per_nm: float = 0.0, approach: F | None = None) -> F:
    """The offsets (n, 3) deg ``fit`` predicts at poses with these τ_w and Y_p (and, when
    the fit has friction, the approach directions (n, 3))."""
    tw = np.asarray(wrist_torque_nm, float)
    yp = GRAVITY_MPS2 * np.asarray(payload_regressor, float)
    k = fit.compliance_deg_per_nm
    out = (k - compensated_deg_per_nm) * tw + k * (yp @ fit.first_moment_kgm)
    if fit.friction_deg is not None and approach is not None:
        out = out + fit.friction_deg * np.sign(np.asarray(approach, float))
    return np.asarray(out, float)
