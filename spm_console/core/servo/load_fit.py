"""Identification of a servo's load with its dynamics (:mod:`.load`).

Alternately: the dynamics (ωn, ζ, delay) fitted to the reference less the load's offset
(:func:`~spm_console.core.servo.identify.identify`), and the offset's parameters by ridge
least squares through the model, which is linear: its response to θ* − Σ π_k col_k is its
response to θ* less Σ π_k times its responses to the columns. Degrees, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from spm_console.core.servo.identify import (
    DELAY_MAX_S,
    P_BOUNDS,
    ZETA_BOUNDS,
    IdentifyResult,
    identify,
    response,
)
from spm_console.core.servo.load import SMOOTH_DEGPS, LoadModel
from spm_console.core.servo.model import Dynamics

F = NDArray[np.float64]

FIT_ROUNDS = 2
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
    res, params = _refine(t, ref, meas, gravity_columns, seen, res, params, smooth_degps)
    return LoadFit(res, LoadModel(params[:-1].copy(), float(params[-1]), smooth_degps))


def _refine(t: F, ref: F, meas: F, gravity_columns: F, seen: NDArray[np.bool_],
            res: IdentifyResult, params: F, smooth: float) -> tuple[IdentifyResult, F]:
    """All parameters at once (ωn, ζ, delay, θ0, load) by scipy's least_squares from the
    alternation's estimate: the friction's column depends on the dynamics (through the
    model's speed), which the alternation converges to only slowly."""
    n0 = 3 + 3

    def unpack(x: F) -> tuple[Dynamics, F, F]:
        return Dynamics(float(x[0]), float(x[1]), float(x[2])), x[3:n0], x[n0:]

    def resid(x: F) -> F:
        dyn, th0, pi = unpack(x)
        cols = _columns(gravity_columns, model_velocity(dyn, t, ref, th0), smooth)
        sim = response(dyn, dyn.delay_s, t - t[0], ref - cols @ pi, th0 - cols[0] @ pi)
        return np.asarray((sim - meas)[seen].reshape(-1), float)

    x0 = np.concatenate([[res.p, res.zeta, res.delay_s], res.theta0_deg, params])
    lo = np.concatenate([[P_BOUNDS[0], ZETA_BOUNDS[0], 0.0], np.full(3, -np.inf),
                         np.full(params.size - 1, -np.inf), [0.0]])
    hi = np.concatenate([[P_BOUNDS[1], ZETA_BOUNDS[1], DELAY_MAX_S], np.full(3, np.inf),
                         np.full(params.size, np.inf)])
    x0 = np.clip(x0, lo, hi)
    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=60)
    if not sol.success or not np.isfinite(sol.x).all():
        return res, params
    dyn, th0, pi = unpack(sol.x)
    r = sol.fun
    out = replace(res, p=dyn.wn, zeta=dyn.zeta, delay_s=dyn.delay_s, theta0_deg=th0.copy(),
                  rms_deg=float(np.sqrt(np.mean(r * r))) if r.size else 0.0,
                  max_abs_deg=float(np.abs(r).max()) if r.size else 0.0)
    return out, pi.copy()
