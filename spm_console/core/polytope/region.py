"""Convex region P = {θ : A θ ≤ b} (θ in degrees), eq. (26)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.lp import solve_lp

F = NDArray[np.float64]

#: Smallest slack (relative to the point's size) of a hint used as qhull's interior point.
INTERIOR_MARGIN = 1e-4
#: A point lies in a region when it violates no half-space by more than this, deg (rows of
#: unit norm: the slack is a distance). Points computed to lie *on* a face — an IRIS plane
#: turned to pass through a required end, a vertex, a grid node on a cube's face — miss it by
#: rounding (about 1e-12° at θ ≈ 300°), so the test needs a margin far above that; 1e-7° is
#: also far below anything the wrist can tell apart (a servo tick is 0.088°), so no point
#: counted inside is measurably outside.
INSIDE_TOL_DEG = 1e-7
#: Points per block of the membership tests: the (points × half-spaces) slacks of one block
#: stay in the cache. The whole 2° grid's feasible nodes at once made a 26 MB array whose
#: fresh pages cost 4–12× the arithmetic.
BLOCK_POINTS = 4096


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

    def contains(self, theta_deg: F, tol: float = INSIDE_TOL_DEG) -> NDArray[np.bool_]:
        """True where A θ ≤ b + tol (each point of (..., 3)); ``tol``: :data:`INSIDE_TOL_DEG`
        (a negative one asks for a point that far inside)."""
        return np.asarray(self._per_point(theta_deg, lambda s: np.asarray((s >= -tol).all(-1)),
                                          bool), bool)

    def violation_deg(self, theta_deg: F) -> F:
        """Largest Euclidean excursion outside any half-space (0 inside), deg: (...,)."""
        norms = np.linalg.norm(self.A, axis=1)
        return np.asarray(self._per_point(
            theta_deg, lambda s: np.asarray(np.maximum(0.0, (-s / norms).max(-1))), float), float)

    def _per_point(self, theta_deg: F, reduce: Callable[[F], NDArray[Any]],
                   dtype: type) -> NDArray[Any]:
        """``reduce(slacks)`` → one value per point of (..., 3), in blocks of
        :data:`BLOCK_POINTS` points (each point's slacks are the same as :meth:`slack`'s)."""
        t = np.asarray(theta_deg, float)
        if t.size <= 3 * BLOCK_POINTS:
            return np.asarray(reduce(self.slack(t)))
        flat = t.reshape(-1, 3)
        out: NDArray[Any] = np.empty(len(flat), dtype)
        for s in range(0, len(flat), BLOCK_POINTS):
            out[s:s + BLOCK_POINTS] = reduce(self.slack(flat[s:s + BLOCK_POINTS]))
        return out.reshape(t.shape[:-1])

    @classmethod
    def box(cls, lo_deg: float, hi_deg: float) -> Region:
        """The cube lo ≤ θ_i ≤ hi."""
        A = np.vstack([np.eye(3), -np.eye(3)])
        b = np.concatenate([np.full(3, hi_deg), np.full(3, -lo_deg)])
        return cls(A, b)

    def tightened(self, margin_deg: float, keep_deg: F | None = None) -> Region:
        """Every face moved ``margin_deg`` inwards (a tube: a motion inside it that is off by
        at most the margin stays inside this region), except as far as it would shut out a
        point of ``keep_deg`` ((M, 3), e.g. a plan's start and goal): a face is moved by
        min(margin, the point's distance to it) and never past where the points lie."""
        n = np.linalg.norm(self.A, axis=1)
        move = np.full(self.halfspaces, float(margin_deg))
        if keep_deg is not None:
            room = (self.slack(np.atleast_2d(np.asarray(keep_deg, float))) / n).min(axis=0)
            move = np.minimum(move, np.maximum(room, 0.0))
        return Region(self.A.copy(), self.b - move * n)

    def normalized(self) -> Region:
        """The same polytope with unit-norm rows (slack then reads in degrees)."""
        n = np.linalg.norm(self.A, axis=1)
        return Region(self.A / n[:, None], self.b / n)

    def chebyshev(self) -> tuple[F, float]:
        """Centre and radius (deg) of the largest ball inside (LP); radius < 0 if empty."""

        n = np.linalg.norm(self.A, axis=1)
        A_ub = np.hstack([self.A, n[:, None]])
        res = solve_lp(np.r_[0.0, 0.0, 0.0, -1.0], A_ub, self.b)
        if res.status != 0:
            return np.full(3, np.nan), -1.0
        return np.asarray(res.x[:3]), float(res.x[3])

    def redundant_rows(self, tol: float = 1e-7) -> list[int]:
        """Rows that can be removed without changing the polytope (one LP per row,
        removed one at a time so duplicated rows keep one copy)."""
        from scipy.optimize import linprog

        keep = list(range(self.halfspaces))
        out = []
        for k in range(self.halfspaces):
            others = [j for j in keep if j != k]
            # maximize a_k θ over the others, capped just above b_k to stay bounded
            A_ub = np.vstack([self.A[others], self.A[k]])
            b_ub = np.r_[self.b[others], self.b[k] + 1.0]
            res = linprog(-self.A[k], A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 3,
                          method="highs")
            if res.status == 0 and -res.fun <= self.b[k] + tol * np.linalg.norm(self.A[k]):
                out.append(k)
                keep.remove(k)
        return out

    def facet_rows(self, tol: float = 1e-7, interior: F | None = None) -> list[int]:
        """Rows that define a facet (2-D face) of the bounded, full-dimensional polytope,
        one row per facet: found from the vertices (qhull), no LP. A row is redundant
        exactly when it defines no facet. ``interior``: see :meth:`vertices`. A polytope too
        thin for qhull to find its vertices keeps every row (as a flat one does)."""
        V = self._solid_vertices(interior)
        if len(V) < 4:
            return list(range(self.halfspaces))
        n = np.linalg.norm(self.A, axis=1)
        An, bn = self.A / n[:, None], self.b / n
        scale = max(1.0, float(np.abs(V).max()))
        tight = np.abs(V @ An.T - bn) <= tol * scale  # (n_vertices, n_rows)
        # a row defines a facet when its tight vertices span a plane: the second singular
        # value of the centred vertices, from the eigenvalues of their scatter matrices
        cnt = tight.sum(0)
        mean = (tight.T @ V) / np.maximum(cnt, 1)[:, None]
        D = (V[None, :, :] - mean[:, None, :]) * tight.T[:, :, None]
        ev = np.linalg.eigvalsh(np.einsum("kvi,kvj->kij", D, D))  # ascending
        sv1 = np.sqrt(np.maximum(ev[:, 1], 0.0))
        cand = np.flatnonzero((cnt >= 3) & (sv1 > 1e3 * tol * scale))
        # copies: rows equal within 1e-9 (normal) and 1e-9·scale (offset); keep the first
        same = ((np.abs(An[cand][:, None, :] - An[cand][None, :, :]).max(-1) < 1e-9)
                & (np.abs(bn[cand][:, None] - bn[cand][None, :]) < 1e-9 * scale))
        earlier = np.tril(same, -1).any(1)
        if not earlier.any():
            return [int(k) for k in cand]
        out: list[int] = []
        kept: list[int] = []  # positions in cand
        for p, k in enumerate(cand):
            if earlier[p] and same[p, kept].any():
                continue  # a copy of a row kept already
            out.append(int(k))
            kept.append(p)
        return out

    def without_redundant(self, tol: float = 1e-7, method: str = "vertices",
                          interior: F | None = None) -> Region:
        """The polytope with every redundant half-space removed.

        ``method="vertices"`` keeps the facet-defining rows (qhull, fast; ``interior``: see
        :meth:`vertices`); ``"lp"`` solves one LP per row (slow, independent check)."""
        if method == "lp":
            drop = set(self.redundant_rows(tol))
            keep = [k for k in range(self.halfspaces) if k not in drop]
        else:
            keep = self.facet_rows(tol, interior)
        return Region(self.A[keep], self.b[keep])

    def interior_point(self, hint: F | None = None) -> F | None:
        """A point well inside the polytope: ``hint`` when every row's (normalized) slack
        there is at least :data:`INTERIOR_MARGIN` (relative to the point's size), else the
        Chebyshev centre (an LP); None when the polytope has no interior."""
        if hint is not None:
            h = np.asarray(hint, float).reshape(3)
            n = np.linalg.norm(self.A, axis=1)
            if np.all(np.isfinite(h)) and float(((self.b - self.A @ h) / n).min()) >= \
                    INTERIOR_MARGIN * max(1.0, float(np.abs(h).max())):
                return h
        c, r = self.chebyshev()
        return c if r > 0 else None

    def vertices(self, interior: F | None = None) -> F:
        """Vertices (n, 3) of the bounded polytope, deg (qhull, around
        :meth:`interior_point` of ``interior``: a known inner point saves its LP)."""
        from scipy.spatial import HalfspaceIntersection  # here: ~0.2 s to import

        c = self.interior_point(interior)
        if c is None:
            return np.zeros((0, 3))
        hs = HalfspaceIntersection(np.hstack([self.A, -self.b[:, None]]), c)
        return np.asarray(hs.intersections)

    def _solid_vertices(self, interior: F | None = None) -> F:
        """:meth:`vertices`, or none (0, 3) when qhull cannot intersect the half-spaces: a
        polytope too thin to tell an inner point from its faces counts as flat."""
        from scipy.spatial import QhullError

        try:
            with np.errstate(divide="ignore", invalid="ignore"):
                V = self.vertices(interior)
        except QhullError:
            return np.zeros((0, 3))
        return V if np.isfinite(V).all() else np.zeros((0, 3))

    def volume(self) -> float:
        """Volume of the bounded polytope, deg³ (0 if empty or flat, also when it is too
        thin for qhull to tell an inner point from the boundary)."""
        from scipy.spatial import ConvexHull, QhullError

        V = self._solid_vertices()
        if len(V) < 4:
            return 0.0
        try:
            return float(ConvexHull(V).volume)
        except QhullError:  # the vertices are coplanar
            return 0.0

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
