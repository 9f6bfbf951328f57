"""The follow QP's optimum from the previous active set, certified without a solver.

The condensed QP (:mod:`spm_console.core.planning.follow.dense`) is

    min ½ zᵀ H z + fᵀ z   s.t.   lo ≤ z ≤ hi (simple bounds),   lo′ ≤ A z ≤ hi′,

with H positive definite and only f and the bounds changing from one period to the next.
Between two periods the rows held at a bound are most often the same ones (the terminal
rows, θ̇(H) = 0, a face the wrist follows). For such a set W of rows, each held at one of
its bounds b_W, the stationary point of the Lagrangian on W is

    z = z₀ − H⁻¹ A_Wᵀ λ,   z₀ = −H⁻¹ f,   (A_W H⁻¹ A_Wᵀ) λ = A_W z₀ − b_W.

If every row is then met (within :data:`PRIMAL_TOL`), every multiplier has its bound's sign
(λ ≥ 0 at an upper bound, λ ≤ 0 at a lower one, either for an equality) and H z + f + A_Wᵀλ
vanishes to round-off (:data:`STATIONARY_REL`), z satisfies the KKT conditions of this convex
QP: it *is* the optimum, the one a solver returns. Otherwise
nothing is claimed and the caller solves (DAQP, warm-started from W). The rows are evaluated
through the model's responses (:meth:`DenseFollow.rows_of`), not the (m, n) matrix, so a
certified answer costs a few small products where a solver reads every row twice.

DAQP's multipliers have this sign convention (H z + f + Aᵀλ = 0), so its answer's nonzero
multipliers give W and each row's side.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.follow.dense import EQUALITY, DenseFollow

F = NDArray[np.float64]
I = NDArray[np.int64]

#: A row counts as met within this of its bound (deg, deg/s): DAQP's own primal tolerance.
PRIMAL_TOL = 1e-6
#: Most solves of (A_W H⁻¹ A_Wᵀ) δλ = A_W z − b_W (the first, then iterative refinement)
#: and the miss of the kept rows that ends them, deg.
REFINE_STEPS = 8
REFINED_DEG = 1e-10
#: Largest ‖H z + f + A_Wᵀ λ‖∞ accepted, relative to the largest of its terms (measured on the
#: follow benchmark's loop: 1e-15).
STATIONARY_REL = 1e-9
#: A multiplier of the wrong sign by at most this counts as zero (a row just at its bound).
DUAL_TOL = 1e-9


class KeptActiveSet:
    """The rows active at the last optimum of one :class:`DenseFollow`, and the check that
    they are still the active ones for a new cost and new bounds."""

    def __init__(self, dense: DenseFollow) -> None:
        self.dense = dense
        self._h_inv = np.linalg.inv(dense.H_cost)
        self._rows: I = np.zeros(0, np.int64)
        """Indices into the bounds (simple bounds first, then the general rows)."""
        self._upper: NDArray[np.bool_] = np.zeros(0, bool)
        self._a_w: F = np.zeros((0, dense.n))
        self._g: F = np.zeros((dense.n, 0))
        self._s_inv: F | None = None

    @property
    def known(self) -> bool:
        """Whether an active set is kept (the last answer was an optimum with one)."""
        return self._s_inv is not None

    def forget(self) -> None:
        self._s_inv = None

    def keep(self, multipliers: F) -> None:
        """Keep the rows with a nonzero multiplier of a solver's optimum (DAQP's ``lam``:
        simple bounds first) and their sides; an active set that is not of full rank is
        not kept."""
        rows = np.flatnonzero(multipliers)
        self._hold(rows, multipliers[rows] > 0.0)

    def reached(self) -> None:
        """Keep the active set of a target reached and held: θ̇(H) = 0 and both terminal
        rows of each joint at their lower bound (θ(H) = t, slacks 0). It is the answer's
        active set whenever nothing else binds, so a first solve needs no solver either."""
        d = self.dense
        n, t0 = d.n, d.rows_terminal
        equality = np.flatnonzero(d.sense[n:] == EQUALITY)
        rows = np.concatenate([equality, np.arange(t0, t0 + 6)]) + n
        self._hold(rows, np.zeros(len(rows), bool))

    def shift(self, samples: int) -> bool:
        """Move the kept rows ``samples`` samples earlier, as the previous answer's own rows
        are one period later (a bound held at sample k is held at k − 1 now; rows before the
        first sample leave; θ̇(H) = 0 and the terminal rows stay). False when that changes
        nothing (no row is tied to a sample)."""
        d = self.dense
        n = d.n
        rows, upper = self._rows, self._upper
        keep = np.ones(len(rows), bool)
        out = rows.copy()
        # (first row, past the last shifted row, rows per sample) of each family
        per_joint = 3 * samples
        families = [(0, 3 * d.H, per_joint),
                    (n + d.rows_speed.start, n + d.rows_speed.stop - 3, per_joint),
                    (n + d.rows_step.start, n + d.rows_step.stop, per_joint),
                    (n + d.rows_lead.start, n + d.rows_lead.stop, per_joint),
                    (n + d.rows_region.start, n + d.rows_region.stop,
                     d.region_A.shape[0] * samples)]
        moved = False
        for start, stop, by in families:
            inside = (rows >= start) & (rows < stop)
            if inside.any():
                moved = True
                out[inside] -= by
                keep[inside & (out < start)] = False
        if not moved:
            return False
        self._hold(out[keep], upper[keep])
        return True

    def _hold(self, rows: I, upper: NDArray[np.bool_]) -> None:
        self._rows = rows
        self._upper = upper
        n = self.dense.n
        a_w = np.zeros((len(rows), n))
        simple = rows < n
        a_w[np.flatnonzero(simple), rows[simple]] = 1.0
        a_w[~simple] = self.dense.A[rows[~simple] - n]
        self._a_w = a_w
        self._g = self._h_inv @ a_w.T
        try:  # S⁻¹ once per active set: each solve then multiplies by it (S is |W| × |W|)
            L = np.linalg.cholesky(a_w @ self._g) if len(rows) else np.zeros((0, 0))
            L_inv = np.linalg.inv(L) if len(rows) else L
            self._s_inv = np.asarray(L_inv.T @ L_inv, float)
        except np.linalg.LinAlgError:
            self._s_inv = None

    def optimum(self, f: F, lo: F, hi: F) -> F | None:
        """The QP's optimum for the cost ``f`` and the bounds (lo, hi) (simple bounds first)
        when the kept rows are its active set (the KKT conditions hold), else None."""
        s_inv = self._s_inv
        if s_inv is None:
            return None
        z0 = -(self._h_inv @ f)
        rows, upper = self._rows, self._upper
        if len(rows):
            b_w = np.where(upper, hi[rows], lo[rows])
            if not np.isfinite(b_w).all():
                return None
            lam = np.zeros(len(rows))
            z = z0
            for _ in range(REFINE_STEPS):  # the slacks' tiny weight makes S ill-conditioned
                miss = self._a_w @ z - b_w
                if np.abs(miss).max() <= REFINED_DEG:
                    break
                lam += s_inv @ miss
                z = z0 - self._g @ lam
            equality = lo[rows] == hi[rows]
            signed = np.where(upper, lam, -lam)
            if np.any((signed < -DUAL_TOL) & ~equality):
                return None
            pull = self._a_w.T @ lam
        else:
            z, pull = z0, np.zeros_like(z0)
        # stationarity, H z + f + A_Wᵀ λ = 0, to round-off (z is built to meet it through H⁻¹)
        grad = self.dense.H_cost @ z
        scale = max(float(np.abs(f).max()), float(np.abs(pull).max()), float(np.abs(grad).max()))
        if float(np.abs(grad + f + pull).max()) > STATIONARY_REL * max(scale, 1.0):
            return None
        values = np.concatenate([z, self.dense.rows_of(z)])
        if np.any(values > hi + PRIMAL_TOL) or np.any(values < lo - PRIMAL_TOL):
            return None
        if len(rows) and np.abs(values[rows] - b_w).max() > PRIMAL_TOL:
            return None
        return np.asarray(z)
