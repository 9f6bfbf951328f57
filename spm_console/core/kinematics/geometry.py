"""SPM geometry: base axes u_i (1), intermediate axes w_i(θ) (2), α3 (6).

Conventions: radians inside; vectors are stacked as (..., 3 legs, 3 xyz);
θ has shape (..., 3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]


@dataclass(frozen=True)
class SpmGeometry:
    """Constant geometric model of one SPM (all angles in radians)."""

    alpha1: float
    """Proximal arc α1, rad."""
    alpha2: float
    """Distal arc α2, rad."""
    beta: float
    """Top pyramid angle β, rad."""
    gamma: float
    """Base pyramid angle γ, rad."""
    eta: tuple[float, float, float]
    """Leg azimuths η_i, rad."""
    d_alpha1: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Per-leg deviation of the proximal arc from α1 (a wrist as built), rad: leg i's arc is
    α1 + d_alpha1[i]. Zero for the paper's symmetric SPM."""
    d_alpha2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Per-leg deviation of the distal arc from α2, rad (leg i's: α2 + d_alpha2[i])."""

    @classmethod
    def from_degrees(
        cls,
        alpha1_deg: float,
        alpha2_deg: float,
        beta_deg: float,
        gamma_deg: float,
        eta_deg: tuple[float, float, float] = (0.0, 120.0, 240.0),
        d_alpha1_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
        d_alpha2_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> SpmGeometry:
        r = math.radians
        return cls(
            r(alpha1_deg), r(alpha2_deg), r(beta_deg), r(gamma_deg),
            (r(eta_deg[0]), r(eta_deg[1]), r(eta_deg[2])),
            (r(d_alpha1_deg[0]), r(d_alpha1_deg[1]), r(d_alpha1_deg[2])),
            (r(d_alpha2_deg[0]), r(d_alpha2_deg[1]), r(d_alpha2_deg[2])),
        )

    @property
    def alpha3(self) -> float:
        """Angle between top axes v_i, v_j: eq. (6), rad."""
        return 2.0 * math.asin(math.sin(self.beta) * math.cos(math.pi / 6.0))

    @property
    def symmetric(self) -> bool:
        """Whether the three legs' arcs are equal (no per-leg deviation)."""
        return not any(self.d_alpha1) and not any(self.d_alpha2)

    @property
    def alpha1_legs(self) -> F:
        """Each leg's proximal arc, rad: (3,)."""
        return np.array([self.alpha1 + d for d in self.d_alpha1])

    @property
    def alpha2_legs(self) -> F:
        """Each leg's distal arc, rad: (3,)."""
        return np.array([self.alpha2 + d for d in self.d_alpha2])

    @property
    def cos_alpha2(self) -> F:
        """cos of each leg's distal arc: (3,), broadcast over the legs' axis of (4)."""
        return np.array([math.cos(self.alpha2 + d) for d in self.d_alpha2])

    @property
    def cos_alpha3(self) -> float:
        return math.cos(self.alpha3)

    @property
    def u(self) -> F:
        """Base joint axes u_i, eq. (1): (3, 3), rows u1..u3."""
        e = np.asarray(self.eta)
        sg, cg = math.sin(self.gamma), math.cos(self.gamma)
        return np.stack([np.sin(e) * sg, np.cos(e) * sg, -cg * np.ones(3)], -1)

    def _coeffs(self) -> tuple[F, F, F]:
        """w_i(θ) = P_i + Q_i cos θ_i + S_i sin θ_i (from eq. 2); each (3, 3)."""
        e = np.asarray(self.eta)
        se, ce = np.sin(e), np.cos(e)
        sg, cg = math.sin(self.gamma), math.cos(self.gamma)
        # each leg's arc (math.sin per leg: the symmetric wrist's figures are unchanged)
        sa = np.array([math.sin(self.alpha1 + d) for d in self.d_alpha1])
        ca = np.array([math.cos(self.alpha1 + d) for d in self.d_alpha1])
        P = np.stack([se * sg * ca, ce * sg * ca, -cg * ca], -1)
        Q = np.stack([se * cg * sa, ce * cg * sa, sg * sa], -1)
        S = np.stack([-ce * sa, se * sa, np.zeros(3)], -1)
        return P, Q, S

    def w(self, theta: F) -> F:
        """Intermediate axes w_i(θ_i), eq. (2). θ (..., 3) rad -> (..., 3, 3)."""
        P, Q, S = self._coeffs()
        t = np.asarray(theta, float)[..., :, None]
        return P + Q * np.cos(t) + S * np.sin(t)

    def ik_coeffs(self) -> tuple[F, F, F]:
        """Coefficients P, Q, S of w_i(θ) (see :meth:`_coeffs`)."""
        return self._coeffs()

    def canonical_triad(self) -> F:
        """A reference triad of top axes with pairwise angle α3: (3, 3), rows v1..v3."""
        e = np.asarray(self.eta)
        sb, cb = math.sin(self.beta), math.cos(self.beta)
        return np.stack([np.sin(e) * sb, np.cos(e) * sb, cb * np.ones(3)], -1)
