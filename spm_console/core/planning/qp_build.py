"""Sparse matrices of the QP (30) for OSQP: min ½ zᵀPz + qᵀz s.t. l ≤ Az ≤ u.

The constraints come in two parts:

* the *base*: boundary conditions (30b, c), dynamics (30f), θ*(0) = θ(0), the speed
  bound (30d) at the samples and optional bounds on the references — always present;
* the *candidates*: region rows (30e) at the samples k = 1..N−1 and, with K > 1, the
  region and speed rows at the sub-sample instants — mostly inactive at the optimum, so
  the solver screens them (``G z ≤ h`` with lower bounds ``g_lo``, see ``osqp_solve``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.planning.problem import Layout, PlanProblem, sub_matrices

F = NDArray[np.float64]
I = NDArray[np.int64]

INF = np.inf


@dataclass(frozen=True)
class QpData:
    """The assembled QP; rows of ``G`` carry a (family, k, j, index) label for reports."""

    layout: Layout
    P: sp.csc_matrix
    """(n, n) cost: 2 on every θ̇ variable (cost Σ θ̇ᵀθ̇, (deg/s)²)."""
    q: F
    A: sp.csc_matrix
    """Base rows."""
    l: F
    u: F
    G: sp.csr_matrix
    """Candidate rows: g_lo ≤ G z ≤ g_hi."""
    g_lo: F
    g_hi: F
    g_family: I
    """0 = region at a sample, 1 = region between samples, 2 = speed between samples."""
    g_k: I
    """Sample index k of each candidate row (the interval k for sub-samples)."""
    g_scale: F
    """Divide a row's slack by this to get deg (region rows: |a_r|) or deg/s (speed rows)."""


def _coo(rows: list[I], cols: list[I], vals: list[F], shape: tuple[int, int]) -> sp.csc_matrix:
    r = np.concatenate(rows) if rows else np.zeros(0, np.int64)
    c = np.concatenate(cols) if cols else np.zeros(0, np.int64)
    v = np.concatenate(vals) if vals else np.zeros(0)
    return sp.csc_matrix(sp.coo_matrix((v, (r, c)), shape=shape))


def build(problem: PlanProblem) -> QpData:
    N = problem.N
    L = Layout(N)
    n = L.n
    Am, Bm = problem.model.A, problem.model.B
    s, g = problem.start_deg, problem.goal_deg
    J = np.arange(3)

    # cost Σ_k θ̇(k)ᵀθ̇(k): P = 2 I on the θ̇ variables
    om_all = L.om(np.repeat(np.arange(N + 1), 3), np.tile(J, N + 1)).ravel()
    P = sp.csc_matrix(sp.coo_matrix((np.full(om_all.size, 2.0), (om_all, om_all)), shape=(n, n)))
    q = np.zeros(n)

    rows: list[I] = []
    cols: list[I] = []
    vals: list[F] = []
    lo: list[F] = []
    hi: list[F] = []
    m = 0

    def add(r: I, c: I, v: F) -> None:
        rows.append(np.asarray(r, np.int64).ravel())
        cols.append(np.asarray(c, np.int64).ravel())
        vals.append(np.asarray(v, float).ravel())

    # boundary conditions: θ(0)=s, θ̇(0)=0, θ(N)=g, θ̇(N)=0  (12 rows)
    bc_cols = np.concatenate([L.th(0, J), L.om(0, J), L.th(N, J), L.om(N, J)])
    add(m + np.arange(12), bc_cols, np.ones(12))
    bc = np.concatenate([s, np.zeros(3), g, np.zeros(3)])
    lo.append(bc)
    hi.append(bc)
    m += 12
    if problem.hold_first:
        add(m + J, L.u(0, J), np.ones(3))
        lo.append(s)
        hi.append(s)
        m += 3

    # dynamics x_i(k+1) − A x_i(k) − B θ*_i(k) = 0, rows (k, i, component)
    kk, ii = np.meshgrid(np.arange(N), J, indexing="ij")
    kk, ii = kk.ravel(), ii.ravel()
    base = m + 6 * kk + 2 * ii  # row of the position equation; +1 velocity
    for c, var_next in ((0, L.th), (1, L.om)):
        r = base + c
        add(r, var_next(kk + 1, ii), np.ones(kk.size))
        add(r, L.th(kk, ii), np.full(kk.size, -Am[c, 0]))
        add(r, L.om(kk, ii), np.full(kk.size, -Am[c, 1]))
        add(r, L.u(kk, ii), np.full(kk.size, -Bm[c]))
    lo.append(np.zeros(6 * N))
    hi.append(np.zeros(6 * N))
    m += 6 * N

    # speed bound at the samples k = 1..N−1 (30d)
    if problem.vmax_degps is not None and N > 1:
        ks, js = np.meshgrid(np.arange(1, N), J, indexing="ij")
        cnt = ks.size
        add(m + np.arange(cnt), L.om(ks.ravel(), js.ravel()), np.ones(cnt))
        lo.append(np.full(cnt, -problem.vmax_degps))
        hi.append(np.full(cnt, problem.vmax_degps))
        m += cnt

    # optional bounds on the free references θ*(k)
    if problem.ref_lo_deg is not None or problem.ref_hi_deg is not None:
        k0 = 1 if problem.hold_first else 0
        ks, js = np.meshgrid(np.arange(k0, N), J, indexing="ij")
        cnt = ks.size
        add(m + np.arange(cnt), L.u(ks.ravel(), js.ravel()), np.ones(cnt))
        lo_v = problem.ref_lo_deg if problem.ref_lo_deg is not None else np.full(3, -INF)
        hi_v = problem.ref_hi_deg if problem.ref_hi_deg is not None else np.full(3, INF)
        lo.append(np.tile(lo_v, N - k0))
        hi.append(np.tile(hi_v, N - k0))
        m += cnt

    A = _coo(rows, cols, vals, (m, n))
    G, g_lo, g_hi, fam, gk, scale = _candidates(problem, L)
    return QpData(L, P, q, A, np.concatenate(lo), np.concatenate(hi), G, g_lo, g_hi, fam, gk,
                  scale)


def _candidates(problem: PlanProblem, L: Layout) -> tuple[sp.csr_matrix, F, F, I, I, F]:
    """Region rows at samples 1..N−1, then region and speed rows between samples."""
    N = problem.N
    Ap, bp = problem.region.A, problem.region.b
    nr = Ap.shape[0]
    anorm = np.linalg.norm(Ap, axis=1)
    scale: list[F] = []
    rows: list[I] = []
    cols: list[I] = []
    vals: list[F] = []
    lo: list[F] = []
    hi: list[F] = []
    fam: list[I] = []
    kss: list[I] = []
    m = 0

    # region at the samples: a_r · θ(k) ≤ b_r
    ks = np.arange(1, N)
    kr, rr = np.meshgrid(ks, np.arange(nr), indexing="ij")
    kr, rr = kr.ravel(), rr.ravel()
    cnt = kr.size
    for i in range(3):
        rows.append(m + np.arange(cnt))
        cols.append(L.th(kr, i))
        vals.append(Ap[rr, i])
    lo.append(np.full(cnt, -INF))
    hi.append(bp[rr])
    fam.append(np.zeros(cnt, np.int64))
    kss.append(kr)
    scale.append(anorm[rr])
    m += cnt

    Phis, Gams = sub_matrices(problem)
    if Phis.shape[0]:
        K1 = Phis.shape[0]
        # region between samples: a_r · (Φ_j[0] x_i(k) + Γ_j[0] θ*_i(k)) ≤ b_r, k = 0..N−1
        kq, jq, rq = np.meshgrid(np.arange(N), np.arange(K1), np.arange(nr), indexing="ij")
        kq, jq, rq = kq.ravel(), jq.ravel(), rq.ravel()
        cnt = kq.size
        for i in range(3):
            a = Ap[rq, i]
            for var, coef in ((L.th, Phis[jq, 0, 0]), (L.om, Phis[jq, 0, 1])):
                rows.append(m + np.arange(cnt))
                cols.append(var(kq, i))
                vals.append(a * coef)
            rows.append(m + np.arange(cnt))
            cols.append(L.u(kq, i))
            vals.append(a * Gams[jq, 0])
        lo.append(np.full(cnt, -INF))
        hi.append(bp[rq])
        fam.append(np.ones(cnt, np.int64))
        kss.append(kq)
        scale.append(anorm[rq])
        m += cnt
        if problem.vmax_degps is not None:
            kv, jv, iv = np.meshgrid(np.arange(N), np.arange(K1), np.arange(3), indexing="ij")
            kv, jv, iv = kv.ravel(), jv.ravel(), iv.ravel()
            cnt = kv.size
            for var, coef in ((L.th, Phis[jv, 1, 0]), (L.om, Phis[jv, 1, 1]), (L.u, Gams[jv, 1])):
                rows.append(m + np.arange(cnt))
                cols.append(var(kv, iv))
                vals.append(coef)
            v = problem.vmax_degps
            lo.append(np.full(cnt, -v))
            hi.append(np.full(cnt, v))
            fam.append(np.full(cnt, 2, np.int64))
            kss.append(kv)
            scale.append(np.ones(cnt))
            m += cnt

    G = sp.csr_matrix(_coo(rows, cols, vals, (m, L.n)))
    return (G, np.concatenate(lo), np.concatenate(hi), np.concatenate(fam), np.concatenate(kss),
            np.concatenate(scale))
