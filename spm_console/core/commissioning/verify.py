"""Check a fitted wrist as built on held-out poses: the gravity direction it predicts against the
one measured, and, when a truth is known (the physical twin's platform), its orientation.

The prediction is the measurement model of :mod:`~spm_console.core.commissioning.gravity`: the
unique FK of (4) at θ_meas + δ with the fitted arcs, the fitted tilt and mount. Degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.commissioning.fit import angles_deg
from spm_console.core.commissioning.gravity import AsBuilt, evaluate
from spm_console.core.kinematics.model import SpmModel
from spm_console.errors import BadInputError

F = NDArray[np.float64]


@dataclass(frozen=True)
class Verification:
    """Predicted against measured, pose by pose (degrees)."""

    gravity_deg: tuple[float, ...]
    """Angle between the predicted and the measured gravity direction at each pose."""
    gravity_rms_deg: float
    gravity_max_deg: float
    orientation_deg: tuple[float, ...] | None
    """Angle of R_predictedᵀ R_truth at each pose (None without a truth)."""
    orientation_rms_deg: float | None
    orientation_max_deg: float | None


def rotation_angles_deg(Ra: F, Rb: F) -> F:
    """Angle of Raᵀ Rb for each pair of rotations (K, 3, 3), deg (from the axis-angle's sine
    and cosine: exact for small angles)."""
    D = np.einsum("kba,kbc->kac", Ra, Rb)
    c = (np.trace(D, axis1=1, axis2=2) - 1.0) / 2.0
    s = np.linalg.norm(np.stack([D[:, 2, 1] - D[:, 1, 2], D[:, 0, 2] - D[:, 2, 0],
                                 D[:, 1, 0] - D[:, 0, 1]], -1), axis=1) / 2.0
    return np.asarray(np.degrees(np.arctan2(s, c)))


def verify_as_built(
    model: SpmModel,
    as_built: AsBuilt,
    theta_meas_deg: F,
    gravity: F,
    truth_R: F | None = None,
) -> Verification:
    """Compare the fit ``as_built`` with held-out poses: ``theta_meas_deg`` (K, 3) reported joint
    angles, ``gravity`` (K, 3) the IMU's measured specific force (any scale), ``truth_R``
    (K, 3, 3) optionally the platform's true rotation from home in the base frame."""
    th = np.asarray(theta_meas_deg, float)
    g = np.asarray(gravity, float)
    if th.ndim != 2 or th.shape[1] != 3 or g.shape != th.shape or not np.isfinite(th).all():
        raise BadInputError(f"verify: (K, 3) joint angles and gravity vectors, got {th.shape} "
                            f"and {g.shape}")
    n = np.linalg.norm(g, axis=1)
    if not (np.isfinite(g).all() and (n > 0.0).all()):
        raise BadInputError("verify: every measured gravity vector must be finite and non-zero")
    ev = evaluate(model, as_built.vector_rad(), np.radians(th), jacobian=False)
    ga = angles_deg(ev.gravity, g / n[:, None])
    ori: F | None = None
    if truth_R is not None:
        T = np.asarray(truth_R, float)
        if T.shape != (len(th), 3, 3):
            raise BadInputError(f"verify: truth rotations must be ({len(th)}, 3, 3), got {T.shape}")
        ori = rotation_angles_deg(ev.R, T)
    return Verification(
        gravity_deg=tuple(float(a) for a in ga), gravity_rms_deg=float(np.sqrt(np.mean(ga**2))),
        gravity_max_deg=float(ga.max()),
        orientation_deg=None if ori is None else tuple(float(a) for a in ori),
        orientation_rms_deg=None if ori is None else float(np.sqrt(np.mean(ori**2))),
        orientation_max_deg=None if ori is None else float(ori.max()),
    )
