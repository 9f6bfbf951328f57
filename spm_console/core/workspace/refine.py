"""Certification refined near the boundary: the grid's P′ at a finer resolution, on demand.

The grid certifies θ when every grid node within L∞ distance < Δ of it is feasible
(:mod:`spm_console.core.workspace.certify`): near an infeasible node that excludes a whole cube of
half-width Δ, although most of it is usually feasible. Here the same criterion is applied
at the resolution h = Δ / :data:`REFINE` of the *fine lattice* (the grid refined
:data:`REFINE` times per axis, same box), only where it is needed:

θ is **certified** when the grid certifies it, **or** θ lies in the grid box and every
fine node within L∞ distance < h of it (at most 8) is exactly feasible.

A fine node is exactly feasible when it passes the workspace's exact checks
(:func:`~spm_console.core.workspace.check.check_points`: FK continued from a
home-connected feasible grid node of its cell in the home assembly and working modes,
ζ ≥ ζ_min, links ≥ 2δ apart). Verdicts are memoized by integer fine index; fine nodes that
are grid nodes take the grid's verdict. The continuation takes as few steps as keep each
step ≤ :data:`~spm_console.core.workspace.check.STEP_RAD` in every joint, counted from the
point's own distance to its start node
(:func:`~spm_console.core.workspace.check.own_steps`), so a verdict never depends on which
other points were evaluated with it: the planner and the runtime (another process, from the
same workspace) reach the same verdicts.

Angles in degrees at this interface.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.workspace.certify import CertifiedSet, nodes_near
from spm_console.core.workspace.check import check_points, exact_ok, own_steps
from spm_console.core.workspace.rowmap import RowMap, serial

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]
I64 = NDArray[np.int64]

#: Fine nodes per grid step and axis: resolution h = Δ / REFINE (Δ/4 or finer).
REFINE = 4
#: Version of the fine verdicts (part of the refined cover's cache key): 2 = continuation
#: steps counted per point (:func:`~spm_console.core.workspace.check.own_steps`).
VERDICTS_VERSION = 2
#: Verdict codes of the memo table.
_UNKNOWN, _INFEASIBLE, _FEASIBLE = -1, 0, 1


class FineGrid:
    """Memoized exact verdicts of the fine lattice of a workspace (θ in degrees)."""

    def __init__(self, ws: Workspace, refine: int = REFINE, rowmap: RowMap = serial) -> None:
        """``rowmap`` runs the exact checks (:mod:`spm_console.core.workspace.rowmap`)."""
        if refine < 4:
            raise ValueError(f"refinement {refine} must be at least 4 (h ≤ Δ/4)")
        self.ws = ws
        self.model, self.links = ws.exact_models()
        self.refine = int(refine)
        self.step_deg = float(ws.step_deg) / self.refine
        """Fine resolution h, deg."""
        self.origin_deg = np.array([a[0] for a in ws.axes_deg], float)
        self.shape = tuple((n - 1) * self.refine + 1 for n in ws.shape)
        self._verdict = np.full(self.shape, _UNKNOWN, np.int8)
        r = self.refine
        self._verdict[::r, ::r, ::r] = np.where(ws.feasible, _FEASIBLE, _INFEASIBLE)
        self.evaluated = 0
        """Fine nodes checked exactly so far (grid nodes and repeats not counted)."""
        self._rowmap = rowmap
        self._exact = partial(exact_ok, ws, self.model, self.links)

    def theta_deg(self, idx: I64) -> F:
        """θ (deg) of fine nodes (…, 3)."""
        return np.asarray(self.origin_deg + np.asarray(idx, float) * self.step_deg)

    def on_lattice(self, idx: I64) -> B:
        return np.asarray(np.all((idx >= 0) & (idx < np.array(self.shape)), axis=-1))

    def verdicts(self, idx: I64) -> B:
        """Exact feasibility of fine nodes (…, 3) on the lattice, evaluated once each."""
        idx = np.asarray(idx, np.int64)
        flat: I64 = np.asarray(np.ravel_multi_index(tuple(idx.reshape(-1, 3).T), self.shape),
                               np.int64)
        table = self._verdict.reshape(-1)
        todo = np.unique(flat[table[flat] == _UNKNOWN])
        if len(todo):
            pts = self.theta_deg(np.column_stack(np.unravel_index(todo, self.shape)))
            ok = self._rowmap(self._exact, pts)
            table[todo] = np.where(ok, _FEASIBLE, _INFEASIBLE)
            self.evaluated += len(todo)
        return np.asarray(table[flat] == _FEASIBLE).reshape(idx.shape[:-1])

    def cubes(self, centres_deg: F, half_nodes: int) -> I64:
        """Fine nodes (m, 3), each once, of the closed cubes of half-width ``half_nodes`` fine
        steps around points that are fine nodes (grid nodes, say), clipped to the lattice."""
        if len(centres_deg) == 0:
            return np.zeros((0, 3), np.int64)
        c = np.rint((np.asarray(centres_deg, float) - self.origin_deg) / self.step_deg)
        k = np.arange(-half_nodes, half_nodes + 1)
        offs = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3)
        idx = (c.astype(np.int64)[:, None, :] + offs[None]).reshape(-1, 3)
        idx = idx[self.on_lattice(idx)]
        flat = np.unique(np.ravel_multi_index(tuple(idx.T), self.shape))
        return np.column_stack(np.unravel_index(flat, self.shape)).astype(np.int64)

    def reason(self, idx: I64) -> str:
        """Why one fine node (3,) fails the exact checks, in words."""
        th = self.theta_deg(np.asarray(idx).reshape(1, 3))
        pc = check_points(self.ws, self.model, self.links, th,
                          steps=int(own_steps(self.ws, th)[0]))
        if pc.pointwise_ok(self.ws.zeta_min, self.ws.min_distance_mm)[0] and not pc.start_feasible[0]:
            return "not continued from a home-connected feasible grid node of its cell"
        return pc.reason(0, self.ws.zeta_min, self.ws.min_distance_mm, self.links)


@dataclass(frozen=True)
class RefinedCertifiedSet(CertifiedSet):
    """The grid's certified set, extended by the fine criterion (module docstring)."""

    fine: FineGrid | None = field(default=None, compare=False, repr=False)

    @classmethod
    def of(cls, ws: Workspace, refine: int = REFINE) -> RefinedCertifiedSet:
        base = ws.certified_set()
        return cls(base.feasible, base.origin_deg, base.step_deg, FineGrid(ws, refine))

    @property
    def resolution_deg(self) -> float:
        """The fine resolution h, deg."""
        return self.step_deg if self.fine is None else self.fine.step_deg

    def contains(self, theta_deg: F, half_width_deg: float | None = None) -> B:
        """Which points (…, 3) are certified. ``half_width_deg`` ∈ (Δ/2, Δ] relaxes the grid
        criterion (see :meth:`CertifiedSet.contains`); the fine criterion is relaxed in the
        same proportion (half-width h·half_width_deg/Δ)."""
        coarse = super().contains(theta_deg, half_width_deg)
        if self.fine is None or coarse.all():
            return coarse
        th = np.asarray(theta_deg, float).reshape(-1, 3)
        flat_ok = coarse.reshape(-1).copy()
        rest = np.flatnonzero(~flat_ok)
        ratio = 1.0 if half_width_deg is None else float(half_width_deg) / self.step_deg
        fg = self.fine
        near = nodes_near(th[rest], fg.origin_deg, fg.step_deg, fg.shape, ratio)
        use = near.needed & near.inside & near.finite[:, None]
        verdict = np.zeros(use.shape, bool)
        if use.any():
            verdict[use] = fg.verdicts(near.index[use])
        flat_ok[rest] = near.all_hold(verdict)
        return flat_ok.reshape(coarse.shape)
