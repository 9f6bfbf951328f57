"""Unique forward kinematics by continuation, and the model that carries the home pose.

The platform orientation is a rotation R with v_i = R v_i⁰ (v⁰ = the home triad),
so (3) and (5) hold by construction and FK reduces to the three equations (4):
f_i(θ, R) = w_i(θ)·v_i − cos α2 = 0. Their derivative with respect to a small
rotation ω (R ← exp([ω]×) R) is exactly J1 (11); with respect to θ it is −J2 (12).

"Unique" FK: the solution in the home assembly mode reached by
continuous motion from home (or from a given known pose) without crossing a
singularity. Newton steps use J1, so they are well defined away from type-2
singularities; a path is refused when det J1 changes sign (type-2 singularity:
another assembly mode) or a diagonal entry of J2 changes sign (type-1: a leg
folds and changes working mode), or when ζ along the path drops below a floor.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.component_ops import Mat
from spm_console.core.kinematics.continuation import (
    CONVERGED_RESIDUAL,
    MAX_CORRECTION,
    NEWTON_TOL,
    PATH_ZETA_FLOOR,
    Local,
    continuation_step,
    one_row_kernel,
)
from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.jacobian import conditioning_index, j1_matrix, j2_diag
from spm_console.core.kinematics.rotations import expm_so3

F = NDArray[np.float64]

#: Farthest θ a continuation is asked to follow, per joint, rad (two turns: every θ the
#: commands take lies within ±360°). Each step is at most a degree, so a target farther than
#: this, or not finite, is refused before the first step instead of being walked for hours.
MAX_TRACK_RAD = 4.0 * math.pi


def platform_axes(R: F, v_home: F) -> F:
    """v_i = R v_i⁰: (..., 3, 3) rotations -> (..., 3, 3) rows v1..v3."""
    return np.einsum("...ab,ib->...ia", R, v_home)


def normal(v: F) -> F:
    """Platform normal n = N/‖N‖, N = v1 + v2 + v3, eq. (7)."""
    N = v.sum(axis=-2)
    return np.asarray(N / np.linalg.norm(N, axis=-1, keepdims=True))


def residual(geom: SpmGeometry, w: F, v: F) -> F:
    """f_i = w_i·v_i − cos α2 (4). -> (..., 3)."""
    return np.asarray(np.einsum("...ij,...ij->...i", w, v) - geom.cos_alpha2)


def full_residual(geom: SpmGeometry, w: F, v: F) -> F:
    """Max violation of (3)-(5) for each pose: (...,)."""
    r4 = np.abs(residual(geom, w, v)).max(-1)
    r3 = np.abs(np.linalg.norm(v, axis=-1) - 1.0).max(-1)
    G = np.einsum("...ik,...jk->...ij", v, v)
    off = np.abs(np.stack([G[..., 0, 1], G[..., 0, 2], G[..., 1, 2]], -1) - geom.cos_alpha3)
    return np.asarray(np.maximum(np.maximum(r4, r3), off.max(-1)))


def newton(
    geom: SpmGeometry, w: F, R: F, v_home: F, iters: int = 12, tol: float = NEWTON_TOL
) -> tuple[F, F]:
    """Newton on (4) over rotations, vectorized. Returns (R, max |f|)."""
    R = R.copy()
    res = np.full(R.shape[:-2], np.inf)
    for _ in range(iters):
        v = platform_axes(R, v_home)
        f = residual(geom, w, v)
        res = np.abs(f).max(-1)
        todo = res > tol
        if not todo.any():
            break
        J1 = j1_matrix(v, w)
        with np.errstate(all="ignore"):
            om = -np.linalg.solve(J1[todo], f[todo][..., None])[..., 0]
        om = np.where(np.isfinite(om), om, 0.0)
        R[todo] = expm_so3(om) @ R[todo]
    v = platform_axes(R, v_home)
    res = np.abs(residual(geom, w, v)).max(-1)
    return R, res


@dataclass(frozen=True)
class Pose:
    """One solved configuration. Angles in radians internally; see ``*_deg`` helpers."""

    theta: F
    """Motor angles θ (3,), rad."""
    R: F
    """Platform rotation from home (3, 3)."""
    v: F
    """Top axes v1..v3 as rows (3, 3)."""
    n: F
    """Platform normal (3,)."""
    zeta: float
    """Conditioning index ζ."""
    residual: float
    """Max violation of (3)-(5)."""

    @property
    def theta_deg(self) -> F:
        return np.degrees(self.theta)


@dataclass(frozen=True)
class FkResult:
    """Result of a continuation FK solve (an object, not a tuple)."""

    ok: bool
    """True when the target was reached in the home assembly and working modes."""
    pose: Pose | None
    """The solved pose when ok (or the last good pose on the path otherwise)."""
    reason: str = ""
    """Why the solve was refused (empty when ok)."""
    path_min_zeta: float = 1.0
    """Smallest ζ met along the path."""
    steps: int = 0
    """Continuation steps taken."""
    path_theta_deg: list[list[float]] = field(default_factory=list)
    """θ samples along the path, deg (for display)."""
    waypoints_deg: tuple[tuple[float, ...], ...] = ()
    """Corners of the polyline followed from home to θ, deg, both ends included (filled by
    :func:`~spm_console.core.workspace.fk_path.fk_connected`; empty from :meth:`SpmModel.track`)."""
    route: str = "straight"
    """"straight" (one segment from home) or "graph" (around a singularity through the
    workspace grid, :mod:`spm_console.core.workspace.fk_path`)."""


@dataclass(frozen=True)
class SpmModel:
    """Geometry plus the home pose and its modes: everything FK/IK needs (constant)."""

    geom: SpmGeometry
    theta_home: F
    """Home θ (3,), rad."""
    v_home: F
    """Home top axes (3, 3); R = I at home."""
    working_signs: F
    """Sign of each J2 diagonal entry at home (the legs' working modes)."""
    det_j1_sign: float
    """Sign of det J1 at home (the assembly mode's side of type-2 singularities)."""

    @property
    def u(self) -> F:
        return self.geom.u

    def pose(self, theta: F, R: F) -> Pose:
        """Assemble a :class:`Pose` (no solving) for one θ (rad) and rotation."""
        w = self.geom.w(theta)
        v = platform_axes(R, self.v_home)
        z = float(conditioning_index(self.u, v, w))
        return Pose(
            theta=np.asarray(theta, float), R=R, v=v, n=normal(v), zeta=z,
            residual=float(full_residual(self.geom, w, v)),
        )

    def poses(self, theta: F, R: F) -> list[Pose]:
        """:meth:`pose` of each row of θ (B, 3) rad with rotations R (B, 3, 3), computed
        together (the same figures as one by one)."""
        theta = np.asarray(theta, float).reshape(-1, 3)
        R = np.asarray(R, float).reshape(-1, 3, 3)
        if not len(theta):
            return []
        w = self.geom.w(theta)
        v = platform_axes(R, self.v_home)
        z = np.broadcast_to(conditioning_index(self.u, v, w), (len(theta),))
        n = normal(v)
        res = np.broadcast_to(full_residual(self.geom, w, v), (len(theta),))
        return [Pose(theta=theta[k].copy(), R=R[k], v=v[k], n=n[k], zeta=float(z[k]),
                     residual=float(res[k])) for k in range(len(theta))]

    def mode_check(self, theta: F, R: F) -> tuple[F, F, F]:
        """(ζ, det J1 · home sign, J2 diag · home signs) for batches: positive = same mode."""
        w = self.geom.w(theta)
        v = platform_axes(R, self.v_home)
        d1 = np.linalg.det(j1_matrix(v, w)) * self.det_j1_sign
        d2 = j2_diag(self.u, v, w) * self.working_signs
        return conditioning_index(self.u, v, w), d1, d2

    def track(
        self,
        theta_target: F,
        theta_from: F | None = None,
        R_from: F | None = None,
        max_step: float = math.radians(1.0),
    ) -> FkResult:
        """Unique FK of one θ (rad) by predictor-corrector continuation along a straight path."""
        res = self.track_batch(
            np.asarray(theta_target, float)[None], theta_from, R_from, max_step
        )
        return res[0]

    def track_batch(
        self,
        theta_targets: F,
        theta_from: F | None = None,
        R_from: F | None = None,
        max_step: float = math.radians(1.0),
        keep_path: bool = False,
    ) -> list[FkResult]:
        """Continuation from a known pose (default: home) to each row of ``theta_targets``.

        All rows advance together with the same number of steps (each row's step is
        its own distance over that count, ≤ ``max_step`` rad in every joint). Rows
        whose corrector struggles are retried with 8× finer steps. A row not finite, or
        farther than :data:`MAX_TRACK_RAD` from the start in a joint, is refused unwalked.
        """
        T = np.atleast_2d(np.asarray(theta_targets, float))
        t0 = self.theta_home if theta_from is None else np.asarray(theta_from, float)
        R0 = np.eye(3) if R_from is None else np.asarray(R_from, float)
        out: list[FkResult | None] = [None] * len(T)
        with np.errstate(invalid="ignore"):
            far = ~(np.abs(T - t0) <= MAX_TRACK_RAD).all(axis=1)  # NaN compares False
        for k in np.flatnonzero(far):
            out[k] = FkResult(ok=False, pose=self.pose(t0, R0), reason=(
                f"θ = {_fmt(T[k])}° is not within {math.degrees(MAX_TRACK_RAD):g}° of the "
                "start in every joint (or not a finite angle): not a motion to follow"))
        idx = np.flatnonzero(~far)
        for refine in (1, 8):
            if len(idx) == 0:
                break
            results = self._march(T[idx], t0, R0, max_step / refine, keep_path)
            retry = []
            for k, r in zip(idx, results, strict=True):
                if r.ok or refine == 8 or r.reason.startswith("crosses"):
                    out[k] = r
                else:
                    retry.append(k)
            idx = np.asarray(retry, int)
        return [r for r in out if r is not None]

    def _march(
        self, T: F, t0: F, R0: F, max_step: float, keep_path: bool
    ) -> list[FkResult]:
        B = len(T)
        if B == 1:
            return [self._march_one(T[0], t0, R0, max_step, keep_path)]
        d = T - t0
        n = max(1, math.ceil(float(np.abs(d).max()) / max_step)) if B else 1
        R = np.broadcast_to(R0, (B, 3, 3)).copy()
        th = np.broadcast_to(t0, (B, 3)).copy()
        alive = np.ones(B, bool)
        reason = [""] * B
        minz = np.ones(B)
        start = [list(np.degrees(t0))] if keep_path else []
        paths: list[list[list[float]]] = [list(start) for _ in range(B)]
        for k in range(1, n + 1):
            a = np.flatnonzero(alive)
            if len(a) == 0:
                break
            th_new = t0 + d[a] * (k / n)
            st = continuation_step(self, th[a], R[a], th_new)
            res, z, s1, s2 = st.residual, st.zeta, st.det_side, st.leg_sides
            conv = st.converged
            minz[a] = np.minimum(minz[a], z)
            crossed = ~conv | (s1 <= 0.0) | (z < PATH_ZETA_FLOOR) | (s2 <= 0.0).any(axis=-1)
            for j in np.flatnonzero(crossed):  # the rows that stop here, each with its reason
                b = a[j]
                alive[b] = False
                reason[b] = _stop_reason(bool(conv[j]), float(res[j]), float(s1[j]), float(z[j]),
                                         s2[j], th_new[j])
            ok = alive[a]
            R[a[ok]] = st.R[ok]
            th[a[ok]] = th_new[ok]
            if keep_path:
                for jj in a[ok]:
                    paths[int(jj)].append(list(np.degrees(th[jj])))
        return [
            FkResult(ok=bool(alive[row]), pose=pose, reason=reason[row],
                     path_min_zeta=float(minz[row]), steps=n, path_theta_deg=paths[row])
            for row, pose in enumerate(self.poses(th, R))
        ]

    def _march_one(self, target: F, t0: F, R0: F, max_step: float, keep_path: bool) -> FkResult:
        """:meth:`_march` of one row, on Python floats (:class:`OneRowKernel`, each step's
        Jacobians reused by the next): the same steps, verdicts and reasons."""
        kern = one_row_kernel(self)
        t0 = np.broadcast_to(t0, (1, 3))[0]  # (as the batch march broadcasts them)
        d = target - t0
        n = max(1, math.ceil(float(np.abs(d).max()) / max_step))
        start, dl = t0.tolist(), d.tolist()
        th: list[float] = list(start)
        R: Mat = np.broadcast_to(R0, (1, 3, 3))[0].tolist()
        at: Local | None = None
        ok, reason, minz = True, "", 1.0
        path = [np.degrees(t0).tolist()] if keep_path else []
        for k in range(1, n + 1):
            th_new = [start[i] + dl[i] * (k / n) for i in range(3)]
            st = kern.step(th, R, th_new, at)
            z = float(st.zeta)
            minz = z if (z < minz or z != z) else minz  # (NaN kept, as np.minimum does)
            s1, s2 = float(st.det_side), [float(x) for x in st.leg_sides]
            conv = bool(st.residual <= CONVERGED_RESIDUAL and st.correction <= MAX_CORRECTION)
            if not conv or s1 <= 0.0 or z < PATH_ZETA_FLOOR or any(x <= 0.0 for x in s2):
                ok = False
                reason = _stop_reason(conv, float(st.residual), s1, z, s2, np.array(th_new))
                break
            th, R, at = th_new, st.R, st.at
            if keep_path:
                path.append(np.degrees(th).tolist())
        pose = self.poses(np.array([th], float), np.array([R], float))[0]
        return FkResult(ok=ok, pose=pose, reason=reason, path_min_zeta=minz, steps=n,
                        path_theta_deg=path)


def _stop_reason(conv: bool, res: float, s1: float, z: float, s2: Sequence[float] | F,
                 th_new: F) -> str:
    """Why a continuation stops at θ_new (rad): not converged, or a mode changed."""
    if not conv:
        return (f"corrector did not converge near θ = {_fmt(th_new)}° (residual {res:.1e}); "
                "try a smaller step")
    if s1 <= 0.0 or z < PATH_ZETA_FLOOR:
        return (f"crosses a type-2 singularity (assembly-mode change) near θ = {_fmt(th_new)}° "
                f"(ζ = {z:.2e}); approach it from another known pose")
    leg = int(np.argmin(s2)) + 1
    return (f"crosses a type-1 singularity (leg {leg} folds, working-mode change) near "
            f"θ = {_fmt(th_new)}° (ζ = {z:.2e})")


def _fmt(theta_rad: F) -> str:
    return "[" + ", ".join(f"{x:.2f}" for x in np.degrees(theta_rad)) + "]"
