"""The follow QP condensed onto the references, for a dense active-set solver (DAQP).

The same problem as :mod:`spm_console.core.planning.follow.qp` (its docstring gives the
rows), with the states eliminated: the servo model (28) is linear, so from the current state
x(0) = (θ(0), θ̇(0)) of each joint

    θ(k) = f_θ(k)·x(0) + Σ_{j<k} T_θ[k, j] θ*(j),   θ̇(k) = f_ω(k)·x(0) + Σ_{j<k} T_ω[k, j] θ*(j)

(T the impulse responses A^{k−1−j} B, f the free responses A^k). Variables: θ*(0..H−1) (joint
fastest) and the three terminal slacks s; n = 3H + 3. The Hessian and every row are constant;
the current state, the reference in use and the targets enter only the linear cost and the
bounds, so the solver factors once and each period updates vectors (and warm-starts from the
previous active set, shifted a sample).

Rows (general, in this order): speed θ̇(k), k = 1..H (θ̇(H) = 0 an equality); step
θ*(k) − θ*(k−1), k = 1..H−1; lead θ*(k) − θ(k), k = 1..H−1 (none without a linear range);
region A θ(k) ≤ b′, k = 1..H; terminal s ∓ θ(H) ≥ ∓t and lo ≤ θ(H) ≤ hi. θ*(0)'s step and
lead from data are simple bounds, intersected with the servo limits.

The slacks carry a tiny quadratic weight (DAQP needs a positive definite Hessian). At s = 0,
the exact penalty's case "reached", its gradient is zero and the answer is unchanged; when
the target cannot be reached it adds 2·ε·s to the penalty ρ (1e-5 for s = 5° against ρ = 1e4):
the answers equal cvxpy's within the tests' bounds there too. Degrees, deg/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import ServoModel

F = NDArray[np.float64]
I = NDArray[np.int64]

SLACK_WEIGHT = 1e-6
"""The terminal slacks' quadratic weight (see the module docstring)."""
DENSE_MAX_ENTRIES = 2_000_000
"""Largest condensed QP (entries of its rows and Hessian) the follow solver gives DAQP: 16 MB
(H = 50 with a 28-face region: 0.37 M); a longer horizon or a larger region goes to OSQP."""


def dense_entries(H: int, halfspaces: int) -> int:
    """Entries of the condensed QP's rows and Hessian for a horizon and a region's faces."""
    n = 3 * H + 3
    return n * (n + 3 * H + 6 * (H - 1) + halfspaces * H + 9)


#: DAQP's sense flags (daqp's ``sense``): an active inequality, at its lower bound, and an
#: equality.
ACTIVE, LOWER, EQUALITY = 1, 2, 5


def impulse(model: ServoModel, H: int) -> tuple[F, F, F, F]:
    """(T_θ (H, H), T_ω (H, H), f_θ (H, 2), f_ω (H, 2)): row k−1 maps θ*(0..H−1) and x(0)
    to θ(k), θ̇(k), k = 1..H (one joint; lower triangular, T[k−1, j] = 0 for j ≥ k)."""
    A = np.asarray(model.A, float)
    B = np.asarray(model.B, float)
    powers = np.empty((H + 1, 2, 2))
    powers[0] = np.eye(2)
    for p in range(1, H + 1):
        powers[p] = A @ powers[p - 1]
    resp = powers[:H] @ B  # (H, 2): A^m B, m = 0..H−1
    k = np.arange(1, H + 1)[:, None]
    j = np.arange(H)[None, :]
    m = k - 1 - j
    T = np.where((m >= 0)[..., None], resp[np.clip(m, 0, H - 1)], 0.0)  # (H, H, 2)
    return T[..., 0], T[..., 1], powers[1:, 0, :], powers[1:, 1, :]


@dataclass(frozen=True)
class DenseFollow:
    """The condensed follow QP's constant parts and where each row family lies."""

    H: int
    H_cost: F
    """(n, n) Hessian (½ zᵀHz)."""
    A: F
    """(m_A, n) general rows."""
    lo: F
    """(n + m_A,) bounds with the data parts at 0: the simple bounds first (DAQP's order)."""
    hi: F
    sense: NDArray[np.int32]
    Tth: F
    Tom: F
    fth: F
    fom: F
    track_weight: float
    step_deg: float
    lead_deg: float
    rows_speed: slice
    rows_step: slice
    rows_lead: slice
    rows_region: slice
    rows_terminal: int
    region_A: F

    @property
    def n(self) -> int:
        return 3 * self.H + 3

    def free(self, theta_deg: F, omega_degps: F) -> tuple[F, F]:
        """(θ (H, 3), θ̇ (H, 3)) of the free response from the state, samples 1..H."""
        x = np.stack([theta_deg, omega_degps])  # (2, 3)
        return self.fth @ x, self.fom @ x

    def response(self, theta_deg: F, omega_degps: F, reference_deg: F) -> tuple[F, F]:
        """(θ (H+1, 3), θ̇ (H+1, 3)), samples 0..H, under the references θ*(0..H−1) (H, 3):
        the model (28) as its free and impulse responses (two small products)."""
        ft, fo = self.free(theta_deg, omega_degps)
        th = np.vstack([theta_deg[None], ft + self.Tth @ reference_deg])
        om = np.vstack([omega_degps[None], fo + self.Tom @ reference_deg])
        return th, om

    def cost(self, free_th: F, free_om: F, targets: F, terminal_weight: float) -> F:
        """The linear cost for the free response and per-sample targets (H, 3)."""
        f = np.empty(self.n)
        # ∂/∂u at u = 0 of Σ‖θ̇‖² + w Σ‖θ − t‖², θ = free_θ + T_θ u, θ̇ = free_ω + T_ω u
        f[: 3 * self.H] = (2.0 * (self.Tom.T @ free_om)
                           + 2.0 * self.track_weight * (self.Tth.T @ (free_th - targets))).ravel()
        f[3 * self.H:] = terminal_weight
        return f

    def rows_of(self, z: F) -> F:
        """A z, the general rows at the variables z (n,), through the responses (a few (H, H)
        by (H, 3) products instead of the (m_A, n) matrix); the data parts are in the bounds."""
        H = self.H
        Z = z[: 3 * H].reshape(H, 3)
        th = self.Tth @ Z  # θ(1..H) − free response
        parts = [(self.Tom @ Z).ravel()]
        if self.rows_step.stop > self.rows_step.start:
            parts.append((Z[1:] - Z[:-1]).ravel())
        if self.rows_lead.stop > self.rows_lead.start:
            parts.append((Z[1:] - th[:-1]).ravel())
        slack = z[3 * H:]
        parts += [(th @ self.region_A.T).ravel(), slack - th[-1], slack + th[-1], th[-1]]
        return np.concatenate(parts)

    def bounds(self, theta_deg: F, omega_degps: F, terminal_deg: F, previous_deg: F,
               free_th: F, free_om: F) -> tuple[F, F]:
        """(lo, hi) for the state, the reference in use and the terminal target."""
        lo, hi = self.lo.copy(), self.hi.copy()
        n = self.n
        lo[0:3] = np.maximum(lo[0:3], np.maximum(previous_deg - self.step_deg,
                                                 theta_deg - self.lead_deg))
        hi[0:3] = np.minimum(hi[0:3], np.minimum(previous_deg + self.step_deg,
                                                 theta_deg + self.lead_deg))
        sp = slice(n + self.rows_speed.start, n + self.rows_speed.stop)
        fo = free_om.ravel()
        lo[sp] -= fo
        hi[sp] -= fo
        if self.rows_lead.stop > self.rows_lead.start:
            ld = slice(n + self.rows_lead.start, n + self.rows_lead.stop)
            ft = free_th[:-1].ravel()  # θ*(k) − θ(k) = (I − T_θ)θ* − free_θ(k)
            lo[ld] += ft
            hi[ld] += ft
        rg = slice(n + self.rows_region.start, n + self.rows_region.stop)
        hi[rg] -= (free_th @ self.region_A.T).ravel()
        t0 = n + self.rows_terminal
        th_h = free_th[-1]
        lo[t0: t0 + 3] = -terminal_deg + th_h
        lo[t0 + 3: t0 + 6] = terminal_deg - th_h
        lo[t0 + 6: t0 + 9] -= th_h
        hi[t0 + 6: t0 + 9] -= th_h
        return lo, hi


def build_dense(model: ServoModel, region: Region, vmax_degps: float, H: int, ref_lo_deg: F,
                ref_hi_deg: F, track_weight: float, margin_deg: float, speed_margin_degps: float,
                step_deg: float = np.inf, lead_deg: float = np.inf) -> DenseFollow:
    """The condensed QP (see the module docstring); arguments as
    :func:`spm_console.core.planning.follow.qp.build`."""
    Tth, Tom, fth, fom = impulse(model, H)
    I3 = np.eye(3)
    Kth = np.asarray(np.kron(Tth, I3), float)  # (3H, 3H): θ(1..H) from θ*(0..H−1)
    Kom = np.asarray(np.kron(Tom, I3), float)
    nu = 3 * H
    n = nu + 3
    Hc = np.zeros((n, n))
    Hc[:nu, :nu] = 2.0 * (Kom.T @ Kom + track_weight * Kth.T @ Kth)
    Hc[nu:, nu:] = 2.0 * SLACK_WEIGHT * I3
    blocks: list[F] = []
    los: list[F] = []
    his: list[F] = []
    sense: list[NDArray[np.int32]] = []

    def rows(M: F, lo: F | float, hi: F | float, flag: int = 0) -> slice:
        start = sum(b.shape[0] for b in blocks)
        full = np.zeros((M.shape[0], n))
        full[:, : M.shape[1]] = M
        blocks.append(full)
        los.append(np.broadcast_to(np.asarray(lo, float), (M.shape[0],)).copy())
        his.append(np.broadcast_to(np.asarray(hi, float), (M.shape[0],)).copy())
        sense.append(np.full(M.shape[0], flag, np.int32))
        return slice(start, start + M.shape[0])

    v = vmax_degps - speed_margin_degps
    r_speed = rows(Kom[:-3], -v, v)
    rows(Kom[-3:], 0.0, 0.0, EQUALITY)  # θ̇(H) = 0: the horizon ends at rest
    r_speed = slice(r_speed.start, r_speed.stop + 3)
    D = (np.eye(nu, k=3) - np.eye(nu))[: nu - 3]  # θ*(k+1) − θ*(k)
    r_step = rows(D, -step_deg, step_deg) if np.isfinite(step_deg) else slice(
        r_speed.stop, r_speed.stop)
    if np.isfinite(lead_deg):  # θ*(k) − θ(k), k = 1..H−1
        r_lead = rows(np.eye(nu)[3:] - Kth[:-3], -lead_deg, lead_deg)
    else:
        r_lead = slice(r_step.stop, r_step.stop)
    Ar = np.asarray(region.A, float)
    reg = np.asarray(np.kron(Tth, Ar), float)  # row (k, r), column (j, i): T_θ[k, j]·A[r, i]
    b_tight = region.b - margin_deg * np.linalg.norm(Ar, axis=1)
    r_region = rows(reg, -np.inf, np.tile(b_tight, H))
    t_row = r_region.stop
    th_H = Kth[-3:]
    term = np.zeros((9, n))
    term[0:3, :nu], term[0:3, nu:] = -th_H, I3
    term[3:6, :nu], term[3:6, nu:] = th_H, I3
    term[6:9, :nu] = th_H
    blocks.append(term)
    los.append(np.concatenate([np.zeros(6), ref_lo_deg]))
    his.append(np.concatenate([np.full(6, np.inf), ref_hi_deg]))
    sense.append(np.zeros(9, np.int32))
    simple_lo = np.concatenate([np.tile(ref_lo_deg, H), np.full(3, -np.inf)])
    simple_hi = np.concatenate([np.tile(ref_hi_deg, H), np.full(3, np.inf)])
    return DenseFollow(
        H=H, H_cost=Hc, A=np.vstack(blocks), lo=np.concatenate([simple_lo, *los]),
        hi=np.concatenate([simple_hi, *his]),
        sense=np.concatenate([np.zeros(n, np.int32), *sense]), Tth=Tth, Tom=Tom, fth=fth,
        fom=fom, track_weight=float(track_weight), step_deg=float(step_deg),
        lead_deg=float(lead_deg), rows_speed=r_speed, rows_step=r_step, rows_lead=r_lead,
        rows_region=r_region, rows_terminal=t_row, region_A=Ar)
