"""Identification of a servo's load with its dynamics (:mod:`.load`).

Alternately: the dynamics (ωn, ζ, delay) fitted to the reference less the load's offset
(:func:`~spm_console.core.servo.identify.identify`), and the offset's parameters by ridge
least squares through the model, which is linear: its response to θ* − Σ π_k col_k is its
response to θ* less Σ π_k times its responses to the columns. Degrees, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.servo.identify import IdentifyResult, identify, response
from spm_console.core.servo.load import SMOOTH_DEGPS, LoadModel
from spm_console.core.servo.model import Dynamics

F = NDArray[np.float64]

FIT_ROUNDS = 4
"""Alternations of dynamics and load parameters in :func:`fit_load`."""
RIDGE = 1e-3
"""Tikhonov weight of the load parameters, relative to the largest squared singular value of
their (normalized) columns: directions the record does not excite stay near 0 instead of
taking whatever value fits the noise."""


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
