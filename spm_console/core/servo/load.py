"""The servo under load: its model driven by the reference less the drive's offset.

A position servo holding a load settles where its drive's torque balances it: with a
proportional drive of stiffness K, θ = θ* − τ/K at rest. So the model (27)-(28) is driven by
θ* − d(θ, θ̇) rather than θ*, with d (deg) the offset the load costs:

* the wrist's weight, d_grav = Y(θ)·m: Y the regressor of the bodies' weight (from the
  kinematics; :mod:`spm_console.core.kinematics.loads`) and m its parameters. A profile holds
  one column, the torque that holds the weight from ``[plant]``'s masses (N·m), so m is one
  number, k in deg/(N·m): the inverse of the drive's stiffness, times the mass model's error;
* Coulomb friction in the gear, d_fric,j = c·tanh(θ̇_j / v_s): it opposes the motion (a
  smooth sign, so the reference stays smooth through a reversal; 0 at rest, where the
  friction takes any value within ±c).

Given the load's offset along a motion, sending θ* + d makes the loaded servo follow the model
of θ* (the compensation the runtime applies). :mod:`.load_fit` identifies m and c together
with the model's ωn, ζ and delay.

Pure: the regressor's values come from the caller. Degrees, deg/s, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]

SMOOTH_DEGPS = 2.0
"""Speed v_s at which the friction offset reaches tanh(1) = 76 % of c, deg/s (about a tick
per 20 ms period: below, the encoder cannot tell motion from rest)."""


@dataclass(frozen=True)
class LoadModel:
    """The offset d the servos' load costs, deg: d = Y(θ)·m + c·tanh(θ̇/v_s)."""

    moments_deg: F
    """(P,) the weight's parameters, deg per unit of the regressor's columns (the profile's
    one column is N·m of holding torque: deg/(N·m))."""
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
