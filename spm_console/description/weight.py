"""The torque the motors give to hold the wrist's weight, from the profile's mass model.

The bodies' first moments of mass come from the same capsules as the MJCF and URDF
(``[plant]``'s link and platform masses), the platform's with the payload's first moment
(``[plant] payload_moment_kgmm``, which commissioning fits) added; the regressor from the kinematics
(:mod:`spm_console.core.kinematics.loads`). Gravity in the base's frame is the profile's
(``[plant] base_tilt_deg``: level, the base's z axis up, unless it names a tilt), as in the
emulated wrist. Degrees at the interface, N·m.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.loads import (
    BODIES,
    GRAVITY_MPS2,
    gravity_regressor,
    path_rotations,
)
from spm_console.core.kinematics.model import SpmModel
from spm_console.description import names
from spm_console.description.mjcf import PlantParams, base_rotation, body_capsules, plant_params

F = NDArray[np.float64]

UP = np.array([0.0, 0.0, 1.0])
"""Against gravity, in the frame of a level base."""
#: The platform's three entries among the bodies' first moments (:data:`BODIES` order).
PLATFORM = slice(3 * BODIES.index("platform"), 3 * BODIES.index("platform") + 3)
_NAMES = (*(names.proximal_link(i) for i in range(3)), *(names.distal_link(i) for i in range(3)),
          names.PLATFORM)
"""The MJCF's bodies in :data:`BODIES` order."""


def first_moments(model: SpmModel, params: PlantParams) -> F:
    """Σ m·c of each body's capsules at home (kg·m), in :data:`BODIES` order, flattened (21,)."""
    caps = body_capsules(model, params)
    assert len(_NAMES) == len(BODIES)
    return np.concatenate([sum((c.mass_kg * 0.5 * (c.a + c.b) for c in caps[name]),
                               np.zeros(3)) for name in _NAMES])


@dataclass(frozen=True)
class Weight:
    """The wrist's weight as the motors feel it: its kinematics and the bodies' first
    moments."""

    model: SpmModel
    moments_kgm: F
    """(21,) first moments of the bodies at home, kg·m (:func:`first_moments`)."""
    up: F = field(default_factory=lambda: UP.copy())
    """(3,) unit vector against gravity in the base's frame (:func:`base_up`)."""

    @classmethod
    def of(cls, profile: Profile, payload: bool = True) -> Weight:
        """The profile's wrist; with its payload's first moment unless ``payload`` is False
        (the bodies alone)."""
        model = model_of(profile)
        moments = first_moments(model, plant_params(profile.plant))
        if payload:
            moments[PLATFORM] += payload_moment_kgm(profile)
        return cls(model, moments, base_up(profile.plant.base_tilt_deg))

    def torque_nm(self, theta_rad: F, R: F) -> F:
        """∂U/∂θ (n, 3), N·m, at poses θ (n, 3) rad with platform rotations R (n, 3, 3)."""
        Y = gravity_regressor(self.model, theta_rad, R, self.up)
        return np.asarray(GRAVITY_MPS2 * Y @ self.moments_kgm, float)

    def along(self, theta_deg: F) -> F:
        """∂U/∂θ (n, 3), N·m, along a path from home through the rows of ``theta_deg``
        (n, 3) in turn (its FK by continuation). Raises ValueError where the path meets a
        singularity."""
        th = np.radians(np.asarray(theta_deg, float).reshape(-1, 3))
        return self.torque_nm(th, path_rotations(self.model, th))


def base_up(tilt_deg: tuple[float, float]) -> F:
    """(3,) against gravity in the frame of a base tilted by ``tilt_deg`` (``[plant]
    base_tilt_deg``): R_tiltᵀ·e_z."""
    return np.asarray(base_rotation(tilt_deg).T @ UP, float)


def payload_moment_kgm(profile: Profile) -> F:
    """The payload's first moment m·c (3,), kg·m, in the platform's frame at home (zero
    without one)."""
    m = profile.plant.payload_moment_kgmm
    return np.zeros(3) if m is None else np.asarray(m, float) * 1e-3


def holding_torque_nm(profile: Profile, theta_deg: F) -> F:
    """∂U/∂θ (n, 3), N·m: what each motor gives to hold the weight at the rows of
    ``theta_deg`` (n, 3), a path from home through the rows in turn (:meth:`Weight.along`).
    Raises ValueError where the path meets a singularity."""
    return Weight.of(profile).along(theta_deg)
