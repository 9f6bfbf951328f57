"""Targets of live following: the nearest admissible point (L2) of an outside target.

The admissible set is the region A θ ≤ b tightened by ``margin_deg`` (as the follow QP sees
it) intersected with the servo limits box lo ≤ θ ≤ hi; θ in degrees.
"""

from __future__ import annotations

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.optimize import nnls

from spm_console.core.polytope.region import Region
from spm_console.errors import InfeasibleError
from spm_console.formatting import fmt_deg

F = NDArray[np.float64]
B = NDArray[np.bool_]


class ProjectionError(InfeasibleError):
    """The nearest admissible point of a target was not found: the target is refused (the
    wrist is never sent to a substitute point)."""


#: Largest move of the QP's answer onto the exactly admissible set, deg (its tolerance is
#: 1e-7: a larger move means the answer was not the projection).
PULL_TOL_DEG = 1e-3
#: A constraint within this of its bound counts as active at the projection, deg.
ACTIVE_TOL_DEG = 1e-5
#: Largest residual of the optimality certificate, relative to the distance moved.
CERTIFY_RTOL = 1e-6


class TargetProjector:
    """Projection onto {θ : A θ ≤ b − margin·‖A_r‖, lo ≤ θ ≤ hi} by a 3-variable QP."""

    def __init__(self, region: Region, lo_deg: F, hi_deg: F, margin_deg: float) -> None:
        norms = np.linalg.norm(region.A, axis=1)
        self.A = np.asarray(region.A, float)
        self.b = np.asarray(region.b - margin_deg * norms, float)
        self.lo = np.asarray(lo_deg, float)
        self.hi = np.asarray(hi_deg, float)
        rows = [self.A]
        rhs = [self.b]
        for i in range(3):  # finite limits as half-spaces, for the interior point
            e = np.eye(3)[i]
            if np.isfinite(self.hi[i]):
                rows.append(e[None])
                rhs.append(self.hi[i: i + 1])
            if np.isfinite(self.lo[i]):
                rows.append(-e[None])
                rhs.append(-self.lo[i: i + 1])
        centre, radius = Region(np.vstack(rows), np.concatenate(rhs)).chebyshev()
        if not radius > 0:
            raise InfeasibleError("the region and the servo limits leave no room to follow a target in")
        self.centre = centre
        # every constraint as G θ ≤ h, and the level above which one counts as active (for
        # the optimality certificate of :meth:`_nearest`; built once, used per projection)
        self._G = np.vstack([self.A, np.eye(3), -np.eye(3)])
        self._h_active = (np.concatenate([self.b, self.hi, -self.lo])
                          - ACTIVE_TOL_DEG * np.linalg.norm(self._G, axis=1))
        G = sp.vstack([sp.csc_matrix(self.A), sp.eye(3, format="csc")], format="csc")
        self._qp = osqp.OSQP()
        self._qp.setup(sp.eye(3, format="csc") * 2.0, np.zeros(3), G,
                       np.concatenate([np.full(self.A.shape[0], -np.inf), self.lo]),
                       np.concatenate([self.b, self.hi]),
                       verbose=False, eps_abs=1e-7, eps_rel=1e-7, polishing=True,
                       max_iter=20000, adaptive_rho_interval=25)

    def admissible(self, theta_deg: F) -> B:
        """True where θ (..., 3) lies in the admissible set."""
        t = np.asarray(theta_deg, float)
        inside = (t @ self.A.T <= self.b).all(-1)
        return np.asarray(inside & (t >= self.lo).all(-1) & (t <= self.hi).all(-1))

    def project(self, target_deg: F) -> tuple[F, float]:
        """(nearest admissible point, distance moved in deg); the target itself if admissible.

        :class:`ProjectionError` when the QP finds no answer (a target absurdly far away):
        never a substitute point such as the region's centre."""
        t = np.asarray(target_deg, float).reshape(3)
        if bool(self.admissible(t)):
            return t.copy(), 0.0
        self._qp.update(q=-2.0 * t)
        res = self._qp.solve(raise_error=False)
        status = str(res.info.status)
        x = np.asarray(res.x, float)
        if status != "solved" or x.shape != (3,) or not np.all(np.isfinite(x)):
            raise ProjectionError(f"the target θ = {fmt_deg(t)} is refused: its nearest point in "
                                  f"the region was not found (projection {status})")
        y = self._pull_inside(x)
        if y is None or float(np.abs(y - x).max()) > PULL_TOL_DEG or not self._nearest(y, t):
            raise ProjectionError(f"the target θ = {fmt_deg(t)} is refused: the projection's "
                                  "answer is not the nearest admissible point")
        return y, float(np.linalg.norm(y - t))

    def _nearest(self, y: F, t: F) -> bool:
        """Certificate that the admissible ``y`` is the nearest point to ``t``: t − y lies in the
        normal cone of the constraints active at y (non-negative multipliers, by NNLS). A
        solver's "solved" is relative to the size of the target; this is not."""
        G, h_active = self._G, self._h_active
        active = G @ y >= h_active
        r = t - y
        if not active.any():
            return False  # t is outside but y touches nothing: not the projection
        _, resid = nnls(G[active].T, r)
        return bool(resid <= CERTIFY_RTOL * max(1.0, float(np.linalg.norm(r))))

    def _pull_inside(self, x: F) -> F | None:
        """x moved toward the interior point just enough to be admissible (exactly); None
        when even that fails."""
        if bool(self.admissible(x)):
            return x
        c = self.centre
        d = x - c
        # largest s in [0, 1] with c + s d admissible
        s = 1.0
        ad = self.A @ d
        slack = self.b - self.A @ c
        pos = ad > 0
        if pos.any():
            s = min(s, float((slack[pos] / ad[pos]).min()))
        for i in range(3):
            if d[i] > 0 and np.isfinite(self.hi[i]):
                s = min(s, (self.hi[i] - c[i]) / d[i])
            if d[i] < 0 and np.isfinite(self.lo[i]):
                s = min(s, (self.lo[i] - c[i]) / d[i])
        y = c + max(0.0, s * (1.0 - 1e-12)) * d
        return y if bool(self.admissible(y)) else None
