"""Exact refinement on an active set: KKT solves with an optimality certificate.

Given a working set W of pool rows held at one of their bounds, solve the
equality-constrained QP exactly (sparse LU of the KKT matrix). If the result
satisfies every pool row and every multiplier of W has the right sign, the KKT
conditions hold and the point is optimal for the full problem (convex QP) — a
certificate independent of the solver that proposed W. Otherwise violated rows
join W and wrong-signed rows leave it, a few times, before giving up.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from spm_console.core.plan_report import Certificate
from spm_console.core.planning.qp_build import Equalities, Pool

F = NDArray[np.float64]
I = NDArray[np.int64]

#: Primal tolerance on pool rows (deg, deg/s) and relative tolerance on multipliers.
PRIMAL_TOL = 1e-9
DUAL_TOL = 1e-9
#: KKT regularization (primal σ, dual δ) removed by iterative refinement.
REG_PRIMAL = 1e-9
REG_DUAL = 1e-9
REFINE_STEPS = 12


@dataclass(frozen=True)
class WorkingSet:
    """Pool rows held at a bound: ``rows`` (pool indices) and ``side`` (+1 upper, −1 lower)."""

    rows: I
    side: I

    def usable(self, pool: Pool) -> WorkingSet:
        """The rows whose bound on their side is finite in ``pool`` (a row of a region the
        motion no longer visits at that sample has an infinite bound and cannot be held)."""
        rows = self.rows[self.rows < pool.m]
        side = self.side[self.rows < pool.m]
        bound = np.where(side > 0, pool.hi[rows], pool.lo[rows])
        keep = np.isfinite(bound)
        return WorkingSet(rows[keep], side[keep])


@dataclass
class ActiveSetResult:
    """Outcome of :func:`refine`."""

    ok: bool
    """True when the KKT conditions hold (optimal)."""
    z: F | None
    active: I = field(default_factory=lambda: np.zeros(0, np.int64))
    """Pool rows at a bound at the end."""
    side: I = field(default_factory=lambda: np.zeros(0, np.int64))
    """+1 at the upper bound, −1 at the lower bound."""
    multipliers: F = field(default_factory=lambda: np.zeros(0))
    solves: int = 0
    max_violation: float = np.inf
    """Largest pool-row violation at z (normalized units)."""
    min_dual: float = -np.inf
    """Smallest sign-corrected multiplier over W, relative to the largest (≥ −tol when ok)."""
    certificate: Certificate | None = None
    """A Farkas certificate of infeasibility, when the method found one (checked: see
    :attr:`Certificate.valid`)."""


def eqp(eq: Equalities, pool: Pool, active: I, side: I) -> tuple[F, F] | None:
    """Minimize ½zᵀPz subject to the equalities and W at its bounds; (z, multipliers of W).

    The KKT matrix is factored with a tiny regularization ([[P + σI, Cᵀ], [C, −δI]] is
    quasi-definite, so the factorization exists even when rows of W are redundant), and
    iterative refinement removes its effect. None when the system has no solution
    (W over-determined or inconsistent).
    """
    n = eq.layout.n
    Cw = pool.rows(active)
    m = eq.C.shape[0] + Cw.shape[0]
    if m > n:
        return None
    rhs_w = np.where(side > 0, pool.hi[active], pool.lo[active])
    # K = [[P, Cᵀ], [C, 0]] assembled from triplets (much cheaper than sparse.bmat)
    Pc = eq.P.tocoo()
    Cc = sp.vstack([eq.C, Cw], format="coo") if Cw.shape[0] else eq.C.tocoo()
    diag = np.arange(n + m)
    rows = np.concatenate([Pc.row, Cc.row + n, Cc.col, diag])
    cols = np.concatenate([Pc.col, Cc.col, Cc.row + n, diag])
    regv = np.concatenate([np.full(n, REG_PRIMAL), np.full(m, -REG_DUAL)])
    vals = np.concatenate([Pc.data, Cc.data, Cc.data])
    Kr = sp.csc_matrix((np.concatenate([vals, regv]), (rows, cols)), shape=(n + m, n + m))

    def residual(x: F) -> F:  # rhs − K x, with K = Kr less its regularization diagonal
        return np.asarray(rhs - (Kr @ x - regv * x))

    rhs = np.concatenate([np.zeros(n), eq.d, rhs_w])
    try:
        lu = spla.splu(Kr, permc_spec="COLAMD")
    except RuntimeError:
        return None
    sol = lu.solve(rhs)
    scale = max(1.0, float(np.abs(rhs).max()))
    for _ in range(REFINE_STEPS):
        res = residual(sol)
        if float(np.abs(res).max()) <= 1e-12 * scale:
            break
        sol = sol + lu.solve(res)
    res = residual(sol)
    if not np.all(np.isfinite(sol)) or float(np.abs(res).max()) > 1e-9 * scale:
        return None
    return sol[:n], sol[n + eq.C.shape[0]:]


def violations(pool: Pool, z: F, act: I, sd: I) -> tuple[F, F]:
    """(upper, lower) normalized violations of every pool row at z (> 0 = violated); the rows
    of W = (act, sd) are −∞ on their side (held with equality by construction)."""
    gz = pool.values(z)
    with np.errstate(invalid="ignore"):
        up = (gz - pool.hi) / pool.scale
        dn = (pool.lo - gz) / pool.scale
    up[act[sd > 0]] = -np.inf
    dn[act[sd < 0]] = -np.inf
    return up, dn


def kkt_verdict(z: F, act: I, sd: I, lam: F, solves: int, up: F, dn: F) -> ActiveSetResult:
    """The KKT check at z with W = (act, sd) held and multipliers ``lam`` of g z = bound: every
    pool row met to :data:`PRIMAL_TOL` (``up``, ``dn`` from :func:`violations`) and every
    multiplier of W of its side's sign to :data:`DUAL_TOL` of the largest — optimal then."""
    viol = np.maximum(up, dn)
    maxv = float(viol.max()) if viol.size else 0.0
    mind = float((lam * sd).min() / _lam_ref(lam)) if lam.size else 0.0
    ok = maxv <= PRIMAL_TOL and not wrong_signed(lam, sd).any()
    return ActiveSetResult(ok, z, act, sd, lam, solves, maxv, mind)


def _lam_ref(lam: F) -> float:
    return max(1.0, float(np.abs(lam).max())) if lam.size else 1.0


def wrong_signed(lam: F, sd: I) -> NDArray[np.bool_]:
    """The rows of W whose multiplier has the wrong sign for their side by more than
    :data:`DUAL_TOL` of the largest (they leave W; a NaN multiplier counts as wrong)."""
    return np.asarray(~(lam * sd >= -DUAL_TOL * _lam_ref(lam)))


def refine(eq: Equalities, pool: Pool, active: I | None = None, side: I | None = None,
           max_solves: int = 8) -> ActiveSetResult:
    """Active-set iterations from W = (active, side); see the module docstring."""
    act = np.zeros(0, np.int64) if active is None else np.asarray(active, np.int64)
    sd = np.zeros(0, np.int64) if side is None else np.asarray(side, np.int64)
    last: ActiveSetResult = ActiveSetResult(False, None)
    for it in range(1, max_solves + 1):
        out = eqp(eq, pool, act, sd)
        if out is None:
            return ActiveSetResult(False, last.z, act, sd, solves=it)
        z, lam = out
        up, dn = violations(pool, z, act, sd)
        last = kkt_verdict(z, act, sd, lam, it, up, dn)
        if last.ok:
            return last
        # violated rows join W, wrong-signed rows leave it
        bad_p = np.flatnonzero(np.maximum(up, dn) > PRIMAL_TOL)
        keep = ~wrong_signed(lam, sd)
        new_side = np.where(up[bad_p] > dn[bad_p], 1, -1)
        act = np.concatenate([act[keep], bad_p])
        sd = np.concatenate([sd[keep], new_side])
    return last
