"""All assembly modes for one θ, the home pose from the sign seed, and the paper's seeded solve.

Assembly modes are found by damped Newton (Levenberg-Marquardt) on (4) over
rotations from many fixed starting rotations, then deduplicated; a rigid platform
has at most 8 (paper Sec. II-B). The paper's Algorithm 1 (fsolve on the nine
unknowns from the sign seed x0, eq. 33) is provided as :func:`seeded_solve` — one
tool among others, not the definition of the unique solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.jacobian import conditioning_index, j1_matrix, j2_diag
from spm_console.core.kinematics.model import (
    SpmModel,
    full_residual,
    newton,
    normal,
    platform_axes,
    residual,
)
from spm_console.core.kinematics.rotations import expm_so3, random_rotations

F = NDArray[np.float64]

_N_STARTS = 512
#: Levenberg-Marquardt: a start whose squared residual is below this has converged, and one
#: whose damping rose above this makes no more progress.
_CONVERGED = 1e-20
_STALLED = 1e6


def _lm_solve(geom: SpmGeometry, w: F, v_ref: F, starts: F, iters: int = 80) -> tuple[F, F]:
    """Levenberg-Marquardt on (4) from many rotations (at most ``iters`` steps, fewer once
    every start has converged or stalled); returns (R, residual)."""
    R = starts.copy()
    lam = np.full(len(R), 1e-2)
    v = platform_axes(R, v_ref)
    f = residual(geom, w, v)
    cost = (f * f).sum(-1)
    for _ in range(iters):
        J = j1_matrix(v, np.broadcast_to(w, v.shape))
        H = np.einsum("bki,bkj->bij", J, J) + lam[:, None, None] * np.eye(3)
        g = np.einsum("bki,bk->bi", J, f)
        with np.errstate(all="ignore"):
            om = -np.linalg.solve(H, g[..., None])[..., 0]
        om = np.where(np.isfinite(om), om, 0.0)
        Rn = expm_so3(om) @ R
        vn = platform_axes(Rn, v_ref)
        fn = residual(geom, w, vn)
        cn = (fn * fn).sum(-1)
        better = cn < cost
        R[better], v[better], f[better], cost[better] = Rn[better], vn[better], fn[better], cn[better]
        lam = np.where(better, np.maximum(lam / 5.0, 1e-12), lam * 4.0)
        if ((cost < _CONVERGED) | (lam > _STALLED)).all():
            break  # every start has converged (Newton polishes it) or stopped moving
    R, res = newton(geom, np.broadcast_to(w, R.shape), R, v_ref)
    return R, res


def solve_all(geom: SpmGeometry, theta: F, v_ref: F, tol: float = 1e-11) -> list[F]:
    """Every rigid pose (rotation of ``v_ref``) satisfying (4) at θ (rad), deduplicated."""
    starts = random_rotations(_N_STARTS, seed=12345)
    starts = np.concatenate([np.eye(3)[None], starts])
    w = geom.w(np.asarray(theta, float))
    R, res = _lm_solve(geom, w, v_ref, starts)
    found: list[F] = []
    for Ri, ri in zip(R, res, strict=True):
        if ri > tol:
            continue
        if all(np.abs(Ri - Rj).max() > 1e-6 for Rj in found):
            found.append(Ri)
    return found


@dataclass(frozen=True)
class AssemblyMode:
    """One solution of (3)-(5) at a given θ."""

    v: F
    """Top axes v1..v3 as rows (3, 3)."""
    n: F
    """Platform normal (3,)."""
    zeta: float
    """Conditioning index ζ."""
    residual: float
    """Max violation of (3)-(5)."""
    home_connected: bool
    """True for the solution reached by continuation from home."""
    same_sides: bool
    """True when det J1 and the J2 diagonal have the home's signs."""


def assembly_modes(model: SpmModel, theta: F, home_R: F | None = None) -> list[AssemblyMode]:
    """All assembly modes at θ (rad), ordered by ζ; flag the home-connected one.

    ``home_R`` is the continuation solution at θ (if known) used for the flag.
    """
    geom = model.geom
    Rs = solve_all(geom, theta, model.v_home)
    w = geom.w(np.asarray(theta, float))
    out = []
    for R in Rs:
        v = platform_axes(R, model.v_home)
        z = float(conditioning_index(model.u, v, w))
        d1 = np.linalg.det(j1_matrix(v, w)) * model.det_j1_sign
        d2 = j2_diag(model.u, v, w) * model.working_signs
        out.append(
            AssemblyMode(
                v=v, n=normal(v), zeta=z, residual=float(full_residual(geom, w, v)),
                home_connected=home_R is not None and float(np.abs(R - home_R).max()) < 1e-6,
                same_sides=bool(d1 > 0 and (d2 > 0).all()),
            )
        )
    out.sort(key=lambda m: -m.zeta)
    return out


def home_model(geom: SpmGeometry, theta_home_rad: F, sign_seed: F) -> SpmModel:
    """Build the :class:`SpmModel`: the home pose is the solution (either chirality)
    whose component signs agree best with the sign seed (eq. 33)."""
    base = geom.canonical_triad()
    mirror = base * np.array([-1.0, 1.0, 1.0])
    seed = np.asarray(sign_seed, float).reshape(3, 3)
    best: tuple[float, F] | None = None
    for ref in (base, mirror):
        for R in solve_all(geom, theta_home_rad, ref):
            v = platform_axes(R, ref)
            score = float((np.sign(np.round(v, 9)) * seed).sum() + 1e-3 * (v * seed).sum())
            if best is None or score > best[0]:
                best = (score, v)
    if best is None:
        raise ValueError("no forward-kinematic solution exists at the home configuration")
    v_home = best[1]
    w = geom.w(theta_home_rad)
    d1 = float(np.linalg.det(j1_matrix(v_home, w)))
    d2 = j2_diag(geom.u, v_home, w)
    if abs(d1) < 1e-9 or (np.abs(d2) < 1e-9).any():
        raise ValueError("the home configuration is singular")
    return SpmModel(
        geom=geom, theta_home=np.asarray(theta_home_rad, float), v_home=v_home,
        working_signs=np.sign(d2), det_j1_sign=float(np.sign(d1)),
    )


def _seeded_equations(geom: SpmGeometry, theta: F) -> tuple[F, F, float]:
    return geom.w(np.asarray(theta, float)), geom.cos_alpha2, geom.cos_alpha3


def seeded_solve(geom: SpmGeometry, theta: F, x0: F, method: str = "hybr") -> tuple[F, bool]:
    """The paper's Algorithm 1: solve (3)-(5) for the nine components of v from ``x0``.

    ``method="hybr"``: ``scipy.optimize.fsolve`` (MINPACK hybrid dogleg, like MATLAB's
    trust-region-dogleg); ``method="newton"``: plain undamped Newton (like the paper's
    Maple check). Returns (v as rows, converged).
    """
    w, c2, c3 = _seeded_equations(geom, theta)

    def eqs(x: F) -> F:
        v = x.reshape(3, 3)
        return np.concatenate(
            [
                (w * v).sum(-1) - c2,
                [v[0] @ v[1] - c3, v[0] @ v[2] - c3, v[1] @ v[2] - c3],
                (v * v).sum(-1) - 1.0,
            ]
        )

    def jac(x: F) -> F:
        v = x.reshape(3, 3)
        J = np.zeros((9, 9))
        for i in range(3):
            J[i, 3 * i : 3 * i + 3] = w[i]
            J[6 + i, 3 * i : 3 * i + 3] = 2 * v[i]
        for r, (i, j) in enumerate(((0, 1), (0, 2), (1, 2))):
            J[3 + r, 3 * i : 3 * i + 3] = v[j]
            J[3 + r, 3 * j : 3 * j + 3] = v[i]
        return J

    x = np.asarray(x0, float).copy()
    if method == "newton":
        for _ in range(100):
            f = eqs(x)
            if np.abs(f).max() < 1e-14:
                break
            try:
                x = x - np.linalg.solve(jac(x), f)
            except np.linalg.LinAlgError:
                break
            if not np.all(np.isfinite(x)):
                break
        ok = bool(np.all(np.isfinite(x)) and np.abs(eqs(x)).max() < 1e-9)
        return x.reshape(3, 3), ok
    from scipy.optimize import fsolve  # here: the paper's Algorithm 1 only (~0.7 s to import)

    x, _info, ier, _msg = fsolve(eqs, x, fprime=jac, full_output=True, xtol=1e-13)
    v = np.asarray(x).reshape(3, 3)
    return v, bool(ier == 1 and np.abs(eqs(x)).max() < 1e-9)
