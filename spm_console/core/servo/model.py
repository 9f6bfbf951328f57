"""Closed-loop servo model (27) and its discretization (28).

Continuous model per joint, state x = [θ, θ̇] (deg, deg/s), input θ* (deg):
    ẋ = [[0, 1], [−p², −2p]] x + [0, p²] θ*,   double pole at −p (rad/s).
Discretized with Ts in closed form: exact sampling (zero-order hold, the paper's
Sec. V and our default) or Tustin (bilinear). python-control's ``c2d`` is the
independent cross-check in the tests; the core does not import it. Note: the paper's printed
eq. (35) is the Tustin discretization with the poles at +p — unstable; never used.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]

Discretization = Literal["zoh", "tustin"]


def continuous(p: float) -> tuple[F, F]:
    """(Ac, Bc) of (27) for pole −p (rad/s)."""
    Ac = np.array([[0.0, 1.0], [-p * p, -2.0 * p]])
    Bc = np.array([[0.0], [p * p]])
    return Ac, Bc


@dataclass(frozen=True)
class ServoModel:
    """Discrete model x(k+1) = A x(k) + B θ*(k) of one joint (28)."""

    p: float
    """Closed-loop double pole at −p, rad/s."""
    ts: float
    """Sampling interval, s."""
    method: Discretization
    """'zoh' (exact sampling) or 'tustin'."""
    A: F
    """(2, 2) state matrix."""
    B: F
    """(2,) input vector."""

    def to_dict(self) -> dict[str, object]:
        return {"A": self.A.tolist(), "B": self.B.tolist(), "p": self.p, "Ts": self.ts,
                "discretization": self.method}


def discretize(p: float, ts: float, method: Discretization = "zoh") -> ServoModel:
    """Discretize (27) in closed form: 'zoh' = :func:`exact_step` over Ts; 'tustin' =
    A = (I − Ts/2·Ac)⁻¹(I + Ts/2·Ac), B = (I − Ts/2·Ac)⁻¹ Bc·Ts (the bilinear map of the
    state equation, as python-control's ``c2d(method="bilinear")`` gives it)."""
    if method == "tustin":
        Ac, Bc = continuous(p)
        M = np.eye(2) - 0.5 * ts * Ac
        A = np.asarray(np.linalg.solve(M, np.eye(2) + 0.5 * ts * Ac), float)
        B = np.asarray(np.linalg.solve(M, Bc * ts), float).reshape(2)
    else:
        A, B = exact_step(p, ts)
    return ServoModel(p=p, ts=ts, method=method, A=A, B=B)


def exact_step(p: float, tau: float) -> tuple[F, F]:
    """Exact (ZOH) transition of (27) over ``tau`` seconds: x(t+τ) = Φ x(t) + Γ θ*.

    Closed form for the double pole at −p: Φ = e^{−pτ} [[1+pτ, τ], [−p²τ, 1−pτ]],
    Γ = [1 − e^{−pτ}(1+pτ), p²τ e^{−pτ}]. Returns (Φ (2, 2), Γ (2,)).
    """
    e = float(np.exp(-p * tau))
    Phi = e * np.array([[1.0 + p * tau, tau], [-p * p * tau, 1.0 - p * tau]])
    Gam = np.array([1.0 - e * (1.0 + p * tau), p * p * tau * e])
    return Phi, Gam


def substeps(p: float, ts: float, k: int) -> tuple[F, F]:
    """Exact ZOH matrices at the sub-sample instants j·Ts/k, j = 1..k−1.

    Returns (Phis (k−1, 2, 2), Gams (k−1, 2)); empty for k = 1.
    """
    if k < 1:
        raise ValueError(f"sub-samples per interval must be ≥ 1, got {k}")
    mats = [exact_step(p, j * ts / k) for j in range(1, k)]
    Phis = np.array([m[0] for m in mats]).reshape(k - 1, 2, 2)
    Gams = np.array([m[1] for m in mats]).reshape(k - 1, 2)
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


def simulate_continuous(p: float, ts: float, x0: F, reference: F, points: int,
                        samples: F | None = None) -> tuple[F, F]:
    """Exact continuous response of (27) under the piecewise-constant references.

    ``points`` ≥ 1 instants per interval (t = k·Ts + j·Ts/points, j = 0..points−1) plus the
    last sample. ``samples``: the exact (ZOH) states at the samples if already known.
    Returns (t (M,), states (M, J, 2)) with M = N·points + 1.
    """
    ref = np.asarray(reference, float)
    n = ref.shape[0] - 1
    if samples is None:
        Phi1, Gam1 = exact_step(p, ts)
        exact = ServoModel(p=p, ts=ts, method="zoh", A=Phi1, B=Gam1)
        xk = simulate(exact, x0, ref)  # (N+1, J, 2) at the samples
    else:
        xk = np.asarray(samples, float)
    Phis, Gams = substeps(p, ts, points)
    # inside interval k: x = Φ_j x(k) + Γ_j θ*(k); shapes (k, j, i, a)
    xa = xk[:n, None, :, None, :]  # (n, 1, J, 1, 2)
    inner = ((Phis[None, :, None, :, :] * xa).sum(-1)
             + Gams[None, :, None, :] * ref[:n, None, :, None])
    xs = np.concatenate([xk[:n, None], inner], axis=1).reshape(n * points, ref.shape[1], 2)
    xs = np.concatenate([xs, xk[n:]], axis=0)
    t = np.arange(n * points + 1) * (ts / points)
    return t, xs
