"""Identification of the closed-loop servo model (27): fit p (and a pure delay) by least squares.

Data: sample instants t (s), the reference θ*(t_k) (deg) applied from t_k until the
next sample (zero-order hold, as the executor streams it), and the measured
positions θ(t_k) (deg) — a logged step response or an executed run; one column per
joint, all joints sharing p. The model starts at rest at θ0 (one per joint, fitted
too, so the quantization of the first sample does not bias p) with the input equal
to θ0 before the first sample. With a delay d the reference sent at t_k acts from
t_k + d. The response is computed exactly (matrix exponential of (27) between
events), and p, d, θ0 are fitted by scipy's least_squares from the best point of a
coarse logarithmic grid of p.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from spm_console.core.servo_model import exact_step
from spm_console.errors import BadInputError, SolverError

F = NDArray[np.float64]

P_BOUNDS = (0.5, 1000.0)
"""Search range of p, rad/s."""
DELAY_MAX_S = 0.25
"""Largest pure delay considered, s."""
DELAY_GRID_S = (0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.15)
"""Delays (s) of the coarse grid the fit starts from."""
DIFF_STEP_P = 1e-6
"""Finite-difference step of p, relative."""
DIFF_STEP_ABS = 1e-6
"""Finite-difference step of the delay (s) and of θ0 (deg)."""


@dataclass(frozen=True)
class IdentifyResult:
    """A fitted servo model."""

    p: float
    """Double closed-loop pole at −p, rad/s."""
    delay_s: float
    """Pure delay, s (0 when not fitted)."""
    theta0_deg: F
    """(J,) fitted initial rest positions, deg."""
    rms_deg: float
    """RMS of the position residuals, deg."""
    max_abs_deg: float
    """Largest absolute residual, deg."""
    p_std: float
    """Approximate standard deviation of p from the Jacobian (rad/s)."""
    samples: int
    joints: int
    fit_delay: bool
    seconds: float
    status: str
    """least_squares' message."""

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["theta0_deg"] = self.theta0_deg.tolist()
        return d


def _forward_jacobian(resid: Callable[[F], F], v: F, hi: list[float]) -> F:
    """Forward differences with absolute steps: p by 1e-6 of itself, the delay by 1 µs, each
    θ0 by 1e-6°. (least_squares' relative steps vanish for a delay at its bound of 0, which
    left the delay where the coarse grid put it.) A step that would cross the upper bound is
    taken backwards."""
    r0 = resid(v)
    out = np.empty((r0.size, v.size))
    for i in range(v.size):
        h = DIFF_STEP_P * max(abs(v[0]), 1.0) if i == 0 else DIFF_STEP_ABS
        if v[i] + h > hi[i]:
            h = -h
        w = v.copy()
        w[i] += h
        out[:, i] = (resid(w) - r0) / h
    return out


def _as2d(a: F, n: int, what: str) -> F:
    x = np.asarray(a, float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] != n:
        raise BadInputError(f"{what}: expected {n} rows (one per sample), got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise BadInputError(f"{what}: holds non-finite values")
    return x


def response(p: float, delay_s: float, t: F, reference: F, theta0: F) -> F:
    """Positions (n, J) at the instants t of (27) at rest at θ0, under the delayed ZOH reference."""
    n, J = reference.shape
    switch = t + delay_s
    # events: sample instants (measure) and switching instants (input change), in time order;
    # at equal times the switch acts first only if it is strictly earlier
    times = np.concatenate([t, switch])
    kinds = np.concatenate([np.zeros(n, int), np.ones(n, int)])
    idx = np.concatenate([np.arange(n), np.arange(n)])
    order = np.lexsort((-kinds, times)) if delay_s > 0 else np.lexsort((kinds, times))
    x = np.column_stack([theta0, np.zeros(J)])
    u = np.asarray(theta0, float).copy()
    out = np.empty((n, J))
    tc = float(times[order[0]])
    cache: dict[float, tuple[F, F]] = {}
    for e in order:
        te = float(times[e])
        dt = te - tc
        if dt > 0:
            key = round(dt, 12)
            if key not in cache:
                cache[key] = exact_step(p, dt)
            Phi, Gam = cache[key]
            x = x @ Phi.T + u[:, None] * Gam[None, :]
            tc = te
        if kinds[e] == 0:
            out[idx[e]] = x[:, 0]
        else:
            u = reference[idx[e]].copy()
    return out


def identify(t: F, reference: F, measured: F, fit_delay: bool = False) -> IdentifyResult:
    """Least-squares fit of p (and optionally a pure delay) to a logged response."""
    t0 = time.perf_counter()
    tt = np.asarray(t, float).reshape(-1)
    n = tt.size
    if n < 5:
        raise BadInputError(f"identification needs at least 5 samples, got {n}")
    if not np.all(np.isfinite(tt)) or np.any(np.diff(tt) <= 0):
        raise BadInputError("sample times must be finite and strictly increasing")
    ref = _as2d(reference, n, "reference")
    meas = _as2d(measured, n, "measured")
    if ref.shape != meas.shape:
        raise BadInputError(f"reference {ref.shape} and measured {meas.shape} differ in shape")
    J = ref.shape[1]
    excitation = float(np.ptp(ref, axis=0).max())
    if excitation <= 0:
        raise BadInputError("the reference never moves: nothing to identify")

    tt = tt - tt[0]  # a log's clock may read 1e5 s: a microsecond must still move an event

    def resid(v: F) -> F:
        p, d = v[0], (v[1] if fit_delay else 0.0)
        th0 = v[2:] if fit_delay else v[1:]
        return (response(p, d, tt, ref, th0) - meas).ravel()

    def jac(v: F) -> F:
        return _forward_jacobian(resid, v, hi)

    th_init = meas[0].copy()
    best = None
    for p in np.geomspace(2.0, 400.0, 12):
        for d in (DELAY_GRID_S if fit_delay else [0.0]):
            v = np.r_[p, d, th_init] if fit_delay else np.r_[p, th_init]
            c = float(np.sum(resid(v) ** 2))
            if best is None or c < best[0]:
                best = (c, v)
    assert best is not None
    lo = [P_BOUNDS[0]] + ([0.0] if fit_delay else []) + [-np.inf] * J
    hi = [P_BOUNDS[1]] + ([DELAY_MAX_S] if fit_delay else []) + [np.inf] * J
    v0 = np.clip(best[1], np.array(lo) + 1e-9, np.array(hi) - 1e-9)
    sol = least_squares(resid, v0, jac=jac, bounds=(lo, hi), x_scale="jac",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12)
    if not sol.success:
        raise SolverError(f"identification did not converge: {sol.message}")
    r = sol.fun
    dof = max(1, r.size - sol.x.size)
    s2 = float(r @ r) / dof
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * s2
        p_std = float(np.sqrt(max(cov[0, 0], 0.0)))
    except np.linalg.LinAlgError:
        p_std = float("nan")
    th0 = sol.x[2:] if fit_delay else sol.x[1:]
    return IdentifyResult(
        p=float(sol.x[0]), delay_s=float(sol.x[1]) if fit_delay else 0.0, theta0_deg=th0,
        rms_deg=float(np.sqrt(np.mean(r**2))), max_abs_deg=float(np.abs(r).max()),
        p_std=p_std, samples=n, joints=J, fit_delay=fit_delay,
        seconds=time.perf_counter() - t0, status=str(sol.message))
