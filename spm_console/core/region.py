"""Convex region P = {θ : A θ ≤ b} (θ in degrees), eq. (26)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]


@dataclass(frozen=True)
class Region:
    """A polytope in motor-angle space, θ in degrees (rows of A need not be normalized)."""

    A: F
    """(n, 3) half-space normals."""
    b: F
    """(n,) offsets."""

    @property
    def halfspaces(self) -> int:
        return int(self.A.shape[0])

    def slack(self, theta_deg: F) -> F:
        """b − A θ per half-space, in degrees of distance for unit-norm rows: (..., n)."""
        t = np.asarray(theta_deg, float)
        return np.asarray(self.b - t @ self.A.T)

    def contains(self, theta_deg: F, tol: float = 1e-9) -> NDArray[np.bool_]:
        """True where A θ ≤ b + tol (each point of (..., 3))."""
        return np.asarray((self.slack(theta_deg) >= -tol).all(-1))

    def violation_deg(self, theta_deg: F) -> F:
        """Largest Euclidean excursion outside any half-space (0 inside), deg: (...,)."""
        norms = np.linalg.norm(self.A, axis=1)
        return np.asarray(np.maximum(0.0, (-self.slack(theta_deg) / norms).max(-1)))

    @classmethod
    def box(cls, lo_deg: float, hi_deg: float) -> Region:
        """The cube lo ≤ θ_i ≤ hi."""
        A = np.vstack([np.eye(3), -np.eye(3)])
        b = np.concatenate([np.full(3, hi_deg), np.full(3, -lo_deg)])
        return cls(A, b)

    def to_dict(self) -> dict[str, list[list[float]] | list[float]]:
        return {"A": self.A.tolist(), "b": self.b.tolist()}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> Region:
        A = np.asarray(d["A"], float)
        b = np.asarray(d["b"], float)
        if A.ndim != 2 or A.shape[1] != 3 or b.shape != (A.shape[0],):
            raise ValueError(f"region: A must be (n, 3) and b (n,), got {A.shape} and {b.shape}")
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(b))):
            raise ValueError("region: A and b must be finite")
        return cls(A, b)
