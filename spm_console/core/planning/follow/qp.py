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
from spm_console.core.servo.model import ServoModel, simulate

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
    ``step_deg``: largest reference step, ``lead_deg``: the linear range (∞: none).

    Every block's entries at once (arrays over the samples k and joints i): a live following
    builds one QP per region of the cover before torque-on."""
    nr = region.halfspaces
    L = FollowLayout(H, nr)
    (a, b), (c, d) = model.A.tolist()
    b0, b1 = model.B.tolist()
    rows: list[I] = []
    cols: list[I] = []
    vals: list[F] = []

    def add(r: I, cc: I, v: F | float) -> None:
        r, cc = np.broadcast_arrays(r, cc)
        rows.append(r.ravel())
        cols.append(cc.ravel())
        vals.append(np.broadcast_to(np.asarray(v, float), r.shape).ravel())

    k = np.arange(1, H + 1)[:, None]  # (H, 1): samples 1..H
    i = np.arange(3)[None, :]  # (1, 3): joints
    r0 = L.rows_per_block * (k - 1)  # first row of each sample's block
    u = BLOCK * (k - 1) + i  # columns of θ*(k−1)
    th, om = u + 3, u + 6  # columns of θ(k), θ̇(k)
    r1 = r0[1:]  # the blocks k = 2..H, whose θ(k−1), θ̇(k−1), θ*(k−2) are variables
    # dynamics: θ row then θ̇ row of each joint
    add(r0 + i, th, 1.0)
    add(r0 + i, u, -b0)
    add(r0 + 3 + i, om, 1.0)
    add(r0 + 3 + i, u, -b1)
    add(r1 + i, th[:-1], -a)
    add(r1 + i, om[:-1], -b)
    add(r1 + 3 + i, th[:-1], -c)
    add(r1 + 3 + i, om[:-1], -d)
    # speed, reference bound, step from the reference before, lead over the position
    add(r0 + 6 + i, om, 1.0)
    add(r0 + 9 + i, u, 1.0)
    add(r0 + 12 + i, u, 1.0)
    add(r0 + 15 + i, u, 1.0)
    add(r1 + 12 + i, u[:-1], -1.0)
    add(r1 + 15 + i, th[:-1], -1.0)
    # region: row j of sample k is A_j · θ(k)
    add((r0 + FIXED_ROWS)[:, :, None] + np.arange(nr)[None, :, None], th[:, None, :],
        np.asarray(region.A, float)[None])
    t0 = L.terminal_row
    add(t0 + np.arange(3), L.s, 1.0)
    add(t0 + np.arange(3), L.th(H), -1.0)
    add(t0 + 3 + np.arange(3), L.s, 1.0)
    add(t0 + 3 + np.arange(3), L.th(H), 1.0)
    add(t0 + 6 + np.arange(3), L.th(H), 1.0)
    Amat = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(L.m, L.n))

    lo = np.zeros(L.m)
    hi = np.zeros(L.m)
    blo = lo[: L.rows_per_block * H].reshape(H, L.rows_per_block)  # views: one row per sample
    bhi = hi[: L.rows_per_block * H].reshape(H, L.rows_per_block)
    lim = np.full((H, 1), vmax_degps - speed_margin_degps)
    lim[-1] = 0.0  # θ̇(H) = 0: the horizon ends at rest
    blo[:, 6:9], bhi[:, 6:9] = -lim, lim
    blo[:, 9:12], bhi[:, 9:12] = ref_lo_deg, ref_hi_deg
    # k = 1: the step's and the lead's bounds come from the data, per solve
    blo[1:, 12:15], bhi[1:, 12:15] = -step_deg, step_deg
    blo[1:, 15:18], bhi[1:, 15:18] = -lead_deg, lead_deg
    blo[:, FIXED_ROWS:] = -np.inf
    bhi[:, FIXED_ROWS:] = region.b - margin_deg * np.linalg.norm(region.A, axis=1)
    hi[t0: t0 + 6] = np.inf
    lo[t0 + 6: t0 + 9], hi[t0 + 6: t0 + 9] = ref_lo_deg, ref_hi_deg

    diag = np.zeros(L.n)
    dblk = diag[: BLOCK * H].reshape(H, BLOCK)
    dblk[:, 6:9] = 2.0  # θ̇(k)
    dblk[:, 3:6] = 2.0 * track_weight  # θ(k)
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
    x0 = np.column_stack([theta_deg, omega_degps])
    xs = simulate(model, x0, np.vstack([reference_deg, reference_deg[-1:]]))  # last row: unused
    return xs[..., 0].copy(), xs[..., 1].copy()
