"""IRIS geometry (Deits & Tedrake 2015) against open axis-aligned cubes (obstacles).

Separating planes in the metric of an ellipsoid, planes that keep required points, and the
greedy reduction of a polytope to a half-space cap. Obstacles are open cubes given by
centres and half-widths (one shared half-width, or one per cube: a grid node's cube of
half-width Δ next to a fine node's cube of half-width h). Works in scaled coordinates
x = (θ − centre) / half-range (:class:`Frame`); degrees where a docstring says so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.ellipsoid import Ellipsoid
from spm_console.core.polytope.lp import solve_lp
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.errors import InfeasibleError

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: Cubes whose closest points :func:`separating_planes` computes at a time (in lower-bound order).
SEPARATION_BATCH = 512
#: Candidate minimizers per box in :func:`closest_on_boxes`: the centre, 6 faces, 12 edges.
_CANDIDATES = 19


def half_widths(half: float | F, n: int) -> F:
    """Per-obstacle half-widths (n,) from one shared value or an array."""
    return np.asarray(np.broadcast_to(np.asarray(half, float), (n,)), float)


@dataclass(frozen=True)
class Frame:
    """Scaling θ (deg) ↔ x = (θ − c) / s."""

    c: F
    s: float

    def to_x(self, theta: F) -> F:
        return np.asarray((np.asarray(theta, float) - self.c) / self.s)

    def region(self, A: F, b: F) -> Region:
        """Rows a·x ≤ b  →  (a/s)·θ ≤ b + a·c/s, normalized."""
        return Region(A / self.s, b + A @ self.c / self.s).normalized()


def closest_on_boxes(M: F, c: F, lo: F, hi: F) -> tuple[F, F]:
    """argmin and min of (x − c)ᵀ M (x − c) over each box [lo_k, hi_k] (k rows of (n, 3)).

    Exact: the minimizer is the centre (if inside) or lies in the relative interior
    of a face, an edge or at a vertex; every face's unconstrained minimizer and every edge's clipped
    minimizer is a candidate, the best feasible one wins (vertices are covered by
    the clipped edges; ties go to the first candidate in that order). The 19 candidates of
    every box are evaluated together.
    """
    n = len(lo)
    bounds = (lo, hi)
    pts = np.empty((_CANDIDATES, n, 3))
    pts[0] = c  # the centre
    m = 1
    for k in range(3):  # faces x_k = const: x_f = c_f − (x_k − c_k) M_ff⁻¹ M_fk
        p, q = (i for i in range(3) if i != k)
        det = M[p, p] * M[q, q] - M[p, q] * M[q, p]
        gp = (M[q, q] * M[p, k] - M[p, q] * M[q, k]) / det
        gq = (M[p, p] * M[q, k] - M[q, p] * M[p, k]) / det
        for s in (0, 1):
            xk = bounds[s][:, k]
            dk = xk - c[k]
            pts[m, :, k] = xk
            pts[m, :, p] = c[p] - gp * dk
            pts[m, :, q] = c[q] - gq * dk
            m += 1
    for i in range(3):  # edges along x_i
        j, k = (q for q in range(3) if q != i)
        for s1 in (0, 1):
            for s2 in (0, 1):
                xj, xk = bounds[s1][:, j], bounds[s2][:, k]
                pts[m, :, j] = xj
                pts[m, :, k] = xk
                xi = c[i] - (M[i, j] * (xj - c[j]) + M[i, k] * (xk - c[k])) / M[i, i]
                np.minimum(np.maximum(xi, lo[:, i]), hi[:, i], out=pts[m, :, i])
                m += 1
    lo_t, hi_t = lo - 1e-12, hi + 1e-12
    inside = np.all((pts >= lo_t) & (pts <= hi_t), -1)  # (19, n)
    Y = pts - c
    q = Y[..., 0] * (M[0, 0] * Y[..., 0] + 2.0 * (M[0, 1] * Y[..., 1] + M[0, 2] * Y[..., 2]))
    q += Y[..., 1] * (M[1, 1] * Y[..., 1] + 2.0 * M[1, 2] * Y[..., 2])
    q += M[2, 2] * Y[..., 2] * Y[..., 2]
    val = np.where(inside, q, np.inf)
    pick = np.argmin(val, axis=0)
    rows = np.arange(n)
    return pts[pick, rows], val[pick, rows]


def box_corners(lo: F, hi: F) -> F:
    return np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1],
                      hi[2] if i & 4 else lo[2]] for i in range(8)])


def keeping_plane(req: F, lo: F, hi: F, g: F) -> tuple[F, float] | None:
    """A plane a·x ≤ b keeping ``req`` (m, 3) with the box [lo, hi] beyond it.

    First the smallest L1 change of the preferred normal ``g`` that separates
    (LP), else the max-margin separator (LP). The offset touches the box."""

    corners = box_corners(lo, hi)
    m = len(req)
    gn = g / np.linalg.norm(g)
    # variables b, p (3), q (3) with a = gn + p − q, p, q ≥ 0; minimize Σ(p + q)
    one = np.ones((m, 1))
    A_ub = np.vstack([
        np.hstack([-one, req, -req]),                    # a·q ≤ b
        np.hstack([np.ones((8, 1)), -corners, corners]),  # a·y ≥ b
        np.hstack([np.zeros((1, 1)), -gn[None], gn[None]]),  # a·gn ≥ 0.5
    ])
    b_ub = np.r_[-(req @ gn), corners @ gn, 0.5]
    res = solve_lp(np.r_[0.0, np.ones(6)], A_ub, b_ub, lower=np.r_[-np.inf, np.zeros(6)])
    if res.status == 0:
        a = gn + res.x[1:4] - res.x[4:7]
        return a, float((corners @ a).min())
    # max-margin: variables a (3), b, t: max t  s.t. a·q + t ≤ b, a·y ≥ b
    A_ub = np.vstack([
        np.hstack([req, -np.ones((m, 1)), np.ones((m, 1))]),
        np.hstack([-corners, np.ones((8, 1)), np.zeros((8, 1))]),
    ])
    res = solve_lp(np.r_[0, 0, 0, 0, -1.0], A_ub, np.zeros(len(A_ub)),
                   lower=np.r_[-1.0, -1.0, -1.0, -np.inf, -np.inf],
                   upper=np.r_[1.0, 1.0, 1.0, np.inf, 1.0])
    if res.status != 0 or res.x[4] < 0 or not np.any(res.x[:3]):
        return None
    a = np.asarray(res.x[:3])
    return a, float((corners @ a).min())


def separating_planes(E: Ellipsoid, Q: F, half: float | F, req: F) -> tuple[F, F]:
    """IRIS step 1: planes (k, 3), (k,) excluding every open cube (centres Q, half-width
    ``half``: one value or one per cube) while keeping the required points ``req`` (m, 3)
    (scaled coordinates)."""
    M = E.metric()
    n = len(Q)
    hw = half_widths(half, n)
    # Cubes are taken in order of their distance in E's metric (ties by index); the closest
    # points are computed batch by batch, nearest lower bound first, and only for cubes no
    # plane has excluded yet. Bound: a cube lies in the ball of radius √3·hw around its
    # centre, whose points are at most √3·hw·√λ_max(M) closer in the metric than the centre.
    y = Q - E.d
    centre = np.sqrt(np.maximum(((y @ M) * y).sum(1), 0.0))
    reach = np.sqrt(3.0 * float(np.linalg.eigvalsh(M)[-1])) * hw
    lb = np.maximum(centre - reach, 0.0) ** 2 * (1.0 - 1e-9)
    by_lb = np.argsort(lb, kind="stable")
    # in that order from here on: cube j below is cube by_lb[j]
    Qs, hws = Q[by_lb], hw[by_lb]
    X = np.zeros((n, 3))
    dist = np.full(n, np.inf)
    alive = np.ones(n, bool)  # for cubes not yet computed: no plane up to `applied` excludes them
    applied = 0
    pending = np.zeros(0, np.int64)  # closest point known, no plane excludes it, not taken
    planes_a: list[F] = []
    planes_b: list[float] = []
    for start in range(0, n, SEPARATION_BATCH):
        end = min(start + SEPARATION_BATCH, n)
        if len(planes_a) > applied:  # the planes found since, on every cube still to compute
            A, bb = np.asarray(planes_a[applied:]), np.asarray(planes_b[applied:])
            applied = len(planes_a)
            gap = Qs[start:] @ A.T - np.outer(hws[start:], np.abs(A).sum(1))
            alive[start:] &= (gap < bb - 1e-12).all(1)
        if not len(pending) and not alive[start:].any():
            break
        nxt = start + np.flatnonzero(alive[start:end])
        if len(nxt):
            X[nxt], dist[nxt] = closest_on_boxes(M, E.d, Qs[nxt] - hws[nxt, None],
                                                 Qs[nxt] + hws[nxt, None])
        # every cube closer than this bound has its closest point now
        bound = float(lb[by_lb[end]]) if end < n else np.inf
        pending = np.concatenate([pending, nxt])
        now = dist[pending] < bound
        ready, pending = pending[now], pending[~now]
        order = ready[np.lexsort((by_lb[ready], dist[ready]))]  # ties by index
        live = np.ones(len(order), bool)
        for i in range(len(order)):
            if not live[i]:
                continue
            k = int(order[i])
            a = M @ (X[k] - E.d)
            b = float(a @ X[k])
            if np.linalg.norm(a) < 1e-12:  # centre on the cube's boundary: push away from it
                a = Qs[k] - E.d
                b = float((box_corners(Qs[k] - hws[k], Qs[k] + hws[k]) @ a).min())
            if len(req) and (req @ a > b - 1e-12).any():
                alt = keeping_plane(req, Qs[k] - hws[k], Qs[k] + hws[k], a)
                if alt is None:
                    raise InfeasibleError(
                        "a required configuration lies inside an infeasible cell (the cube "
                        "around an infeasible node)"
                    )
                a, b = alt
            planes_a.append(a)
            planes_b.append(b)
            s_a = np.abs(a).sum()
            rest = order[i + 1:]
            live[i + 1:] &= (Qs[rest] @ a - hws[rest] * s_a) < b - 1e-12
            pending = pending[(Qs[pending] @ a - hws[pending] * s_a) < b - 1e-12]
    if not planes_a:
        return np.zeros((0, 3)), np.zeros(0)
    return np.asarray(planes_a), np.asarray(planes_b)


def inside(region: Region, pts: F) -> B:
    return region.contains(pts, tol=INSIDE_TOL_DEG)


def is_box_row(a: F) -> bool:
    return int(np.count_nonzero(np.abs(a) > 1e-12)) == 1


class _Exclusion:
    """Which rows exclude which cubes, kept up to date as rows come and go: per cube the
    number of rows excluding it and the sum of their tokens (the token of the only one when
    the number is 1). A row is identified by a token, new whenever its offset changes."""

    def __init__(self, n_obs: int) -> None:
        self.count = np.zeros(n_obs, np.int64)
        self.token_sum = np.zeros(n_obs, np.int64)
        self.rows: dict[int, B] = {}
        self.next = 0

    def add(self, excl: B) -> int:
        tok = self.next
        self.next += 1
        self.rows[tok] = excl
        self.count += excl
        self.token_sum += tok * excl
        return tok

    def remove(self, tok: int) -> None:
        excl = self.rows.pop(tok)
        self.count -= excl
        self.token_sum -= tok * excl


def reduce_halfspaces(
    region: Region, frame: Frame, Q: F, half: float | F, req: F, max_n: int, pts: F,
    tick: Callable[[], None] | None = None,
) -> Region:
    """Greedy plane removal: drop a plane and hand the obstacles only it excluded to
    the other planes by lowering their offsets (never cutting a required point).
    Each round drops the plane that loses the fewest of ``pts`` (deg) — often a
    net gain, since the freed region can exceed what the lowered planes cut.
    Rounds continue while there are more than ``max_n`` rows or a drop gains.
    Grid-box rows are kept. ``half``: the cubes' half-width, one value or one per cube.
    ``tick()`` is called every round (progress; may raise to cancel).

    Rows only ever come from the region and the grid box, and a row's normal never changes
    (only its offset), so each row's minimum over every cube is computed once and the
    exclusions are updated only for the rows a round changes."""
    box = frame.region(np.vstack([np.eye(3), -np.eye(3)]), np.ones(6))
    Qd = Q * frame.s + frame.c
    hd = half_widths(half, len(Q)) * frame.s
    reqd = req * frame.s + frame.c
    tol = INSIDE_TOL_DEG
    A_all = np.vstack([region.A, box.A])
    box_ids = np.arange(region.halfspaces, len(A_all))
    # per row: min of a·θ over each cube, max over the required points, a·p over pts
    mins_t = Qd @ A_all.T - hd[:, None] * np.abs(A_all).sum(1)  # (n_obs, rows)
    req_all = (A_all @ reqd.T).max(1) if len(reqd) else np.full(len(A_all), -np.inf)
    dots_all = A_all @ pts.T
    ex = _Exclusion(len(Q))
    ids = np.arange(region.halfspaces)
    b = region.b.copy()
    toks = np.array([ex.add(mins_t[:, i] >= bi - 1e-9) for i, bi in zip(ids, b, strict=True)],
                    np.int64)
    inner: F | None = None
    while True:
        if tick is not None:
            tick()
        n = len(b)
        A = A_all[ids]
        # the cubes only one plane excludes (their owner), and for each the plane that would
        # take it over if its owner were dropped: the one it is least inside, never moving
        # past a required point
        s1 = np.flatnonzero(ex.count == 1)
        pos = np.full(ex.next, -1, np.int64)
        pos[toks] = np.arange(n)
        owner = pos[ex.token_sum[s1]]
        req_max = req_all[ids]
        m = mins_t.take(s1, axis=0).take(ids, axis=1)  # (n_sole, n)
        rows_s = np.arange(len(s1))
        gain = m - b
        gain[m < req_max] = -np.inf
        gain[rows_s, owner] = -np.inf
        j = np.argmax(gain, axis=1)
        stuck = np.zeros(n, bool)
        stuck[owner[~np.isfinite(gain[rows_s, j])]] = True
        new_b = np.broadcast_to(b, (n, n)).copy()  # row k: the offsets if plane k is dropped
        np.minimum.at(new_b, (owner, j), m[rows_s, j])
        slk = b[:, None] - dots_all[ids]  # slack, (n, n_pts): one row per plane
        nviol = (slk < -tol).sum(0)
        S_in = slk[:, nviol == 0]
        S_one = slk[:, nviol == 1]
        only = np.argmin(S_one, axis=0) if S_one.shape[1] else np.zeros(0, int)
        # first the offsets each drop needs, then the losses on the points that matter
        moves = [(k, new_b[k]) for k in range(n) if not is_box_row(A[k]) and not stuck[k]]
        if not moves:
            break
        reach = max(float((b - nb).max()) for _, nb in moves) + tol
        S_in = S_in[:, S_in.min(0) < reach]
        best: F | None = None
        best_k, best_loss = -1, np.inf
        for k, nb in moves:
            moved = np.flatnonzero(nb < b)
            shift = b[moved] - nb[moved]
            freed = S_one[:, only == k]
            lost = np.zeros(S_in.shape[1], bool)
            kept = np.ones(freed.shape[1], bool)
            for jj, sh in zip(moved, shift, strict=True):
                lost |= S_in[jj] < sh - tol
                kept &= freed[jj] >= sh - tol
            loss = float(lost.sum() - kept.sum())
            if loss < best_loss:
                best_loss, best, best_k = loss, nb, k
        if best is None or (n <= max_n and best_loss >= 0):
            break
        keep = np.flatnonzero(np.arange(n) != best_k)
        # the grid box may have been redundant only because of the dropped plane
        cand_ids = np.r_[ids[keep], box_ids]
        cand_b = np.r_[best[keep], box.b]
        reduced = Region(A_all[cand_ids], cand_b)
        inner = reduced.interior_point(inner)
        rows = reduced.facet_rows(interior=inner)
        new_toks = []
        for r in rows:
            same = r < len(keep) and cand_b[r] == b[keep[r]]
            new_toks.append(int(toks[keep[r]]) if same else
                            ex.add(mins_t[:, cand_ids[r]] >= cand_b[r] - 1e-9))
        for t in set(toks.tolist()) - set(new_toks):
            ex.remove(t)
        ids, b, toks = cand_ids[rows], cand_b[rows], np.asarray(new_toks, np.int64)
    return Region(A_all[ids], b)


