"""Closed-loop servo model (27) and its discretization (28).

Continuous model per joint, state x = [θ, θ̇] (deg, deg/s), input θ* (deg):
    ẋ = [[0, 1], [−ωn², −2ζωn]] x + [0, ωn²] θ*,
with ζ = 1 the paper's (27), a double pole at −p (ωn = p, rad/s). An identified servo may
be under- or overdamped (ζ ≠ 1) and see its reference a transport delay d later
(:class:`Dynamics`). Discretized with Ts in closed form: exact sampling (zero-order hold,
the paper's Sec. V and our default) or Tustin (bilinear). python-control's ``c2d`` is the
independent cross-check in the tests; the core does not import it. Note: the paper's printed
eq. (35) is the Tustin discretization with the poles at +p — unstable; never used.

The delay does not enter (A, B): a plan starts at rest with its first reference held at the
start (30b), so the delayed response is the undelayed one d later, on the same path. The
runtime's model of what it will measure (:func:`delayed_spans`) applies it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]

Discretization = Literal["zoh", "tustin"]


@dataclass(frozen=True)
class Dynamics:
    """A joint's continuous closed-loop dynamics (unit DC gain)."""

    wn: float
    """Natural frequency ωn, rad/s (the paper's p when ζ = 1)."""
    zeta: float = 1.0
    """Damping ratio ζ > 0 (1: the paper's double pole)."""
    delay_s: float = 0.0
    """Transport delay d, s, 0 ≤ d < Ts: the reference sent at t acts from t + d."""

    @property
    def slowest_rate(self) -> float:
        """Decay rate of the slowest mode, 1/s: ζωn up to ζ = 1 (p for (27)), the slow real
        pole ωn(ζ − √(ζ² − 1)) above."""
        z = self.zeta
        return self.wn * (z if z <= 1.0 else z - float(np.sqrt(z * z - 1.0)))

    def step_peak_speed(self) -> float:
        """Largest speed of the response to a unit step of the reference, 1/s (deg/s per
        deg): p/e for (27); for ζ < 1, ωn·e^{−ζφ/√(1−ζ²)} with φ = arccos ζ (at ω_d·t = φ)."""
        z, w = self.zeta, self.wn
        if z < 1.0:
            r = float(np.sqrt(1.0 - z * z))
            return w * float(np.exp(-z * float(np.arccos(z)) / r))
        if z == 1.0:
            return w / math.e  # p·t·e^{−pt} peaks at t = 1/p
        # ζ > 1: real poles a < b, ab = ωn²; the velocity ωn²(e^{−at} − e^{−bt})/(b − a)
        # peaks at t = ln(b/a)/(b − a)
        r = math.sqrt(z * z - 1.0)
        a, b = w * (z - r), w * (z + r)
        t = math.log(b / a) / (b - a)
        return w * w * (math.exp(-a * t) - math.exp(-b * t)) / (b - a)

    def overshoot(self) -> float:
        """Fractional overshoot of the step response: e^{−πζ/√(1−ζ²)} below ζ = 1, else 0."""
        z = self.zeta
        return float(np.exp(-np.pi * z / np.sqrt(1.0 - z * z))) if z < 1.0 else 0.0


Pole = float | Dynamics
"""A bare p (rad/s) means the paper's (27): Dynamics(p)."""


def dynamics(pole: Pole) -> Dynamics:
    """``pole`` as :class:`Dynamics` (a float is the double pole at −p)."""
    return pole if isinstance(pole, Dynamics) else Dynamics(float(pole))


def continuous(pole: Pole) -> tuple[F, F]:
    """(Ac, Bc) of (27) for pole −p (rad/s), or of ωn, ζ."""
    d = dynamics(pole)
    w, z = d.wn, d.zeta
    Ac = np.array([[0.0, 1.0], [-w * w, -2.0 * z * w]])
    Bc = np.array([[0.0], [w * w]])
    return Ac, Bc


@dataclass(frozen=True)
class ServoModel:
    """Discrete model x(k+1) = A x(k) + B θ*(k) of one joint (28)."""

    p: float
    """Natural frequency ωn, rad/s: with ζ = 1 the closed-loop double pole at −p of (27)."""
    ts: float
    """Sampling interval, s."""
    method: Discretization
    """'zoh' (exact sampling) or 'tustin'."""
    A: F
    """(2, 2) state matrix."""
    B: F
    """(2,) input vector."""
    zeta: float = 1.0
    """Damping ratio ζ (1: the paper's double pole)."""
    delay_s: float = 0.0
    """Transport delay d, s (0 ≤ d < Ts); not in (A, B), see the module's note."""

    @property
    def dynamics(self) -> Dynamics:
        """The continuous model this was sampled from."""
        return Dynamics(self.p, self.zeta, self.delay_s)

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"A": self.A.tolist(), "B": self.B.tolist(), "p": self.p,
                                  "Ts": self.ts, "discretization": self.method}
        if self.zeta != 1.0 or self.delay_s != 0.0:
            out.update(zeta=self.zeta, delay_s=self.delay_s)
        return out


def discretize(pole: Pole, ts: float, method: Discretization = "zoh") -> ServoModel:
    """Discretize (27) in closed form: 'zoh' = :func:`exact_step` over Ts; 'tustin' =
    A = (I − Ts/2·Ac)⁻¹(I + Ts/2·Ac), B = (I − Ts/2·Ac)⁻¹ Bc·Ts (the bilinear map of the
    state equation, as python-control's ``c2d(method="bilinear")`` gives it)."""
    d = dynamics(pole)
    if method == "tustin":
        Ac, Bc = continuous(d)
        M = np.eye(2) - 0.5 * ts * Ac
        A = np.asarray(np.linalg.solve(M, np.eye(2) + 0.5 * ts * Ac), float)
        B = np.asarray(np.linalg.solve(M, Bc * ts), float).reshape(2)
    else:
        A, B = exact_step(d, ts)
    return ServoModel(p=d.wn, ts=ts, method=method, A=A, B=B, zeta=d.zeta, delay_s=d.delay_s)


_SERIES_X = 1e-4
"""Below this |ω_d·τ| the circular/hyperbolic terms use their series (no 0/0 near ζ = 1)."""


def exact_step(pole: Pole, tau: float) -> tuple[F, F]:
    """Exact (ZOH) transition of (27) over ``tau`` seconds: x(t+τ) = Φ x(t) + Γ θ*.

    Closed form, σ = ζωn, λ = ωn²(ζ² − 1): Φ = e^{−στ} [c·I + s·(Ac + σI)] with
    c = cos(ω_d τ), s = sin(ω_d τ)/ω_d, ω_d = √−λ when ζ < 1 (cosh, sinh and √λ when ζ > 1;
    c = 1, s = τ when ζ = 1, where Φ = e^{−pτ} [[1+pτ, τ], [−p²τ, 1−pτ]]). The DC gain is 1,
    so Γ = (I − Φ)·[1, 0]. Returns (Φ (2, 2), Γ (2,)).
    """
    a, b, c, d, g0, g1 = exact_coeffs(pole, tau)
    return np.array([[a, b], [c, d]]), np.array([g0, g1])


def exact_coeffs(pole: Pole, tau: float) -> tuple[float, float, float, float, float, float]:
    """:func:`exact_step` as plain floats (Φ00, Φ01, Φ10, Φ11, Γ0, Γ1): for loops over many
    irregular intervals, where small arrays cost more than the arithmetic."""
    d = pole if isinstance(pole, Dynamics) else Dynamics(float(pole))
    w, z = d.wn, d.zeta
    sigma = z * w
    lam = w * w * (z * z - 1.0)
    wd = math.sqrt(abs(lam))
    x = wd * tau
    if x < _SERIES_X:
        sgn = 1.0 if lam > 0 else -1.0  # cosh/sinh above ζ = 1, cos/sin below
        c = 1.0 + sgn * x * x / 2.0
        s = tau * (1.0 + sgn * x * x / 6.0)
    elif lam < 0:
        c, s = math.cos(x), math.sin(x) / wd
    else:
        c, s = math.cosh(x), math.sinh(x) / wd
    e = math.exp(-sigma * tau)
    p00, p01 = e * (c + s * sigma), e * s
    p10, p11 = -e * s * w * w, e * (c - s * sigma)
    return p00, p01, p10, p11, 1.0 - p00, -p10


def substeps(pole: Pole, ts: float, k: int) -> tuple[F, F]:
    """Exact ZOH matrices at the sub-sample instants j·Ts/k, j = 1..k−1.

    Returns (Phis (k−1, 2, 2), Gams (k−1, 2)), read-only (kept for the next call with the
    same arguments); empty for k = 1.
    """
    if k < 1:
        raise ValueError(f"sub-samples per interval must be ≥ 1, got {k}")
    return _substeps(pole, float(ts), int(k))


@functools.lru_cache(maxsize=64)
def _substeps(pole: Pole, ts: float, k: int) -> tuple[F, F]:
    mats = [exact_step(pole, j * ts / k) for j in range(1, k)]
    Phis = np.array([m[0] for m in mats]).reshape(k - 1, 2, 2)
    Gams = np.array([m[1] for m in mats]).reshape(k - 1, 2)
    Phis.setflags(write=False)
    Gams.setflags(write=False)
    return Phis, Gams


def simulate(model: ServoModel, x0: F, reference: F) -> F:
    """Discrete simulation of (28) for every joint.

    ``x0``: (J, 2) initial [θ, θ̇] per joint (deg, deg/s); ``reference``: (N+1, J) θ*(k), deg
    (θ*(N) is the reference held after the end). Returns states (N+1, J, 2).
    """
    ref = np.asarray(reference, float)
    (a, b), (c, d) = model.A.tolist()
    b0, b1 = model.B.tolist()
    out = np.empty((ref.shape[0], ref.shape[1], 2))
    x0 = np.asarray(x0, float)
    for i in range(ref.shape[1]):  # scalar recursion: far faster than tiny numpy ops
        th, om = float(x0[i, 0]), float(x0[i, 1])
        col = [(th, om)]
        for u in ref[:-1, i].tolist():
            th, om = a * th + b * om + b0 * u, c * th + d * om + b1 * u
            col.append((th, om))
        out[:, i, :] = col
    return out


def simulate_continuous(pole: Pole, ts: float, x0: F, reference: F, points: int,
                        samples: F | None = None) -> tuple[F, F]:
    """Exact continuous response of (27) under the piecewise-constant references.

    ``points`` ≥ 1 instants per interval (t = k·Ts + j·Ts/points, j = 0..points−1) plus the
    last sample. ``samples``: the exact (ZOH) states at the samples if already known.
    Returns (t (M,), states (M, J, 2)) with M = N·points + 1.
    """
    ref = np.asarray(reference, float)
    n = ref.shape[0] - 1
    if samples is None:
        exact = discretize(pole, ts, "zoh")
        xk = simulate(exact, x0, ref)  # (N+1, J, 2) at the samples
    else:
        xk = np.asarray(samples, float)
    Phis, Gams = substeps(pole, ts, points)
    # inside interval k: x = Φ_j x(k) + Γ_j θ*(k); each component as outer products (k, j, i)
    th, om, u = xk[:n, None, :, 0], xk[:n, None, :, 1], ref[:n, None, :]
    P, G = Phis[None, :, :, :, None], Gams[None, :, :, None]  # (1, j, 2, 2, 1), (1, j, 2, 1)
    xs = np.empty((n, points, ref.shape[1], 2))
    xs[:, 0] = xk[:n]
    for a in range(2):
        xs[:, 1:, :, a] = P[:, :, a, 0] * th + P[:, :, a, 1] * om + G[:, :, a] * u
    xs = np.concatenate([xs.reshape(n * points, ref.shape[1], 2), xk[n:]], axis=0)
    t = np.arange(n * points + 1) * (ts / points)
    return t, xs
