"""The payload, from the IMU stage's poses: each was held after a verified move, so the offset
between the pose commanded and the one the servos hold is the load's (:mod:`spm_console.core.
commissioning.payload`). Fitted on the stage's fit poses, checked on its held-out ones;
reported, never written to the profile: statics give the payload's first moment m·c, not its
mass, and the profile's mass model needs both. Degrees, N·m, kg·m."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.payload import (
    HoldingFit,
    fit_holding,
    predicted_offsets_deg,
)
from spm_console.core.kinematics.loads import BODIES, gravity_regressor
from spm_console.description.weight import UP, Weight

F = NDArray[np.float64]

#: The platform's columns in the regressor of the bodies' first moments.
_PLATFORM = slice(3 * BODIES.index("platform"), 3 * BODIES.index("platform") + 3)


@dataclass(frozen=True)
class PayloadReport:
    fit: HoldingFit
    held_out_rms_deg: float
    """RMS of predicted − measured offsets on the held-out poses, deg."""


def _loads(profile: Profile, theta_deg: F) -> tuple[F, F]:
    """The wrist's holding torque (n, 3) N·m and the platform's regressor (n, 3, 3) at the
    poses θ (deg) (NaN rows where the FK finds no pose)."""
    model = model_of(profile)
    th = np.radians(np.asarray(theta_deg, float).reshape(-1, 3))
    R = np.empty((len(th), 3, 3))
    for i, t in enumerate(th):
        r = model.track(t)
        R[i] = r.pose.R if r.ok and r.pose is not None else np.nan
    tw = Weight.of(profile).torque_nm(th, R)
    yp = gravity_regressor(model, th, R, UP)[:, :, _PLATFORM]
    return np.asarray(tw, float), np.asarray(yp, float)


def payload_from_holding(profile: Profile, commanded_deg: F, measured_deg: F,
                         held_out: NDArray[np.bool_]) -> PayloadReport:
    """Fit the payload to the offsets commanded − measured (n, 3) deg at the poses not
    ``held_out``; check it on those. ValueError when the data do not determine it."""
    measured = np.asarray(measured_deg, float)
    offsets = np.asarray(commanded_deg, float) - measured
    tw, yp = _loads(profile, measured)
    comp = float(profile.servo.load_deg_per_nm or 0.0)
    fit = fit_holding(offsets[~held_out], tw[~held_out], yp[~held_out], comp)
    pred = predicted_offsets_deg(fit, tw[held_out], yp[held_out], comp)
    rms = float(np.sqrt(np.mean((pred - offsets[held_out]) ** 2))) if held_out.any() else 0.0
    return PayloadReport(fit, rms)
