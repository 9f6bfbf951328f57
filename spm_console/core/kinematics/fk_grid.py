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
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.component_ops import C
from spm_console.core.kinematics.continuation import PATH_ZETA_FLOOR, Kernel, Local
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
    v_home: F
    """The top axes at home (3, 3), rows v1⁰..v3⁰ (:attr:`v` turns them by R)."""
    zeta: F
    """Conditioning index ζ; 0 where unreached."""
    reached: B
    """True where the home-mode solution was tracked to the node."""
    residual: F
    """Max |w·v − cos α2| per node (NaN where unreached)."""
    waves: int
    """Flood-fill waves used."""

    @cached_property
    def v(self) -> F:
        """Top axes (M1, M2, M3, 3, 3) rows v1..v3, v_i = R v_i⁰; NaN where unreached
        (computed when first read: the workspace build takes them of the reached nodes
        only)."""
        return platform_axes(self.R, self.v_home)

    @property
    def shape(self) -> tuple[int, int, int]:
        return (len(self.axes[0]), len(self.axes[1]), len(self.axes[2]))

    def theta(self) -> F:
        """All node θ as (M1, M2, M3, 3), rad."""
        g = np.meshgrid(*self.axes, indexing="ij")
        return np.stack(g, -1)


def neighbour_table(shape: tuple[int, int, int]) -> NDArray[np.int64]:
    """(n_nodes, 6) flat indices of every node's 6-neighbours in ``_DIRS`` order, −1 where
    the neighbour lies outside the grid."""
    idx = np.arange(shape[0] * shape[1] * shape[2], dtype=np.int64).reshape(shape)
    out = np.full((*shape, 6), -1, np.int64)
    for d, step in enumerate(_DIRS):
        # node p's neighbour in direction d is p + step, where that lies inside the grid
        at: tuple[slice, ...] = tuple(slice(max(-k, 0), n - max(k, 0)) for k, n in zip(step, shape, strict=True))
        nb: tuple[slice, ...] = tuple(slice(max(k, 0), n - max(-k, 0)) for k, n in zip(step, shape, strict=True))
        key: tuple[slice | int, ...] = (*at, d)
        out[key] = idx[nb]
    return out.reshape(-1, 6)


def _local_rows(at: Local) -> list[C]:
    """The 22 component arrays of a step's Jacobians (w, adj(J1)'s columns, det J1, J2's
    diagonal), in one order."""
    return [*(x for v in at.w for x in v), *(x for v in at.cols for x in v), at.det, *at.j2]


def _local_of(rows: F) -> Local:
    """:func:`_local_rows` back: a (22, n) array → :class:`Local` of its rows (views)."""
    return Local([list(rows[0:3]), list(rows[3:6]), list(rows[6:9])],
                 [list(rows[9:12]), list(rows[12:15]), list(rows[15:18])], rows[18],
                 list(rows[19:22]))


def track_grid(
    model: SpmModel,
    axes: tuple[F, F, F],
    zeta_floor: float = PATH_ZETA_FLOOR,
    progress: Callable[[float], None] | None = None,
) -> GridFk:
    """Flood-fill FK over the grid ``axes`` (rad) from the home pose.

    The nodes' state is kept as component rows (θ (3, n); R and the Jacobians each validated
    node's step computed, (9 + 22, n)), so a wave gathers its parents' rows at once and steps
    them without recomputing their Jacobians (the predictor's J1, J2 at the parent)."""
    shape = (len(axes[0]), len(axes[1]), len(axes[2]))
    n_nodes = shape[0] * shape[1] * shape[2]
    TH = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    TH3 = np.ascontiguousarray(TH.T)
    S = np.zeros((31, n_nodes))  # rows 0-8: R (NaN where not valid); 9-30: the Jacobians
    S[:9] = np.nan
    zeta = np.zeros(n_nodes)
    res = np.full(n_nodes, np.nan)
    valid = np.zeros(n_nodes, bool)
    tried = np.zeros(n_nodes, bool)

    def result(waves: int) -> GridFk:
        R = np.ascontiguousarray(S[:9].T).reshape(*shape, 3, 3)
        return GridFk(axes, R, np.asarray(model.v_home, float), zeta.reshape(shape),
                      valid.reshape(shape), res.reshape(shape), waves)

    # start: the node nearest home, tracked from home by continuation
    start = tuple(int(np.argmin(np.abs(a - t))) for a, t in zip(axes, model.theta_home, strict=True))
    s = int(np.ravel_multi_index(start, shape))
    r0 = model.track(TH[s])
    tried[s] = True
    if not r0.ok or r0.pose is None:
        return result(0)
    kern = Kernel(model)
    S[:9, s] = np.asarray(r0.pose.R, float).reshape(9)
    zeta[s], res[s], valid[s] = r0.pose.zeta, r0.pose.residual, True
    R0 = S[:9, s:s + 1]
    S[9:, s:s + 1] = np.array(_local_rows(kern.modes(kern.w(list(TH3[:, s:s + 1])),
                                                     [list(R0[0:3]), list(R0[3:6]), list(R0[6:9])])[3]))
    waves = 0
    nbr = neighbour_table(shape)
    # w_i(θ_i) (eq. 2) of every value on axis i, (3, M_i), and each node's index on each axis
    w_axis = [np.array(x) for x in kern.w(list(axes))]
    at_axis = np.indices(shape).reshape(3, -1)
    # ζ of valid nodes, −1 elsewhere and in the last slot (so a missing neighbour, −1, reads −1)
    z_valid = np.full(n_nodes + 1, -1.0)
    z_valid[s] = zeta[s]
    mark = np.zeros(n_nodes, bool)
    new = np.array([s], np.int64)  # nodes validated by the last wave
    while True:
        # candidates: untried 6-neighbours of the nodes the last wave validated (those of
        # older valid nodes were tried before), in index order; parent: the valid neighbour
        # with the largest ζ, the first in _DIRS order on a tie
        nb = nbr[new].reshape(-1)
        nb = nb[nb >= 0]
        mark[nb[~tried[nb]]] = True
        cand = np.flatnonzero(mark)
        mark[cand] = False
        if len(cand) == 0:
            break
        waves += 1
        tried[cand] = True
        fl = nbr[cand]  # (n, 6)
        par = fl[np.arange(len(cand)), np.argmax(z_valid[fl], axis=1)]
        Sp = S[:, par]
        st = kern.step(list(TH3[:, par]), [list(Sp[0:3]), list(Sp[3:6]), list(Sp[6:9])],
                       list(TH3[:, cand]), at_old=_local_of(Sp[9:]),
                       w_new=[list(w_axis[i][:, at_axis[i, cand]]) for i in range(3)])
        good = st.good(zeta_floor)
        S[:, cand] = np.stack([*(x for row in st.R for x in row), *_local_rows(st.at)])
        if not good.all():  # the rejected nodes' columns back to unreached
            bad = cand[~good]
            S[:9, bad] = np.nan
            S[9:, bad] = 0.0
        g = cand[good]
        zeta[g] = np.asarray(st.zeta)[good]
        z_valid[g] = zeta[g]
        res[g] = np.asarray(st.residual)[good]
        valid[g] = True
        new = g
        if progress is not None:
            progress(float(tried.sum()) / n_nodes)
    return result(waves)
