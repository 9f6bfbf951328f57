"""Live joint-velocity estimation from measured positions (pure: numpy + filterpy only).

Per joint, state x = [θ, θ̇] (deg, deg/s), the servo model (28)
``x(k+1) = A x(k) + B θ*(k)`` from :func:`~spm_console.core.servo.model.discretize`,
the reference θ*(k) as the known input and the measured position θ(k) as the
measurement. The joints are independent: one ``filterpy`` Kalman filter on their stacked
states, whose matrices are block diagonal (the three joints' filters in one call).

Noise model (profile section ``estimation``):

* measurement: R = σ_m², σ_m = ``measurement_noise_deg`` (quantization + backlash);
* process: Q = diag(σ_q², (σ_q / Ts)²), σ_q = ``process_noise_deg`` — an
  unmodelled position disturbance of σ_q per step together with the velocity
  change it implies over one step. (Tried on a quantized simulation of (27):
  this diagonal form is the most robust to a reference that lands up to a few
  ms late, which is what a real bus does.)

A real loop is not on the ideal grid: θ*(k) reaches the servos when it is written
(a little after k·Ts, much later in a late cycle) and θ(k) is read after that
(bus time; a retry after a timeout). :meth:`KalmanVelocity.step_timed` therefore
propagates (27) exactly over the actual spans — θ*(k−1) until the write, θ*(k)
until the read — and keeps the estimate at the measurement instant, so it
compares directly with the measurement whatever the timing.

:class:`FiniteDifference` is the plain backward difference of the measured
positions, the baseline the filter is compared with.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.servo.model import ServoModel, exact_step

if TYPE_CHECKING:
    from filterpy.kalman import KalmanFilter

F = NDArray[np.float64]


def process_noise(ts: float, sigma_pos_deg: float) -> F:
    """Q of one joint: diag(σ², (σ/Ts)²) for a position disturbance σ (deg) per step."""
    return np.diag([sigma_pos_deg**2, (sigma_pos_deg / ts) ** 2])


class KalmanVelocity:
    """Kalman filters of the three joints on [θ, θ̇] (deg, deg/s) with the model (28).

    Call :meth:`step` once per sample k with the reference applied during the
    previous interval θ*(k−1) and the position measured at k (or ``None`` when the
    bus read failed: prediction only).
    """

    @staticmethod
    def load() -> None:
        """Import the filters now (~1 s: filterpy loads scipy.stats), before anything runs in
        real time: a run builds its filters after torque-on, where an import would hold the
        interpreter for longer than the servos' Bus Watchdog allows."""
        import filterpy.kalman  # noqa: F401  # here: ~1 s to import, only a run needs it

    def __init__(
        self,
        model: ServoModel,
        theta0_deg: F,
        measurement_noise_deg: float,
        process_noise_deg: float,
        velocity0_std_degps: float = 1.0,
    ) -> None:
        from filterpy.kalman import KalmanFilter  # here: ~1 s to import (see load)

        self.model = model
        theta0 = np.asarray(theta0_deg, float).reshape(3)
        eye = np.eye(3)
        # one filter on the stacked state (θ1, θ̇1, θ2, θ̇2, θ3, θ̇3): every matrix is block
        # diagonal, so it is the three joints' filters exactly (the off-diagonal blocks stay
        # 0), in one filterpy call per step instead of three
        self._F = np.zeros((6, 6))
        self._B = np.zeros((6, 3))
        self._blocks(model.A, model.B)
        kf = KalmanFilter(dim_x=6, dim_z=3, dim_u=3)
        kf.F = self._F.copy()
        kf.B = self._B.copy()
        kf.H = np.kron(eye, np.array([[1.0, 0.0]]))
        kf.R = measurement_noise_deg**2 * eye
        kf.Q = self._q = np.kron(eye, process_noise(model.ts, process_noise_deg))
        kf.x = np.stack([theta0, np.zeros(3)], axis=1).reshape(6, 1)
        kf.P = np.kron(eye, np.diag([measurement_noise_deg**2, velocity0_std_degps**2]))
        self.filter: KalmanFilter = kf

    def _blocks(self, Phi: F, Gam: F) -> None:
        """Put one joint's transition (2, 2) and input (2,) on each joint's diagonal block."""
        gam = np.asarray(Gam, float).reshape(2)
        for i in range(3):
            j = 2 * i
            self._F[j:j + 2, j:j + 2] = Phi
            self._B[j:j + 2, i] = gam

    def step(self, reference_prev_deg: F, measured_deg: F | None) -> tuple[F, F]:
        """Ideal timing: predict over Ts with θ*(k−1), update with θ(k) measured at k·Ts."""
        self.filter.predict(u=np.asarray(reference_prev_deg, float).reshape(3, 1))
        if measured_deg is not None:
            self.filter.update(np.asarray(measured_deg, float).reshape(3, 1))
        return self.position_deg, self.velocity_degps

    def step_timed(self, spans: Sequence[tuple[float, F]], measured_deg: F | None
                   ) -> tuple[F, F]:
        """Actual timing: propagate exactly through ``spans`` = [(duration s, θ* held), …]
        from the last estimate's instant to the measurement's, then update with it.

        The state then lives at the measurement instant; process noise scales with the
        elapsed time (Q per Ts). Returns (θ̂, θ̇̂) there, deg and deg/s.
        """
        for dt, u in spans:
            if dt <= 0.0:
                continue
            Phi, Gam = exact_step(self.model.dynamics, dt)
            self._blocks(Phi, Gam)
            self.filter.predict(u=np.asarray(u, float).reshape(3, 1), B=self._B, F=self._F,
                                Q=self._q * (dt / self.model.ts))
        if measured_deg is not None:
            self.filter.update(np.asarray(measured_deg, float).reshape(3, 1))
        return self.position_deg, self.velocity_degps

    @property
    def position_deg(self) -> F:
        """Filtered positions θ̂ at the last estimate's instant (3,), deg."""
        return np.array(self.filter.x[0::2, 0], float)

    @property
    def velocity_degps(self) -> F:
        """Filtered velocities θ̇̂ at the last estimate's instant (3,), deg/s."""
        return np.array(self.filter.x[1::2, 0], float)

@dataclass
class FiniteDifference:
    """Backward difference (θ(k) − θ(k−1)) / Ts of the measured positions, deg/s.

    A failed read (``None``) spans the next difference over the missing samples.
    """

    ts: float
    """Sampling interval, s."""
    _last: F | None = None
    _t: float | None = None
    _gap: int = 1
    velocity_degps: F = field(default_factory=lambda: np.zeros(3))

    def step(self, measured_deg: F | None, t: float | None = None) -> F:
        """Difference with the last good measurement; over the actual time when ``t`` (s)
        of each measurement is given, else over the missed samples × Ts."""
        if measured_deg is None:
            self._gap += 1
            return self.velocity_degps
        z = np.asarray(measured_deg, float).reshape(3)
        if self._last is not None:
            dt = self._gap * self.ts
            if t is not None and self._t is not None and t > self._t:
                dt = t - self._t
            self.velocity_degps = (z - self._last) / dt
        self._last, self._t = z, t
        self._gap = 1
        return self.velocity_degps


class ModelPredictor:
    """Open-loop simulation of the model (28) under the references: the 'simulated' curves.

    Seeded at rest at the measured start position; :meth:`advance` applies θ*(k) for one
    ideal period, :meth:`propagate` follows the actual timing.
    """

    def __init__(self, model: ServoModel, theta0_deg: F) -> None:
        self.model = model
        self.x = np.zeros((2, 3))
        self.x[0] = np.asarray(theta0_deg, float).reshape(3)
        self._acting = self.x[0].copy()
        """The reference the servo acts on now (a delayed model): at rest, the start."""
        self._pending: list[tuple[float, F]] = []
        """References sent and not yet acting: (seconds until they act, θ*)."""

    @property
    def position_deg(self) -> F:
        return self.x[0].copy()

    @property
    def velocity_degps(self) -> F:
        return self.x[1].copy()

    def propagate(self, spans: Sequence[tuple[float, F]]) -> None:
        """Exact response of (27) through [(duration s, θ* held), …] (actual timing)."""
        if self.model.delay_s > 0.0:
            for dt, u in spans:
                self._delayed(dt, u)
            return
        for dt, u in spans:
            if dt > 0.0:
                Phi, Gam = exact_step(self.model.dynamics, dt)
                self.x = Phi @ self.x + np.outer(Gam, np.asarray(u, float).reshape(3))

    def advance(self, reference_deg: F) -> None:
        """x(k+1) = A x(k) + B θ*(k) for the three joints (with a delay d: the reference
        sent before acts for the first d of the period, this one for the rest)."""
        if self.model.delay_s > 0.0:
            self._delayed(self.model.ts, reference_deg)
            return
        ref = np.asarray(reference_deg, float).reshape(3)
        self.x = self.model.A @ self.x + np.outer(self.model.B, ref)

    def _delayed(self, dt: float, reference_deg: F) -> None:
        """``reference_deg`` sent now, held ``dt`` s: it acts from d after now (exact)."""
        self._pending.append((self.model.delay_s, np.asarray(reference_deg, float).reshape(3)))
        left = dt
        while left > 0.0:
            while self._pending and self._pending[0][0] <= 0.0:
                self._acting = self._pending.pop(0)[1]
            step = min(left, self._pending[0][0]) if self._pending else left
            Phi, Gam = exact_step(self.model.dynamics, step)
            self.x = Phi @ self.x + np.outer(Gam, self._acting)
            self._pending = [(w - step, u) for w, u in self._pending]
            left -= step

