"""The receding-horizon QP of live following: a fixed sparsity pattern, vectors per solve.

Units: θ, θ* in degrees; θ̇ in deg/s; H samples of Ts seconds.

Variables, one block of nine per sample k = 1..H, then three slacks::

    z = [θ*(0), θ(1), θ̇(1), θ*(1), θ(2), θ̇(2), …, θ*(H−1), θ(H), θ̇(H), s]

(θ*(k−1) is the reference that leads from sample k−1 to sample k.) The current state
θ(0), θ̇(0) is data: it enters only the right-hand side of the first dynamics rows.

Rows, one block of 18 + n_r per sample k = 1..H, then nine terminal rows::

    dynamics  θ(k) − a θ(k−1) − b θ̇(k−1) − b₀ θ*(k−1) = 0      (3 rows, k = 1: = a θ(0) + b θ̇(0))
              θ̇(k) − c θ(k−1) − d θ̇(k−1) − b₁ θ*(k−1) = 0      (3 rows, k = 1: = c θ(0) + d θ̇(0))
    speed     −v ≤ θ̇(k) ≤ v                                   (3 rows; k = H: 0 ≤ θ̇(H) ≤ 0, rest)
    reference lo ≤ θ*(k−1) ≤ hi                                (3 rows)
    step      |θ*(k−1) − θ*(k−2)| ≤ S                          (3 rows; k = 1: from the reference
                                                                in use, data)
    lead      |θ*(k−1) − θ(k−1)| ≤ L (the linear range)        (3 rows; k = 1: from θ(0), data;
                                                                ±∞ without a linear range)
    region    A θ(k) ≤ b − margin·‖A_r‖                        (n_r rows)
    terminal  s − θ(H) ≥ −t,  s + θ(H) ≥ t                     (6 rows: s ≥ |θ(H) − t|)
              lo ≤ θ(H) ≤ hi                                   (3 rows: θ(H) may be held)

Cost (½ zᵀPz + qᵀz, plus a constant)::

    Σ_{k=1..H} ‖θ̇(k)‖²  +  w Σ_{k=1..H} ‖θ(k) − t(k)‖²  +  ρ Σ_i s_i

The target enters only q and the terminal rows' lower bounds; the current state and the
reference in use only the first block's bounds; P and A never change, so OSQP factors once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import ServoModel

F = NDArray[np.float64]
I = NDArray[np.int64]

BLOCK = 9
"""Variables per sample: θ*(k−1), θ(k), θ̇(k) (three joints each)."""
FIXED_ROWS = 18
"""Rows per sample before the region's: dynamics 6, speed 3, reference 3, step 3, lead 3."""


@dataclass(frozen=True)
class FollowLayout:
    """Indices of the variables and rows of the follow QP for a horizon of H samples."""

    H: int
    nr: int
    """Half-spaces of the region."""

    @property
    def n(self) -> int:
        return BLOCK * self.H + 3

    @property
    def rows_per_block(self) -> int:
        return FIXED_ROWS + self.nr

    @property
    def m(self) -> int:
        return self.rows_per_block * self.H + 9

    def u(self, k: int) -> I:
        """Columns of θ*(k), k = 0..H−1."""
        return np.arange(3) + BLOCK * k

    def th(self, k: int) -> I:
        """Columns of θ(k), k = 1..H."""
        return np.arange(3) + BLOCK * (k - 1) + 3

    def om(self, k: int) -> I:
        """Columns of θ̇(k), k = 1..H."""
        return np.arange(3) + BLOCK * (k - 1) + 6

    @property
    def s(self) -> I:
        return np.arange(3) + BLOCK * self.H

    def row(self, k: int) -> int:
        """First row of sample k's block (k = 1..H)."""
        return self.rows_per_block * (k - 1)

    @property
    def terminal_row(self) -> int:
        return self.rows_per_block * self.H

    def unpack(self, z: F) -> tuple[F, F, F]:
        """(θ*(0..H−1), θ(1..H), θ̇(1..H)), each (H, 3), from a solution vector."""
        blk = z[: BLOCK * self.H].reshape(self.H, BLOCK)
        return blk[:, 0:3].copy(), blk[:, 3:6].copy(), blk[:, 6:9].copy()

    def shift_primal(self, z: F, steps: int) -> F:
        """The solution ``steps`` samples later: blocks moved forward, the tail held at rest
        at θ(H) (reference θ(H), speed 0) — feasible again whenever z was."""
        last = z[BLOCK * (self.H - 1): BLOCK * self.H]
        hold = np.concatenate([last[3:6], last[3:6], np.zeros(3)])
        return _shift_blocks(z, self.H, BLOCK, steps, hold)

    def shift_dual(self, y: F, steps: int) -> F:
        """Multipliers moved like :meth:`shift_primal`; the tail blocks get zeros."""
        return _shift_blocks(y, self.H, self.rows_per_block, steps,
                             np.zeros(self.rows_per_block))


def _shift_blocks(v: F, H: int, width: int, steps: int, tail: F) -> F:
    """``v`` with its first ``H`` blocks of ``width`` moved ``steps`` blocks forward and
    the freed blocks at the end set to ``tail``; entries after the blocks unchanged."""
    out = v.copy()
    j = min(max(steps, 0), H)
    if j == 0:
        return out
    blk = v[: width * H].reshape(H, width)
    new = np.empty_like(blk)
    new[: H - j] = blk[j:]
    new[H - j:] = tail
    out[: width * H] = new.ravel()
    return out


@dataclass(frozen=True)
class FollowMatrices:
    """The constant parts of the follow QP."""

    layout: FollowLayout
    P: sp.csc_matrix
    """(n, n) upper triangle: 2 on θ̇, 2w on θ."""
    A: sp.csc_matrix
    """(m, n) constraint matrix."""
    lo: F
    """(m,) lower bounds with the state and target parts left at 0 (filled per solve)."""
    hi: F
    """(m,) upper bounds, likewise."""
    step_deg: float = np.inf
    """Largest reference step, deg."""
    lead_deg: float = np.inf
    """Largest |θ*(k) − θ(k)| (the servo's linear range), deg; ∞: none."""


def build(model: ServoModel, region: Region, vmax_degps: float, H: int, ref_lo_deg: F, ref_hi_deg: F,
          track_weight: float, margin_deg: float, speed_margin_degps: float,
          step_deg: float = np.inf, lead_deg: float = np.inf) -> FollowMatrices:
    """Assemble P, A and the constant bounds of the follow QP (see the module docstring);
    ``step_deg``: largest reference step, ``lead_deg``: the linear range (∞: none)."""
    nr = region.halfspaces
    L = FollowLayout(H, nr)
    (a, b), (c, d) = model.A.tolist()
    b0, b1 = model.B.tolist()
    rows: list[I] = []
    cols: list[I] = []
    vals: list[F] = []

    def add(r: I | int, cc: I, v: F | float) -> None:
        cc = np.asarray(cc, np.int64).ravel()
        rows.append(np.broadcast_to(np.asarray(r, np.int64), cc.shape).ravel())
        cols.append(cc)
        vals.append(np.broadcast_to(np.asarray(v, float), cc.shape).ravel())

    inf = np.inf
    lo = np.zeros(L.m)
    hi = np.zeros(L.m)
    An = np.linalg.norm(region.A, axis=1)
    b_tight = region.b - margin_deg * An
    v = vmax_degps - speed_margin_degps
    for k in range(1, H + 1):
        r0 = L.row(k)
        for i in range(3):
            # dynamics, θ row then θ̇ row of joint i
            add(r0 + i, L.th(k)[i:i + 1], 1.0)
            add(r0 + i, L.u(k - 1)[i:i + 1], -b0)
            add(r0 + 3 + i, L.om(k)[i:i + 1], 1.0)
            add(r0 + 3 + i, L.u(k - 1)[i:i + 1], -b1)
            if k > 1:
                add(r0 + i, L.th(k - 1)[i:i + 1], -a)
                add(r0 + i, L.om(k - 1)[i:i + 1], -b)
                add(r0 + 3 + i, L.th(k - 1)[i:i + 1], -c)
                add(r0 + 3 + i, L.om(k - 1)[i:i + 1], -d)
        # speed, reference bound
        add(r0 + 6 + np.arange(3), L.om(k), 1.0)
        lim = 0.0 if k == H else v
        lo[r0 + 6: r0 + 9], hi[r0 + 6: r0 + 9] = -lim, lim
        add(r0 + 9 + np.arange(3), L.u(k - 1), 1.0)
        lo[r0 + 9: r0 + 12], hi[r0 + 9: r0 + 12] = ref_lo_deg, ref_hi_deg
        # step from the reference before, lead over the position (k = 1: bounds per solve)
        add(r0 + 12 + np.arange(3), L.u(k - 1), 1.0)
        add(r0 + 15 + np.arange(3), L.u(k - 1), 1.0)
        if k > 1:
            add(r0 + 12 + np.arange(3), L.u(k - 2), -1.0)
            add(r0 + 15 + np.arange(3), L.th(k - 1), -1.0)
            lo[r0 + 12: r0 + 15], hi[r0 + 12: r0 + 15] = -step_deg, step_deg
            lo[r0 + 15: r0 + 18], hi[r0 + 15: r0 + 18] = -lead_deg, lead_deg
        # region
        rr = r0 + FIXED_ROWS + np.arange(nr)
        for i in range(3):
            add(rr, np.full(nr, L.th(k)[i]), region.A[:, i])
        lo[rr], hi[rr] = -inf, b_tight
    t0 = L.terminal_row
    add(t0 + np.arange(3), L.s, 1.0)
    add(t0 + np.arange(3), L.th(H), -1.0)
    add(t0 + 3 + np.arange(3), L.s, 1.0)
    add(t0 + 3 + np.arange(3), L.th(H), 1.0)
    hi[t0: t0 + 6] = inf
    add(t0 + 6 + np.arange(3), L.th(H), 1.0)
    lo[t0 + 6: t0 + 9], hi[t0 + 6: t0 + 9] = ref_lo_deg, ref_hi_deg
    Amat = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(L.m, L.n))
    diag = np.zeros(L.n)
    for k in range(1, H + 1):
        diag[L.om(k)] = 2.0
        diag[L.th(k)] = 2.0 * track_weight
    idx = np.arange(L.n)
    P = sp.csc_matrix((diag, (idx, idx)), shape=(L.n, L.n))
    return FollowMatrices(L, P, Amat, lo, hi, float(step_deg), float(lead_deg))


def linear_cost(L: FollowLayout, targets: F, track_weight: float, terminal_weight: float) -> F:
    """q of the QP for per-sample targets ``targets`` (H, 3), deg."""
    q = np.zeros(L.n)
    blk = q[: BLOCK * L.H].reshape(L.H, BLOCK)
    blk[:, 3:6] = -2.0 * track_weight * targets
    q[L.s] = terminal_weight
    return q


def fill_bounds(mats: FollowMatrices, model: ServoModel, theta_deg: F, omega_degps: F,
                terminal_deg: F, previous_reference_deg: F | None = None) -> tuple[F, F]:
    """(lo, hi) of the QP for the current state, the reference in use (θ(0) when None: at
    rest) and the terminal target."""
    L = mats.layout
    lo, hi = mats.lo.copy(), mats.hi.copy()
    x1_th = model.A[0, 0] * theta_deg + model.A[0, 1] * omega_degps
    x1_om = model.A[1, 0] * theta_deg + model.A[1, 1] * omega_degps
    lo[0:3] = hi[0:3] = x1_th
    lo[3:6] = hi[3:6] = x1_om
    prev = theta_deg if previous_reference_deg is None else previous_reference_deg
    lo[12:15], hi[12:15] = prev - mats.step_deg, prev + mats.step_deg
    lo[15:18], hi[15:18] = theta_deg - mats.lead_deg, theta_deg + mats.lead_deg
    t0 = L.terminal_row
    lo[t0: t0 + 3] = -terminal_deg
    lo[t0 + 3: t0 + 6] = terminal_deg
    return lo, hi


def predict(model: ServoModel, theta_deg: F, omega_degps: F, reference_deg: F) -> tuple[F, F]:
    """Exact model prediction (θ (H+1, 3), θ̇ (H+1, 3)) from the state under the references."""
    H = reference_deg.shape[0]
    th = np.empty((H + 1, 3))
    om = np.empty((H + 1, 3))
    th[0], om[0] = theta_deg, omega_degps
    (a, b), (c, d) = model.A.tolist()
    b0, b1 = model.B.tolist()
    for k in range(H):  # vectorized over the joints
        th[k + 1] = a * th[k] + b * om[k] + b0 * reference_deg[k]
        om[k + 1] = c * th[k] + d * om[k] + b1 * reference_deg[k]
    return th, om
