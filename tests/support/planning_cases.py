"""Hand-made regions and hard cases shared by the planning tests (θ in degrees).

The regions are built so that the paper's start/goal configurations lie inside (some on
faces), with a thin slab variant whose faces bind once a joint's references are limited.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import discretize

MODEL = discretize(32.22, 0.02)
START = np.array([127.53, 83.23, 85.25])  # paper MVN experiment
GOAL = np.array([66.80, 155.00, 131.48])
START_MT = np.array([70.0, 90.0, 80.0])  # paper minimum-time experiment


def polytope(seed: int = 0, planes: int = 55) -> Region:
    """Box 65..155° and random slanted planes; the first six touch a paper configuration."""
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(planes, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    pts = np.array([START, GOAL, START_MT])
    b = (n @ pts.T).max(1) + rng.uniform(0.0, 20.0, planes)
    b[:6] = (n[:6] @ pts.T).max(1)
    box = Region.box(65.0, 155.0)
    return Region(np.vstack([box.A, n]), np.concatenate([box.b, b]))


def slab(a: np.ndarray, c: np.ndarray, half_width: float, seed: int = 0) -> Region:
    """:func:`polytope` cut to a square tube of half-width ``half_width`` around segment a→c."""
    base = polytope(seed)
    d = (c - a) / np.linalg.norm(c - a)
    e1 = np.cross(d, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    w = half_width
    return Region(np.vstack([base.A, e1, -e1, e2, -e2]),
                  np.concatenate([base.b, [e1 @ a + w, -e1 @ a + w, e2 @ a + w, -e2 @ a + w]]))


@dataclass(frozen=True)
class Case:
    name: str
    region: Region
    N: int
    vmax: float | None = None
    K: int = 1
    ref_hi2: float | None = None
    """Upper bound on joint 2's references (the goal is at 155°: this makes them bind)."""

    def limits(self) -> dict[str, np.ndarray]:
        if self.ref_hi2 is None:
            return {}
        return {"ref_lo_deg": np.full(3, 60.0), "ref_hi_deg": np.array([160.0, self.ref_hi2, 160.0])}


HARD_CASES = [
    Case("paper-polytope", polytope(), 150),
    Case("paper-vmax-inactive", polytope(), 150, vmax=60.0, K=4),
    Case("ref-bound", polytope(), 150, ref_hi2=155.3),
    Case("slab0.5-ref-bound-N80", slab(START, GOAL, 0.5), 80, ref_hi2=155.05),
    Case("slab0.1-K4-ref-bound", slab(START, GOAL, 0.1), 150, K=4, ref_hi2=155.05),
    Case("slab0.02-K4-ref-bound-N80", slab(START, GOAL, 0.02), 80, K=4, ref_hi2=155.3),
]
