"""Closed-loop servo model (27) and its discretization (28).

Continuous model per joint, state x = [θ, θ̇] (deg, deg/s), input θ* (deg):
    ẋ = [[0, 1], [−p², −2p]] x + [0, p²] θ*,   double pole at −p (rad/s).
Discretized with Ts by python-control: exact sampling (zero-order hold, the
paper's Sec. V and our default) or Tustin. Note (SPEC §3): the paper's printed
eq. (35) is the Tustin discretization with the poles at +p — unstable; never used.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import control
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
    """Discretize (27) with python-control's ``c2d`` ('zoh' or 'tustin')."""
    Ac, Bc = continuous(p)
    sys_c = control.ss(Ac, Bc, np.array([[1.0, 0.0]]), np.zeros((1, 1)))
    sys_d = control.c2d(sys_c, ts, method="bilinear" if method == "tustin" else "zoh")
    A = np.asarray(sys_d.A, float)
    B = np.asarray(sys_d.B, float).reshape(2)
    return ServoModel(p=p, ts=ts, method=method, A=A, B=B)
