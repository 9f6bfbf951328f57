"""Mass properties of the bodies that carry the wrist's mass: solid capsules of uniform density,
the same bodies and the same formula MuJoCo uses for the MJCF's capsules (a cylinder and two
hemispheres), so the URDF's inertias equal what the physical emulator simulates."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]


@dataclass(frozen=True)
class MassProperties:
    """Mass (kg), centre of mass (m, (3,)) and inertia about it (kg·m², (3, 3)), in the body's
    frame."""

    mass: float
    com: F
    inertia: F


def capsule(a: F, b: F, radius: float, mass: float) -> MassProperties:
    """A solid capsule from ``a`` to ``b`` (m) of ``radius`` (m) and ``mass`` (kg)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    v_cyl = math.pi * radius ** 2 * length
    v_sph = 4.0 / 3.0 * math.pi * radius ** 3
    m_cyl = mass * v_cyl / (v_cyl + v_sph)
    m_sph = mass - m_cyl
    axial = m_cyl * radius ** 2 / 2.0 + m_sph * 2.0 / 5.0 * radius ** 2
    # each hemisphere: (2/5)(m/2)r² about a diameter of its flat face, shifted to the middle
    # (its centre of mass lies 3r/8 beyond the face)
    transverse = (m_cyl * (length ** 2 / 12.0 + radius ** 2 / 4.0)
                  + m_sph * (2.0 / 5.0 * radius ** 2 + length ** 2 / 4.0 + 3.0 * radius * length / 8.0))
    zz = np.outer(z, z)
    inertia = transverse * (np.eye(3) - zz) + axial * zz
    return MassProperties(mass, (a + b) / 2.0, inertia)


def combined(parts: Sequence[MassProperties]) -> MassProperties:
    """One body made of ``parts`` (parallel-axis theorem)."""
    mass = sum(p.mass for p in parts)
    com = sum((p.mass * p.com for p in parts), np.zeros(3)) / mass
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.com - com
        inertia += p.inertia + p.mass * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return MassProperties(mass, com, inertia)
