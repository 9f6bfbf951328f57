"""The servo under load: its model driven by the reference less the drive's offset.

A position servo holding a load settles where its drive's torque balances it: with a
proportional drive of stiffness K, θ = θ* − τ/K at rest. So the model (27)-(28) is driven by
θ* − d(θ, θ̇) rather than θ*, with d (deg) the offset the load costs:

* the wrist's weight, d_grav = Y(θ)·m: Y the regressor of the bodies' weight (per rad, from
  the kinematics; :mod:`spm_console.core.kinematics.loads`) and m its first moments of mass
  scaled by g/K (deg per unit of Y);
* Coulomb friction in the gear, d_fric,j = c_j·tanh(θ̇_j / v_s): it opposes the motion (a
  smooth sign, so the reference stays smooth through a reversal; 0 at rest, where the
  friction takes any value within ±c_j).

Given the load's offset along a motion, sending θ* + d makes the loaded servo follow the model
of θ* (the compensation the runtime applies). :func:`fit_load` identifies m and c together
with the model's ωn, ζ and delay: alternately the dynamics for the offset-corrected reference
and the offset's parameters by ridge least squares through the model (the model is linear, so
its response to d is the sum of its responses to d's columns).

Pure: the regressor's values come from the caller. Degrees, deg/s, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.servo.identify import IdentifyResult, identify, response
from spm_console.core.servo.model import Dynamics

F = NDArray[np.float64]

SMOOTH_DEGPS = 2.0
"""Speed v_s at which the friction offset reaches tanh(1) = 76 % of c, deg/s (about a tick
per 20 ms period: below, the encoder cannot tell motion from rest)."""
FIT_ROUNDS = 4
"""Alternations of dynamics and load parameters in :func:`fit_load`."""
RIDGE = 1e-3
"""Tikhonov weight of the load parameters, relative to the largest squared singular value of
their (normalized) columns: directions the record does not excite stay near 0 instead of
taking whatever value fits the noise."""


@dataclass(frozen=True)
class LoadModel:
    """The offset d the servos' load costs, deg: d = Y(θ)·m + c·tanh(θ̇/v_s)."""

    moments_deg: F
    """(P,) first moments of the bodies' mass scaled by g/K, deg (Y per rad)."""
    coulomb_deg: float
    """The friction's offset c, deg (≥ 0; the joints share it, as they share ωn and ζ)."""
    smooth_degps: float = SMOOTH_DEGPS
    """v_s, deg/s."""

    def offset_deg(self, gravity_columns: F, velocity_degps: F) -> F:
        """d (n, 3) deg for the regressor Y (n, 3, P) at the poses and the joints' speeds
        (n, 3) deg/s."""
        grav = np.asarray(gravity_columns, float) @ self.moments_deg
        v = np.asarray(velocity_degps, float)
        return np.asarray(grav + self.coulomb_deg * np.tanh(v / self.smooth_degps), float)


def _columns(gravity_columns: F, velocity_degps: F, smooth: float) -> F:
    """The load's columns (n, 3, P + 1): the weight's regressor, then the friction's."""
    fric = np.tanh(np.asarray(velocity_degps, float) / smooth)[:, :, None]
    return np.concatenate([np.asarray(gravity_columns, float), fric], axis=2)


def model_velocity(dyn: Dynamics, t: F, reference: F, theta0: F) -> F:
    """The model's speeds (n, 3) deg/s at the instants t under the references (the friction
    column's argument: smooth, unlike the encoder's differences)."""
    pos = response(dyn, dyn.delay_s, t - t[0], reference, theta0)
    return np.asarray(np.gradient(pos, t, axis=0), float)


@dataclass(frozen=True)
class LoadFit:
    """Dynamics and load identified together."""

    result: IdentifyResult
    """The dynamics fitted to the reference less the load's offset."""
    load: LoadModel
    offset_deg: F
    """(n, 3) the fitted offset along the record, deg."""


def fit_load(t: F, reference: F, measured: F, gravity_columns: F, lost: NDArray[np.bool_],
             start: IdentifyResult, smooth_degps: float = SMOOTH_DEGPS) -> LoadFit:
    """Identify ωn, ζ, the delay and the load (m, c) on a record: t (n,) s, references and
    positions (n, 3) deg (NaN where lost), the weight's regressor at the measured poses
    (n, 3, P). ``start``: the dynamics fitted without load. Raises as :func:`identify`."""
    t = np.asarray(t, float)
    ref = np.asarray(reference, float)
    meas = np.asarray(measured, float)
    seen = ~np.asarray(lost, bool) & np.isfinite(meas).all(axis=1)
    res = start
    params = np.zeros(gravity_columns.shape[2] + 1)
    for _ in range(FIT_ROUNDS):
        dyn = res.dynamics
        vel = model_velocity(dyn, t, ref, res.theta0_deg)
        cols = _columns(gravity_columns, vel, smooth_degps)
        base = response(dyn, dyn.delay_s, t - t[0], ref, res.theta0_deg)
        # the model is linear: its response to ref − Σ π_k col_k is base − Σ π_k G(col_k)
        resp = np.stack([response(dyn, dyn.delay_s, t - t[0], cols[:, :, k], cols[0, :, k])
                         for k in range(cols.shape[2])], axis=2)  # (n, 3, K)
        A = -resp[seen].reshape(-1, cols.shape[2])
        b = (meas[seen] - base[seen]).reshape(-1)
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0.0] = 1.0
        An = A / scale
        s_max = float(np.linalg.norm(An, 2)) if An.size else 1.0
        lam = RIDGE * s_max * s_max
        params = np.linalg.solve(An.T @ An + lam * np.eye(An.shape[1]), An.T @ b) / scale
        params[-1] = max(float(params[-1]), 0.0)  # friction opposes the motion
        d = cols @ params
        res = identify(t, ref - d, meas, fit_delay=True, fit_damping=True, lost=~seen,
                       start=res.dynamics)
    dyn = res.dynamics
    vel = model_velocity(dyn, t, ref, res.theta0_deg)
    cols = _columns(gravity_columns, vel, smooth_degps)
    load = LoadModel(params[:-1].copy(), float(params[-1]), smooth_degps)
    return LoadFit(res, load, cols @ params)
