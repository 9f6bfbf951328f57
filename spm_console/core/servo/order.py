"""Does a record ask for a higher order than the identified second-order model?

The identified model (ωn, ζ, delay d, load) is compared with the same model through one more
real pole, a first-order lag of time constant τ on the reference (a slower drive or a
compliant transmission would show as one): both are fitted to the experiment's fit part with
the load's offset taken off the reference, the delay held at the identified one, and judged on
the held-out part. The data ask for the higher order when its held-out RMS falls below
:data:`ASK_RATIO` of the second order's. The planner's model stays second order (28); the
answer is reported, and the residual bound covers what is left.

Sampling is taken as uniform at the record's median interval (the executor's ±1 ms jitter
moves the ZOH input by less than the delay's own resolution); the delay splits each interval:
x(t_k + d) = Φ(d) x_k + Γ(d) θ*(k−1), x_{k+1} = Φ(Ts − d) x(t_k + d) + Γ(Ts − d) θ*(k).
Degrees, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm
from scipy.optimize import least_squares
from scipy.signal import lfilter, ss2tf

from spm_console.core.servo.identify import P_BOUNDS, ZETA_BOUNDS
from spm_console.core.servo.model import Dynamics, continuous

F = NDArray[np.float64]

ASK_RATIO = 0.8
"""A third pole must bring the held-out RMS below this share of the second order's."""
TAU_MAX_S = 0.2
"""Largest lag time constant searched, s."""


@dataclass(frozen=True)
class OrderCheck:
    """The second-order model against the same with one more real pole, on held-out data."""

    tau_s: float
    """Fitted lag time constant, s (0: the fit found none)."""
    held_out_rms_2nd_deg: float
    held_out_rms_3rd_deg: float

    @property
    def asks(self) -> bool:
        """Whether the data ask for the higher order."""
        return self.held_out_rms_3rd_deg < ASK_RATIO * self.held_out_rms_2nd_deg


def _zoh(A: F, B: F, h: float) -> tuple[F, F]:
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A * h, B * h
    E = expm(M)
    return E[:n, :n], E[:n, n]


def _system(wn: float, zeta: float, tau: float) -> tuple[F, F]:
    """States [θ, θ̇] of (27) (τ = 0), or [θ, θ̇, θ_f] with τ·θ̇_f = θ* − θ_f driving it."""
    Ac, Bc = continuous(Dynamics(wn, zeta))
    if tau <= 0.0:
        return Ac, Bc.reshape(2)
    A = np.zeros((3, 3))
    A[:2, :2], A[:2, 2], A[2, 2] = Ac, Bc.reshape(2), -1.0 / tau
    return A, np.array([0.0, 0.0, 1.0 / tau])


def simulate(wn: float, zeta: float, tau: float, delay_s: float, ts: float, reference: F,
             theta0: F) -> F:
    """Positions (n, J) at the samples, from rest at θ0 with θ0 held before the first
    sample."""
    A, B = _system(wn, zeta, tau)
    d = min(max(delay_s, 0.0), ts)
    P1, G1 = _zoh(A, B, d) if d > 0 else (np.eye(A.shape[0]), np.zeros(A.shape[0]))
    P2, G2 = _zoh(A, B, ts - d)
    # y = C (zI − A)⁻¹ (B0 + B1 z⁻¹) u with A = Φ(Ts−d)Φ(d), B0 = Γ(Ts−d), B1 = Φ(Ts−d)Γ(d):
    # a linear filter (scipy's lfilter) on the deviations from the rest at θ0
    Ad = P2 @ P1
    C = np.zeros((1, A.shape[0]))
    C[0, 0] = 1.0
    num0, den = ss2tf(Ad, G2[:, None], C, np.zeros((1, 1)))
    num1, _ = ss2tf(Ad, (P2 @ G1)[:, None], C, np.zeros((1, 1)))
    b = np.zeros(A.shape[0] + 2)
    b[: A.shape[0] + 1] += num0[0]
    b[1:] += num1[0]
    th0 = np.asarray(theta0, float).reshape(1, -1)
    dev = np.asarray(reference, float) - th0
    y = lfilter(b, den, dev, axis=0)  # strictly proper: sample k sees inputs up to k − 1
    return np.asarray(y + th0, float)


def check_order(t: F, reference: F, measured: F, fit_mask: NDArray[np.bool_],
                held_mask: NDArray[np.bool_], wn: float, zeta: float, delay_s: float,
                theta0: F) -> OrderCheck:
    """Fit (ωn, ζ, θ0) with τ = 0 and (ωn, ζ, τ, θ0) on ``fit_mask`` of the record (t (n,) s,
    the reference less the load's offset and the positions (n, J) deg, NaN where lost), the
    delay held; compare them on ``held_mask``."""
    t = np.asarray(t, float)
    ts = float(np.median(np.diff(t)))
    ref, meas = np.asarray(reference, float), np.asarray(measured, float)
    seen = np.isfinite(meas).all(axis=1)
    fit, held = fit_mask & seen, held_mask & seen
    J = ref.shape[1]

    def resid(x: F, with_tau: bool, mask: NDArray[np.bool_]) -> F:
        tau = float(x[2]) if with_tau else 0.0
        th0 = x[3:] if with_tau else x[2:]
        sim = simulate(float(x[0]), float(x[1]), tau, delay_s, ts, ref, th0)
        return np.asarray((sim - meas)[mask].reshape(-1), float)

    def fitted(with_tau: bool) -> F:
        head = [wn, zeta] + ([min(0.01, TAU_MAX_S / 2)] if with_tau else [])
        x0 = np.concatenate([head, np.asarray(theta0, float).reshape(J)])
        lo = [P_BOUNDS[0], ZETA_BOUNDS[0]] + ([1e-4] if with_tau else []) + [-np.inf] * J
        hi = [P_BOUNDS[1], ZETA_BOUNDS[1]] + ([TAU_MAX_S] if with_tau else []) + [np.inf] * J
        sol = least_squares(resid, x0, bounds=(lo, hi), args=(with_tau, fit), x_scale="jac",
                            max_nfev=100)
        return np.asarray(sol.x, float)

    x2, x3 = fitted(False), fitted(True)
    r2, r3 = resid(x2, False, held), resid(x3, True, held)

    def rms(r: F) -> float:
        return float(math.sqrt(float(np.mean(r * r)))) if r.size else float("nan")

    return OrderCheck(float(x3[2]), rms(r2), rms(r3))
