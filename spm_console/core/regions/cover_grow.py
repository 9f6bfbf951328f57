"""Growing one region of the cover (IRIS in P's scaled frame), choosing its seed, and the
throttled progress reports of a cover build. Angles in degrees at this interface."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.ellipsoid import Ellipsoid, inscribed_ellipsoid
from spm_console.core.polytope.iris import Frame, reduce_halfspaces, separating_planes
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.errors import SolverError

F = NDArray[np.float64]
B = NDArray[np.bool_]
I64 = NDArray[np.int64]

#: Seeds are chosen by the uncovered nodes within this many grid steps (L∞) of them.
SEED_WINDOW = 2
#: Longest pause between two progress reports of a cover build, s (a cancel waits for one).
REPORT_EVERY_S = 0.1


@dataclass
class Grower:
    """IRIS for cover regions (fewer steps and rows than P), in P's scaled frame."""

    frame: Frame
    Q: F
    half: float | F
    max_halfspaces: int
    iters: int
    step_deg: float
    tick: Callable[[], None] | None = None
    """Called between the steps of a growth (progress; may raise to cancel)."""

    def _tick(self) -> None:
        if self.tick is not None:
            self.tick()

    def grow(self, seed_deg: F, objective_deg: F) -> Region:
        fr = self.frame
        req = fr.to_x(seed_deg).reshape(1, 3)
        Abox = np.vstack([np.eye(3), -np.eye(3)])
        E = Ellipsoid.ball(fr.to_x(seed_deg), self.step_deg / fr.s)
        best: Region | None = None
        best_n = -1
        for it in range(self.iters):
            Ap, bp = separating_planes(E, self.Q, self.half, req)
            self._tick()
            cand = fr.region(np.vstack([Abox, Ap]), np.r_[np.ones(6), bp]).without_redundant()
            n = int(cand.contains(objective_deg, tol=INSIDE_TOL_DEG).sum())
            self._tick()
            if n > best_n:
                best, best_n = cand, n
            if it + 1 < self.iters:
                try:
                    E = inscribed_ellipsoid(cand.A * fr.s, cand.b - cand.A @ fr.c)
                except SolverError:
                    break
        assert best is not None
        if best.halfspaces > self.max_halfspaces:
            best = reduce_halfspaces(best, fr, self.Q, self.half, req, self.max_halfspaces,
                                        objective_deg, tick=self.tick)
        return best


class Reporter:
    """progress(fraction) at most every :data:`REPORT_EVERY_S` (and always when forced)."""

    def __init__(self, progress: Callable[[float], None] | None) -> None:
        self.progress = progress
        self.last = time.perf_counter()

    def __call__(self, fraction: float, force: bool = False) -> None:
        now = time.perf_counter()
        if self.progress is not None and (force or now - self.last >= REPORT_EVERY_S):
            self.last = now
            self.progress(min(1.0, max(0.0, fraction)))


def dense_seed(f: B, fidx: I64, uncovered: B, candidates: B) -> int:
    """Index (into ``fidx``) of the candidate node with the most uncovered feasible nodes in
    the (2·:data:`SEED_WINDOW`+1)³ nodes around it. Equal counts are not always equal after
    the filter's floating-point sums (they can differ in the last bit), so which of two tied
    nodes wins is the round-off's choice, not C order (deterministic all the same)."""
    from scipy import ndimage  # here: only a build needs it (~0.4 s to import)

    g = np.zeros(f.shape, np.float64)
    g[tuple(fidx[uncovered].T)] = 1.0
    dens = ndimage.uniform_filter(g, size=2 * SEED_WINDOW + 1, mode="constant")
    score = np.where(candidates, dens[tuple(fidx.T)], -1.0)
    return int(np.argmax(score))


def deepest_seed(f: B, fidx: I64, candidates: B) -> int:
    """Index (into ``fidx``) of the candidate node deepest inside the candidate set (Euclidean
    distance transform on the grid; the box's faces do not count as its boundary); ties go to
    the first in C order."""
    from scipy import ndimage

    g = np.zeros(f.shape, bool)
    g[tuple(fidx[candidates].T)] = True
    d = ndimage.distance_transform_edt(g)
    return int(np.argmax(np.where(candidates, d[tuple(fidx.T)], -1.0)))
