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

from spm_console.core.kinematics.continuation import PATH_ZETA_FLOOR, continuation_step
from spm_console.core.kinematics.model import SpmModel, platform_axes

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
    dirs = np.asarray(_DIRS, np.int64)
    dims = np.asarray(shape, np.int64)
    new = np.array([s], np.int64)  # nodes validated by the last wave
    while True:
        # candidates: untried 6-neighbours of the nodes the last wave validated (those of
        # older valid nodes were tried before); parent: the valid neighbour with the largest
        # ζ, the first in _DIRS order on a tie
        ni = np.array(np.unravel_index(new, shape)).T
        nb = (ni[:, None, :] + dirs[None]).reshape(-1, 3)
        nb = nb[np.all((nb >= 0) & (nb < dims), axis=1)]
        flat = np.unique(np.ravel_multi_index(nb.T, shape))
        cand = flat[~tried[flat]]
        if len(cand) == 0:
            break
        waves += 1
        tried[cand] = True
        ci = np.array(np.unravel_index(cand, shape)).T
        around = ci[:, None, :] + dirs[None]  # (n, 6, 3)
        inside = np.all((around >= 0) & (around < dims), axis=2)
        fl = np.ravel_multi_index(tuple(np.clip(around, 0, dims - 1).reshape(-1, 3).T), shape)
        zn = np.where(inside & valid[fl].reshape(-1, 6), zeta[fl].reshape(-1, 6), -1.0)
        k = np.argmax(zn, axis=1)
        par = fl.reshape(-1, 6)[np.arange(len(cand)), k]
        st = continuation_step(model, TH[par], R[par], TH[cand])
        good = st.good(zeta_floor)
        z, Rc, rc = st.zeta, st.R, st.residual
        g = cand[good]
        R[g], zeta[g], res[g], valid[g] = Rc[good], z[good], rc[good], True
        new = g
        if progress is not None:
            progress(float(tried.sum()) / n_nodes)
    Rg = R.reshape(*shape, 3, 3)
    v = platform_axes(np.where(valid[:, None, None], R, np.nan), model.v_home).reshape(*shape, 3, 3)
    return GridFk(axes, Rg, v, zeta.reshape(shape), valid.reshape(shape), res.reshape(shape), waves)
