"""Unique FK over a whole θ grid by flood fill from home (continuation over neighbours).

Every node is solved once, seeded from an already-solved 6-neighbour (the best
conditioned one) by a first-order predictor and Newton corrector on (4). A node is
*valid* (may seed others) when it converged, kept the home's sign of det J1 and of
every J2 diagonal entry, and has ζ ≥ the floor. Nodes that can only be reached by
crossing a singularity stay unreached: their pose is NaN. No node is ever solved
independently from a fixed seed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.jacobian import conditioning_index, j1_matrix, j2_diag
from spm_console.core.kinematics import (
    PATH_ZETA_FLOOR,
    SpmModel,
    newton,
    orthonormalize,
    platform_axes,
)
from spm_console.core.rotations import expm_so3

F = NDArray[np.float64]
B = NDArray[np.bool_]

_DIRS = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]


@dataclass(frozen=True)
class GridFk:
    """FK of every grid node. Arrays are indexed [i1, i2, i3] like the axes."""

    axes: tuple[F, F, F]
    """Grid values of θ1, θ2, θ3, rad."""
    R: F
    """Platform rotations (M1, M2, M3, 3, 3); NaN where unreached."""
    v: F
    """Top axes (M1, M2, M3, 3, 3) rows v1..v3; NaN where unreached."""
    zeta: F
    """Conditioning index ζ; 0 where unreached."""
    reached: B
    """True where the home-mode solution was tracked to the node."""
    residual: F
    """Max |w·v − cos α2| per node (NaN where unreached)."""
    waves: int
    """Flood-fill waves used."""

    @property
    def shape(self) -> tuple[int, int, int]:
        return (len(self.axes[0]), len(self.axes[1]), len(self.axes[2]))

    def theta(self) -> F:
        """All node θ as (M1, M2, M3, 3), rad."""
        g = np.meshgrid(*self.axes, indexing="ij")
        return np.stack(g, -1)


def _shift(a: NDArray[np.generic], d: tuple[int, int, int], fill: object) -> NDArray[np.generic]:
    """out[x] = a[x + d] (neighbour in direction d), ``fill`` outside the grid."""
    out = np.full_like(a, fill)
    src = tuple(slice(max(k, 0), a.shape[i] + min(k, 0)) for i, k in enumerate(d))
    dst = tuple(slice(max(-k, 0), a.shape[i] + min(-k, 0)) for i, k in enumerate(d))
    out[dst] = a[src]
    return out


def track_grid(
    model: SpmModel,
    axes: tuple[F, F, F],
    zeta_floor: float = PATH_ZETA_FLOOR,
    progress: Callable[[float], None] | None = None,
) -> GridFk:
    """Flood-fill FK over the grid ``axes`` (rad) from the home pose."""
    shape = (len(axes[0]), len(axes[1]), len(axes[2]))
    n_nodes = shape[0] * shape[1] * shape[2]
    TH = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    R = np.full((n_nodes, 3, 3), np.nan)
    zeta = np.zeros(n_nodes)
    res = np.full(n_nodes, np.nan)
    valid = np.zeros(n_nodes, bool)
    tried = np.zeros(n_nodes, bool)

    # start: the node nearest home, tracked from home by continuation
    start = tuple(int(np.argmin(np.abs(a - t))) for a, t in zip(axes, model.theta_home, strict=True))
    s = int(np.ravel_multi_index(start, shape))
    r0 = model.track(TH[s])
    tried[s] = True
    if not r0.ok or r0.pose is None:
        return GridFk(axes, R.reshape(*shape, 3, 3), R.reshape(*shape, 3, 3), zeta.reshape(shape),
                      valid.reshape(shape), res.reshape(shape), 0)
    R[s], zeta[s], res[s], valid[s] = r0.pose.R, r0.pose.zeta, r0.pose.residual, True
    waves = 0
    u = model.u
    while True:
        V3 = valid.reshape(shape)
        Z3 = np.where(V3, zeta.reshape(shape), -1.0)
        best = np.full(shape, -1.0)
        parent_dir = np.full(shape, -1, int)
        for k, d in enumerate(_DIRS):
            zn = _shift(Z3, d, -1.0)
            better = zn > best
            best = np.where(better, zn, best)
            parent_dir = np.where(better, k, parent_dir)
        cand = np.flatnonzero((best.ravel() >= 0.0) & ~tried)
        if len(cand) == 0:
            break
        waves += 1
        tried[cand] = True
        ci = np.array(np.unravel_index(cand, shape)).T
        dirs = np.asarray(_DIRS)[parent_dir.ravel()[cand]]
        par = np.ravel_multi_index((ci + dirs).T, shape)
        th_p, th_c = TH[par], TH[cand]
        Rp = R[par]
        w_p = model.geom.w(th_p)
        v_p = platform_axes(Rp, model.v_home)
        rhs = j2_diag(u, v_p, w_p) * (th_c - th_p)
        with np.errstate(all="ignore"):
            om = np.linalg.solve(j1_matrix(v_p, w_p), rhs[..., None])[..., 0]
        Rpred = expm_so3(np.where(np.isfinite(om), om, 0.0)) @ Rp
        w_c = model.geom.w(th_c)
        Rc, rc = newton(model.geom, w_c, Rpred, model.v_home)
        Rc = orthonormalize(Rc)
        v_c = platform_axes(Rc, model.v_home)
        z = conditioning_index(u, v_c, w_c)
        d1 = np.linalg.det(j1_matrix(v_c, w_c)) * model.det_j1_sign
        d2 = j2_diag(u, v_c, w_c) * model.working_signs
        corr = np.linalg.norm(Rc - Rpred, axis=(-2, -1))
        good = (rc < 1e-10) & (corr < 0.05) & (d1 > 0) & (d2 > 0).all(-1) & (z >= zeta_floor)
        g = cand[good]
        R[g], zeta[g], res[g], valid[g] = Rc[good], z[good], rc[good], True
        if progress is not None:
            progress(float(tried.sum()) / n_nodes)
    Rg = R.reshape(*shape, 3, 3)
    v = platform_axes(np.where(valid[:, None, None], R, np.nan), model.v_home).reshape(*shape, 3, 3)
    return GridFk(axes, Rg, v, zeta.reshape(shape), valid.reshape(shape), res.reshape(shape), waves)
