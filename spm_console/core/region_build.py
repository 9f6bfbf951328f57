"""The convex region P ⊆ P' (paper eq. 26), built IRIS-style from the classified grid.

P' = (∪_{θ∈V} θ ⊕ C_Δ) ⊖ C_Δ is, on the grid, the set of points at L∞ distance
≥ Δ from every node that is not home-connected feasible, and inside the grid box:
the union of the grid cells whose 8 corners are all feasible. So P must avoid the
*open cube of half-width Δ* around every infeasible node. Only infeasible nodes
with a feasible 26-neighbour can be touched first by a convex set grown inside the
feasible set, so those are the obstacles; the grid box adds six half-spaces.

IRIS (Deits & Tedrake 2015) alternates two steps:
1. separating planes: in the metric of the current ellipsoid E, take the closest
   remaining obstacle cube, add the plane tangent to E's level set at its closest
   point (the whole cube lies beyond it), drop every cube beyond it, repeat;
2. the maximum-volume ellipsoid inscribed in the resulting polytope.
Required points (home, or the two configurations of :func:`region_containing`)
are never cut: a plane that would cut one is replaced by the max-margin plane
between the required points and that cube (an LP).

Angles in degrees at this interface; the solver works in scaled coordinates
x = (θ − centre) / half-range.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.optimize import linprog

from spm_console.core.ellipsoid import Ellipsoid, inscribed_ellipsoid
from spm_console.core.region import Region
from spm_console.errors import InfeasibleError

if TYPE_CHECKING:
    from spm_console.core.workspace import Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: IRIS stops when the ellipsoid volume grows by less than this fraction.
VOLUME_TOL = 0.02
#: Maximum IRIS iterations.
MAX_ITERS = 6
#: Feasible nodes used as the objective of the heuristics (random subset beyond this).
OBJECTIVE_POINTS = 20_000
#: Tolerance (deg) for "a node lies in P".
INSIDE_TOL_DEG = 1e-7


@dataclass(frozen=True)
class RegionBuild:
    """Result of a region construction (object, not tuple)."""

    region: Region
    """P with unit-norm rows, θ in degrees."""
    coverage: float
    """Fraction of feasible nodes inside P."""
    iterations: int
    """IRIS iterations run."""
    obstacles: int
    """Obstacle cubes considered (infeasible nodes next to feasible ones)."""
    log_volume: float
    """log det of the last inscribed ellipsoid (scaled coordinates)."""
    seconds: float
    iris_planes: int = 0
    """Non-redundant planes IRIS produced before any reduction to the cap."""

    def info(self) -> dict[str, float]:
        return {
            "iris_planes": float(self.iris_planes),
            "coverage": self.coverage, "iterations": float(self.iterations),
            "obstacles": float(self.obstacles), "halfspaces": float(self.region.halfspaces),
            "log_volume": self.log_volume, "seconds": self.seconds,
        }


@dataclass(frozen=True)
class _Frame:
    """Scaling θ (deg) ↔ x = (θ − c) / s."""

    c: F
    s: float

    def to_x(self, theta: F) -> F:
        return np.asarray((np.asarray(theta, float) - self.c) / self.s)

    def region(self, A: F, b: F) -> Region:
        """Rows a·x ≤ b  →  (a/s)·θ ≤ b + a·c/s, normalized."""
        return Region(A / self.s, b + A @ self.c / self.s).normalized()


def obstacle_nodes(feasible: B, theta_deg: F) -> F:
    """θ (deg) of the infeasible nodes that have a feasible 26-neighbour: (n, 3)."""
    near = ndimage.binary_dilation(feasible, structure=np.ones((3, 3, 3), bool))
    return np.asarray(theta_deg[near & ~feasible])


def closest_on_boxes(M: F, c: F, lo: F, hi: F) -> tuple[F, F]:
    """argmin and min of (x − c)ᵀ M (x − c) over each box [lo_k, hi_k] (k rows of (n, 3)).

    Exact: the minimizer is the centre (if inside) or lies in the relative interior
    of a face, an edge or at a vertex; every face's unconstrained minimizer and every edge's clipped
    minimizer is a candidate, the best feasible one wins (vertices are covered by
    the clipped edges).
    """
    n = len(lo)
    best = np.full(n, np.inf)
    arg = np.zeros((n, 3))
    bounds = (lo, hi)

    def consider(x: F) -> None:
        inside = np.all((x >= lo - 1e-12) & (x <= hi + 1e-12), -1)
        y = x - c
        val = np.where(inside, np.einsum("ni,ij,nj->n", y, M, y), np.inf)
        better = val < best
        best[better] = val[better]
        arg[better] = x[better]

    consider(np.broadcast_to(c, (n, 3)).copy())  # centre inside the box
    for k in range(3):  # faces x_k = const
        f = [i for i in range(3) if i != k]
        gain = np.linalg.solve(M[np.ix_(f, f)], M[f, k])
        for s in (0, 1):
            x = np.empty((n, 3))
            x[:, k] = bounds[s][:, k]
            x[:, f] = c[f] - np.outer(x[:, k] - c[k], gain)
            consider(x)
    for i in range(3):  # edges along x_i
        j, k = (m for m in range(3) if m != i)
        for s1 in (0, 1):
            for s2 in (0, 1):
                x = np.empty((n, 3))
                x[:, j] = bounds[s1][:, j]
                x[:, k] = bounds[s2][:, k]
                xi = c[i] - (M[i, j] * (x[:, j] - c[j]) + M[i, k] * (x[:, k] - c[k])) / M[i, i]
                x[:, i] = np.clip(xi, lo[:, i], hi[:, i])
                consider(x)
    return arg, best


def _corners(lo: F, hi: F) -> F:
    return np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1],
                      hi[2] if i & 4 else lo[2]] for i in range(8)])


def _keeping_plane(req: F, lo: F, hi: F, g: F) -> tuple[F, float] | None:
    """A plane a·x ≤ b keeping ``req`` (m, 3) with the box [lo, hi] beyond it.

    First the smallest L1 change of the preferred normal ``g`` that separates
    (LP), else the max-margin separator (LP). The offset touches the box."""
    corners = _corners(lo, hi)
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
    res = linprog(np.r_[0.0, np.ones(6)], A_ub=A_ub, b_ub=b_ub,
                  bounds=[(None, None)] + [(0, None)] * 6, method="highs")
    if res.status == 0:
        a = gn + res.x[1:4] - res.x[4:7]
        return a, float((corners @ a).min())
    # max-margin: variables a (3), b, t: max t  s.t. a·q + t ≤ b, a·y ≥ b
    A_ub = np.vstack([
        np.hstack([req, -np.ones((m, 1)), np.ones((m, 1))]),
        np.hstack([-corners, np.ones((8, 1)), np.zeros((8, 1))]),
    ])
    res = linprog(np.r_[0, 0, 0, 0, -1.0], A_ub=A_ub, b_ub=np.zeros(len(A_ub)),
                  bounds=[(-1, 1)] * 3 + [(None, None), (None, 1.0)], method="highs")
    if res.status != 0 or res.x[4] < 0 or not np.any(res.x[:3]):
        return None
    a = np.asarray(res.x[:3])
    return a, float((corners @ a).min())


def separating_planes(E: Ellipsoid, Q: F, half: float, req: F) -> tuple[F, F]:
    """IRIS step 1: planes (k, 3), (k,) excluding every open cube (centre Q, half-width)
    while keeping the required points ``req`` (m, 3) (scaled coordinates)."""
    M = E.metric()
    lo, hi = Q - half, Q + half
    X, dist = closest_on_boxes(M, E.d, lo, hi)
    order = np.argsort(dist, kind="stable")
    alive = np.ones(len(Q), bool)
    l1 = np.zeros(len(Q))
    planes_a: list[F] = []
    planes_b: list[float] = []
    for k in order:
        if not alive[k]:
            continue
        a = M @ (X[k] - E.d)
        b = float(a @ X[k])
        if np.linalg.norm(a) < 1e-12:  # centre on the cube's boundary: push away from it
            a = Q[k] - E.d
            b = float((_corners(lo[k], hi[k]) @ a).min())
        if len(req) and (req @ a > b - 1e-12).any():
            alt = _keeping_plane(req, lo[k], hi[k], a)
            if alt is None:
                raise InfeasibleError(
                    "a required configuration lies inside an infeasible grid cell"
                )
            a, b = alt
        planes_a.append(a)
        planes_b.append(b)
        l1 = half * np.abs(a).sum()
        alive &= (Q @ a - l1) < b - 1e-12
    if not planes_a:
        return np.zeros((0, 3)), np.zeros(0)
    return np.asarray(planes_a), np.asarray(planes_b)


def _inside(region: Region, pts: F) -> B:
    return region.contains(pts, tol=INSIDE_TOL_DEG)


def _iris(
    feasible: B, theta_deg: F, step_deg: float, lo: float, hi: float, req_deg: F,
    E0_deg: tuple[F, F], max_halfspaces: int,
    progress: Callable[[float], None] | None = None,
) -> RegionBuild:
    t0 = time.perf_counter()
    frame = _Frame(np.full(3, 0.5 * (lo + hi)), 0.5 * (hi - lo))
    Q = frame.to_x(obstacle_nodes(feasible, theta_deg))
    half = step_deg / frame.s
    req = frame.to_x(req_deg).reshape(-1, 3)
    Abox = np.vstack([np.eye(3), -np.eye(3)])
    bbox = np.ones(6)
    E = Ellipsoid(E0_deg[0] / frame.s, frame.to_x(E0_deg[1]))
    feas_pts = theta_deg[feasible]
    # objective points of the heuristics: a fixed random subset (exact coverage at the end)
    rng = np.random.default_rng(0)
    obj = feas_pts if len(feas_pts) <= OBJECTIVE_POINTS else feas_pts[
        rng.choice(len(feas_pts), OBJECTIVE_POINTS, replace=False)]
    best: RegionBuild | None = None
    it = 0
    for it in range(1, MAX_ITERS + 1):
        Ap, bp = separating_planes(E, Q, half, req)
        cand = frame.region(np.vstack([Abox, Ap]), np.r_[bbox, bp]).without_redundant()
        raw_planes = cand.halfspaces
        cov = float(_inside(cand, obj).mean()) if len(obj) else 0.0
        # next ellipsoid inside the candidate, in scaled coordinates
        Ax = cand.A * frame.s
        bx = cand.b - cand.A @ frame.c
        E_new = inscribed_ellipsoid(Ax, bx)
        grow = E_new.log_volume - E.log_volume
        if best is None or cov > best.coverage:
            best = RegionBuild(cand, cov, it, len(Q), E_new.log_volume, 0.0, raw_planes)
        if progress is not None:
            progress(it / MAX_ITERS)
        E = E_new
        if it > 1 and grow < np.log1p(VOLUME_TOL):
            break
    assert best is not None
    final = reduce_halfspaces(best.region, frame, Q, half, req, max_halfspaces, obj)
    cov = float(_inside(final, feas_pts).mean()) if len(feas_pts) else 0.0
    return RegionBuild(final, cov, it, best.obstacles, best.log_volume,
                       time.perf_counter() - t0, best.iris_planes)


def _is_box_row(a: F) -> bool:
    return int(np.count_nonzero(np.abs(a) > 1e-12)) == 1


def reduce_halfspaces(
    region: Region, frame: _Frame, Q: F, half: float, req: F, max_n: int, pts: F
) -> Region:
    """Greedy plane removal: drop a plane and hand the obstacles only it excluded to
    the other planes by lowering their offsets (never cutting a required point).
    Each round drops the plane that loses the fewest of ``pts`` (deg) — often a
    net gain, since the freed region can exceed what the lowered planes cut.
    Rounds continue while there are more than ``max_n`` rows or a drop gains.
    Grid-box rows are kept."""
    A, b = region.A.copy(), region.b.copy()
    box = frame.region(np.vstack([np.eye(3), -np.eye(3)]), np.ones(6))
    Qd = Q * frame.s + frame.c
    hd = half * frame.s
    reqd = req * frame.s + frame.c
    tol = INSIDE_TOL_DEG
    while True:
        n = len(b)
        mins = Qd @ A.T - hd * np.abs(A).sum(1)  # (n_obs, n) min of a·θ over each cube
        excl = mins >= b - 1e-9
        nex = excl.sum(1)
        req_max = (reqd @ A.T).max(0) if len(reqd) else np.full(n, -np.inf)
        slk = b[:, None] - A @ pts.T  # slack, (n, n_pts): one row per plane
        nviol = (slk < -tol).sum(0)
        S_in = slk[:, nviol == 0]
        S_one = slk[:, nviol == 1]
        only = np.argmin(S_one, axis=0) if S_one.shape[1] else np.zeros(0, int)
        # first the offsets each drop needs, then the losses on the points that matter
        moves: list[tuple[int, F]] = []
        for k in range(n):
            if _is_box_row(A[k]):
                continue
            sole = np.flatnonzero(excl[:, k] & (nex == 1))
            nb = b.copy()
            if len(sole):
                ok = (mins[sole] >= req_max) & (np.arange(n) != k)
                gain = np.where(ok, mins[sole] - b, -np.inf)
                j = np.argmax(gain, axis=1)
                if not np.isfinite(gain[np.arange(len(sole)), j]).all():
                    continue
                np.minimum.at(nb, j, mins[sole, j])
            moves.append((k, nb))
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
        keep = np.arange(n) != best_k
        # the grid box may have been redundant only because of the dropped plane
        reduced = Region(np.vstack([A[keep], box.A]), np.r_[best[keep], box.b]).without_redundant()
        A, b = reduced.A, reduced.b
    return Region(A, b)


def build_region(
    ws: Workspace, max_halfspaces: int = 64, progress: Callable[[float], None] | None = None
) -> RegionBuild:
    """The default P of a workspace: IRIS grown from the home node (which it contains)."""
    feasible = ws.feasible
    lo, hi = ws.range_deg()
    theta = ws.theta_deg()
    home = _home_node(ws)
    return _iris(feasible, theta, ws.step_deg, lo, hi, home[None],
                 (np.eye(3) * ws.step_deg, home), max_halfspaces, progress)


def _home_node(ws: Workspace) -> F:
    """θ (deg) of the grid node nearest home (feasible whenever anything is)."""
    return np.asarray(ws.theta_deg()[ws.home_index])


@dataclass(frozen=True)
class RegionChoice:
    """The region a plan between two configurations uses, and where it came from."""

    region: Region
    kind: Literal["P", "grown", "given"]
    """The workspace's cached P, a region grown around the straight segment, or one given
    by the operator (``source`` says which)."""
    source: str = ""

    def describe(self) -> str:
        """One line naming the region and its size (half-spaces, inscribed ball radius)."""
        _, radius = self.region.chebyshev()
        what = {"P": "the workspace region P", "grown": "a region grown around the segment",
                "given": self.source or "the given region"}[self.kind]
        return (f"{what} ({self.region.halfspaces} half-spaces, inscribed ball radius "
                f"{radius:.1f}°)")


def choose_region(ws: Workspace, theta_a_deg: F, theta_b_deg: F) -> RegionChoice:
    """A region (θ in degrees) containing both configurations: the cached P if it
    already does, else an IRIS region grown around the straight segment between
    them. Raises :class:`InfeasibleError` naming why when the segment leaves the
    feasible set."""
    from spm_console.core.segment_check import check_segment

    a = np.asarray(theta_a_deg, float)
    b = np.asarray(theta_b_deg, float)
    if not bool(ws.feasible.any()):
        raise InfeasibleError("the workspace has no feasible node (every grid node is singular, "
                              "colliding or unreachable): nothing can be planned in it; check the "
                              "profile's links, δ and ζ_min")
    if bool(ws.region.contains(np.stack([a, b]), tol=1e-9).all()):
        return RegionChoice(ws.region, "P")
    check_segment(ws, a, b)
    lo, hi = ws.range_deg()
    # seed: the inscribed ellipsoid of the default P (planes that would cut a or b
    # are turned just enough to keep them)
    E = inscribed_ellipsoid(ws.region.A, ws.region.b)
    limit = max(ws.region.halfspaces, int(ws.region_info.get("max_halfspaces", 64)))
    res = _iris(ws.feasible, ws.theta_deg(), ws.step_deg, lo, hi, np.stack([a, b]),
                (E.C, E.d), limit)
    if not bool(res.region.contains(np.stack([a, b]), tol=1e-7).all()):
        raise InfeasibleError("could not build a convex region containing both configurations")
    return RegionChoice(res.region, "grown")


def region_containing(ws: Workspace, theta_a_deg: F, theta_b_deg: F) -> Region:
    """The region of :func:`choose_region`."""
    return choose_region(ws, theta_a_deg, theta_b_deg).region
