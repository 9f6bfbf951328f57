"""Link segment model (18)-(23) and closed-form segment-segment distances (QP 24).

Lengths in mm. Points are stacked (..., 3 legs, 3 xyz). A pair of segments of
different legs collides when their distance is below 2δ (paper Sec. IV-B).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations, product

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]

SEGMENT_ENDS = {"AB": ("A", "B"), "BC": ("B", "C"), "DE": ("D", "E"), "EF": ("E", "F")}


def _unit(x: F) -> F:
    return np.asarray(x / np.linalg.norm(x, axis=-1, keepdims=True))


@dataclass(frozen=True)
class LinkModel:
    """Radii of the points A..F (mm), capsule radius δ (mm) and the segments checked."""

    oa: float
    ob: float
    oc: float
    od: float
    oe: float
    of: float
    delta: float
    segments: tuple[str, ...]

    def points(self, u: F, w: F, v: F) -> dict[str, F]:
        """Points A..F of every leg, eqs. (18)-(23): each (..., 3, 3), mm."""
        uu = np.broadcast_to(u, w.shape)
        return {
            "A": uu * self.oa,
            "B": _unit(uu + w) * self.ob,
            "C": w * self.oc,
            "D": w * self.od,
            "E": _unit(v + w) * self.oe,
            "F": v * self.of,
        }

    def pairs(self) -> list[tuple[int, str, int, str]]:
        """(leg i, segment, leg j, segment) for every checked pair of different legs."""
        return [
            (i, s1, j, s2)
            for i, j in combinations(range(3), 2)
            for s1, s2 in product(self.segments, self.segments)
        ]

    def pair_distances(self, u: F, w: F, v: F) -> F:
        """Distance of every checked segment pair: (..., n_pairs), mm."""
        pts = self.points(u, w, v)
        segs = [(i, s) for i in range(3) for s in self.segments]
        col = {key: k for k, key in enumerate(segs)}
        pairs = self.pairs()
        c1 = np.array([col[(i, s1)] for i, s1, _, _ in pairs], np.intp)
        c2 = np.array([col[(j, s2)] for _, _, j, s2 in pairs], np.intp)
        # per segment (..., n_segments), per axis: its start and its direction
        start = [np.stack([pts[SEGMENT_ENDS[s][0]][..., i, a] for i, s in segs], -1)
                 for a in range(3)]
        along = [np.stack([pts[SEGMENT_ENDS[s][1]][..., i, a] for i, s in segs], -1) - start[a]
                 for a in range(3)]
        length2 = _dot(along, along)
        return _segment_distance_xyz(
            [x[..., c1] for x in start], [x[..., c1] for x in along], length2[..., c1],
            [x[..., c2] for x in start], [x[..., c2] for x in along], length2[..., c2], 1e-12)

    def apart(self, u: F, w: list[list[F]], v: list[list[F]], dist_mm: float) -> NDArray[np.bool_]:
        """(n,) True where every checked pair is at least ``dist_mm`` apart: the verdict
        :meth:`pair_distances` ``.min(-1) >= dist_mm``, per component (``w[i][a]``, ``v[i][a]``:
        (n,) arrays, leg i, axis a; u (3, 3)). The exact distance is computed only for pairs
        whose bounding spheres (centred on each segment's midpoint) are closer than that."""
        seg: dict[tuple[int, str], tuple[list[F], list[F]]] = {}
        for i in range(3):
            wi, vi, ui = w[i], v[i], [float(x) for x in u[i]]
            uw = [ui[a] + wi[a] for a in range(3)]
            k = self.ob / np.sqrt(uw[0] * uw[0] + uw[1] * uw[1] + uw[2] * uw[2])
            vw = [vi[a] + wi[a] for a in range(3)]
            m = self.oe / np.sqrt(vw[0] * vw[0] + vw[1] * vw[1] + vw[2] * vw[2])
            pts = {"A": [np.full(wi[a].shape, ui[a] * self.oa) for a in range(3)],
                   "B": [uw[a] * k for a in range(3)], "C": [wi[a] * self.oc for a in range(3)],
                   "D": [wi[a] * self.od for a in range(3)], "E": [vw[a] * m for a in range(3)],
                   "F": [vi[a] * self.of for a in range(3)]}
            for s in self.segments:
                seg[(i, s)] = (pts[SEGMENT_ENDS[s][0]], pts[SEGMENT_ENDS[s][1]])
        mid = {key: [0.5 * (p[a] + q[a]) for a in range(3)] for key, (p, q) in seg.items()}
        rad = {key: 0.5 * np.sqrt(sum((q[a] - p[a]) ** 2 for a in range(3)))
               for key, (p, q) in seg.items()}
        ok = np.ones(len(w[0][0]), bool)
        for i, s1, j, s2 in self.pairs():
            m1, m2 = mid[(i, s1)], mid[(j, s2)]
            d2 = sum((m1[a] - m2[a]) ** 2 for a in range(3))
            reach = rad[(i, s1)] + rad[(j, s2)] + dist_mm
            close = np.flatnonzero(ok & (d2 < reach * reach))
            if len(close):
                (p1, q1), (p2, q2) = seg[(i, s1)], seg[(j, s2)]
                e = [np.stack([x[a][close] for a in range(3)], -1) for x in (p1, q1, p2, q2)]
                d = segment_distance(e[0], e[1], e[2], e[3])
                ok[close] = d >= dist_mm
        return ok

    def min_distance(self, u: F, w: F, v: F) -> tuple[F, NDArray[np.int64]]:
        """Closest inter-leg link distance (mm) and the index of that pair in :meth:`pairs`."""
        d = self.pair_distances(u, w, v)
        return d.min(-1), np.argmin(d, -1)


def segment_distance(p1: F, q1: F, p2: F, q2: F, eps: float = 1e-12) -> F:
    """Exact minimum distance between segments [p1, q1] and [p2, q2] (..., 3) -> (...).

    Minimizes ‖(p1 + s d1) − (p2 + t d2)‖ over s, t ∈ [0, 1] in closed form,
    handling zero-length and parallel segments (the QP (24) without a solver).
    """
    start1 = [p1[..., k] for k in range(3)]
    start2 = [p2[..., k] for k in range(3)]
    d1 = [q1[..., k] - start1[k] for k in range(3)]
    d2 = [q2[..., k] - start2[k] for k in range(3)]
    return _segment_distance_xyz(start1, d1, _dot(d1, d1), start2, d2, _dot(d2, d2), eps)


def _dot(x: list[F], y: list[F]) -> F:
    """x·y of vectors given per axis (three arrays of one shape)."""
    return np.asarray(x[0] * y[0] + x[1] * y[1] + x[2] * y[2])


def _segment_distance_xyz(p1: list[F], d1: list[F], a: F, p2: list[F], d2: list[F], e: F,
                          eps: float) -> F:
    """:func:`segment_distance` of the segments p1 + s·d1 and p2 + t·d2, given per axis
    (three arrays of one shape each; a = ‖d1‖², e = ‖d2‖²): the products stay elementwise on
    contiguous arrays."""
    r = [p1[k] - p2[k] for k in range(3)]
    f, c, b = _dot(d2, r), _dot(d1, r), _dot(d1, d2)
    a_pt, e_pt = a <= eps, e <= eps
    a_s = np.where(a_pt, 1.0, a)
    e_s = np.where(e_pt, 1.0, e)
    denom = a * e - b * b
    par = denom <= eps * np.maximum(a * e, eps)
    s = np.where(par, 0.0, np.clip((b * f - c * e) / np.where(par, 1.0, denom), 0.0, 1.0))
    t = (b * s + f) / e_s
    lo, hi = t < 0.0, t > 1.0
    s = np.where(lo, np.clip(-c / a_s, 0.0, 1.0), np.where(hi, np.clip((b - c) / a_s, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate segments
    s = np.where(a_pt, 0.0, np.where(e_pt, np.clip(-c / a_s, 0.0, 1.0), s))
    t = np.where(a_pt, np.where(e_pt, 0.0, np.clip(f / e_s, 0.0, 1.0)), np.where(e_pt, 0.0, t))
    diff = [(r[k] + s * d1[k]) - t * d2[k] for k in range(3)]
    return np.asarray(np.sqrt(_dot(diff, diff)))
