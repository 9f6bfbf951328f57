"""The QP (30) by a dual active-set method on one factorization of its KKT matrix.

Goldfarb and Idnani's dual method: start from the minimum of ½zᵀPz under the equalities
alone (every pool row free, multipliers zero: dual feasible), then repeatedly take the most
violated pool row p and raise its multiplier t along the direction that keeps the working
set W held and the equalities met. The step stops when p is met (p joins W) or when a
multiplier of W reaches zero first (that row leaves W, and p's step goes on). The cost rises
at every step and W never repeats, so the method ends: with every row met (optimal), or with
a violated row that no step can meet (the QP is infeasible; the caller lets a solver with
an infeasibility certificate say so).

Every solve uses one LU of K₀ = [[P, Cᵀ], [C, 0]] (the equalities, kept per N: the
matrices are the same for every start, goal, region and route of that N) and the Schur
complement of W's rows, a |W| × |W| dense matrix: W changes by a row at a time and each row
costs one more triangular solve, not a factorization. The end point is solved once more
with iterative refinement on the unregularized system and checked like
:func:`~spm_console.core.planning.active_set.refine` does: every pool row met to
``PRIMAL_TOL`` and every multiplier of W of the right sign — the optimality certificate.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.plan_report import Certificate
from spm_console.core.planning import active_set
from spm_console.core.planning.active_set import (
    PRIMAL_TOL,
    REG_DUAL,
    REG_PRIMAL,
    ActiveSetResult,
    kkt_verdict,
    violations,
)
from spm_console.core.planning.qp_build import Equalities, Pool
from spm_console.core.planning.solvers.banded import Factor, factor
from spm_console.core.planning.solvers.clarabel_qp import farkas_verdict

F = NDArray[np.float64]
I = NDArray[np.int64]

#: Most dual steps (added or dropped rows) before giving up (the caller falls back).
MAX_STEPS = 40
#: Wall-time bound of one solve, s (the caller falls back past it).
TIME_LIMIT_S = 0.25
#: A row whose step direction meets it by less than this fraction of its curvature with W
#: empty is taken as dependent on W and the equalities.
DEPENDENT = 1e-10
REFINE_STEPS = 8
#: Refinement steps of each K₀ solve inside the iteration (the end point gets REFINE_STEPS).
SOLVE_REFINE = 2
#: Factorizations of K₀ kept (one per N, servo model and θ*(0) rule seen lately).
CACHE = 16
#: Free optima (one per start and goal) kept per factorization.
FREE_POINTS = 8
#: Columns K₀⁻¹[g; 0] kept per factorization (2,271 entries each at N = 150), and the entries
#: they may hold together (4 MB: fewer columns for a long horizon, 13 at N = 5,000).
COLUMNS = 256
COLUMN_ENTRIES = 1 << 19


@dataclass(frozen=True)
class _Kkt:
    """K₀'s LU (banded where it can be: :mod:`.solvers.banded`) and the unregularized
    matrices, for one (P, C). K₀ itself is factored (partial pivoting needs no
    regularization: K₀ is nonsingular when C has full row rank and P is positive definite on
    C's null space, as (30)'s are); only a K₀ that does not factor is regularized."""

    P: sp.csc_matrix
    C: sp.csc_matrix
    lu: Factor
    n: int
    m: int
    K: sp.csr_matrix  # K₀ unregularized (one product per refinement step)
    free: dict[bytes, F] = field(default_factory=dict, compare=False, repr=False)
    """K₀⁻¹[0; d] (refined) by the bytes of d: every QP of one start and goal starts there."""
    columns: dict[bytes, F] = field(default_factory=dict, compare=False, repr=False)
    """K₀⁻¹[g; 0] by g's entries: a route's switch search asks again for the same rows."""
    lock: threading.Lock = field(default_factory=threading.Lock, compare=False, repr=False)
    """Guards the two caches (plans may be solved in several threads)."""

    def solve(self, rhs: F, steps: int = SOLVE_REFINE, tol: float = 1e-11) -> F:
        """K₀⁻¹ rhs on the unregularized K₀: the LU's answer refined (a regularized LU's
        would otherwise leave C dz = δ dλ, and a large dλ turns that into a drift of the
        equalities and a false curvature; an exact LU's needs no correction but round-off),
        at most ``steps`` corrections, until the residual is below ``tol``·max(1, ‖rhs‖∞)."""
        x = np.asarray(self.lu.solve(rhs))
        scale = max(1.0, float(np.abs(rhs).max()))
        for _ in range(steps):
            res = rhs - self.apply(x)
            if not float(np.abs(res).max()) > tol * scale:  # one correction gets ~1e-12
                break
            x = x + np.asarray(self.lu.solve(res))
        return x

    def apply(self, y: F) -> F:
        """K₀ y, unregularized."""
        return np.asarray(self.K @ y)

    def column(self, a: F) -> F:
        """K₀⁻¹[a; 0] for a signed pool row a (n,), kept for the next QP that holds it."""
        nz = np.flatnonzero(a)
        key = nz.tobytes() + a[nz].tobytes()
        with self.lock:
            x = self.columns.get(key)
        if x is None:
            x = self.solve(np.concatenate([a, np.zeros(self.m)]))
            room = min(COLUMNS, max(8, COLUMN_ENTRIES // (self.n + self.m)))
            with self.lock:
                _keep(self.columns, key, x, room)
        return x

    def free_point(self, d: F) -> F | None:
        """K₀⁻¹[0; d], the minimum of ½zᵀPz under C z = d alone, refined as far as refine's
        eqp goes (a stiff or slow servo's K₀ is ill-conditioned) and kept for the next QP of
        the same d; None when the solve does not reach round-off."""
        key = np.ascontiguousarray(d, float).tobytes()
        with self.lock:
            hit = self.free.get(key)
        if hit is not None:
            return hit
        f = np.concatenate([np.zeros(self.n), d])
        y = self.solve(f, steps=active_set.REFINE_STEPS, tol=1e-12)
        scale = max(1.0, float(np.abs(f).max()))
        if not np.all(np.isfinite(y)) or float(np.abs(f - self.apply(y)).max()) > 1e-9 * scale:
            return None
        with self.lock:
            _keep(self.free, key, y, FREE_POINTS)
        return y


def _keep(cache: dict[bytes, F], key: bytes, value: F, room: int) -> None:
    """Put ``value`` in ``cache`` (its caller holds the lock), the oldest entries out first so
    that at most ``room`` are kept."""
    cache[key] = value
    while len(cache) > room:
        del cache[next(iter(cache))]


_FACTORS: dict[tuple[int, int], _Kkt] = {}
_FACTORS_LOCK = threading.Lock()


def kkt_of(eq: Equalities) -> _Kkt | None:
    """K₀'s factorization for ``eq``'s matrices (cached by identity: ``equalities`` returns
    the same matrices for the same N, model and θ*(0) rule); None when it does not factor."""
    key = (id(eq.P), id(eq.C))
    with _FACTORS_LOCK:
        hit = _FACTORS.pop(key, None)
        if hit is not None and hit.P is eq.P and hit.C is eq.C:
            _FACTORS[key] = hit  # the most recently used goes last: the first is evicted
            return hit
    n, m = eq.P.shape[0], eq.C.shape[0]
    Pc, Cc = eq.P.tocoo(), eq.C.tocoo()  # K₀ from triplets (sparse.bmat costs more)
    K0 = sp.csr_matrix((np.concatenate([Pc.data, Cc.data, Cc.data]),
                        (np.concatenate([Pc.row, Cc.row + n, Cc.col]),
                         np.concatenate([Pc.col, Cc.col, Cc.row + n]))), shape=(n + m, n + m))
    lu = factor(K0, np.zeros(n + m))
    if lu is None:  # singular as built: the quasi-definite regularization, refined away
        lu = factor(K0, np.concatenate([np.full(n, REG_PRIMAL), np.full(m, -REG_DUAL)]))
    if lu is None:
        return None
    kkt = _Kkt(eq.P, eq.C, lu, n, m, K0)
    with _FACTORS_LOCK:
        _FACTORS[key] = kkt
        while len(_FACTORS) > CACHE:
            del _FACTORS[next(iter(_FACTORS))]
    return kkt


def free_optimum(eq: Equalities) -> F | None:
    """The minimum of ½zᵀPz under the equalities alone (no pool row), on the kept K₀
    factorization; None when K₀ does not factor or the solve does not reach round-off."""
    kkt = kkt_of(eq)
    if kkt is None:
        return None
    y = kkt.free_point(eq.d)
    return None if y is None else y[: kkt.n].copy()


class _Working:
    """The working set: signed rows a_j = s_j·g_j (dense) held at b_j, with the columns
    X = K₀⁻¹[a_j; 0] and the Schur complement S = A X (symmetric), updated a row at a time
    in arrays that grow as rows join, up to ``capacity`` rows (most working sets hold a few)."""

    def __init__(self, kkt: _Kkt, pool: Pool, capacity: int, first: int = 8) -> None:
        self.kkt, self.pool = kkt, pool
        self.capacity = capacity
        self.rows: list[int] = []
        self.side: list[int] = []
        room = min(capacity, first)
        self._A = np.zeros((room, kkt.n))
        self._Xt = np.zeros((room, kkt.n + kkt.m))
        self._S = np.zeros((room, room))

    def _grow(self) -> None:
        """Room for twice the rows (at most ``capacity``)."""
        k = self.k
        room = min(self.capacity, 2 * k)
        A, Xt, S = self._A, self._Xt, self._S
        self._A = np.zeros((room, A.shape[1]))
        self._Xt = np.zeros((room, Xt.shape[1]))
        self._S = np.zeros((room, room))
        self._A[:k], self._Xt[:k], self._S[:k, :k] = A[:k], Xt[:k], S[:k, :k]

    @property
    def k(self) -> int:
        return len(self.rows)

    @property
    def A(self) -> F:
        return self._A[: self.k]

    @property
    def X(self) -> F:
        return self._Xt[: self.k].T

    @property
    def S(self) -> F:
        return self._S[: self.k, : self.k]

    def signed(self, row: int, side: int) -> tuple[F, float]:
        """(a, b) of pool row ``row`` held at its bound on ``side``, a dense (n,)."""
        g = self.pool.dense_row(row)
        b = self.pool.hi[row] if side > 0 else -self.pool.lo[row]
        return (g if side > 0 else -g), float(b)

    def add(self, row: int, side: int, a: F, x: F) -> None:
        k, n = self.k, self.kkt.n
        if k == self.capacity:
            raise np.linalg.LinAlgError("working set full")
        if k == self._S.shape[0]:
            self._grow()
        col = self._A[:k] @ x[:n]
        self._S[k, :k] = col
        self._S[:k, k] = col
        self._S[k, k] = float(a @ x[:n])
        self._A[k] = a
        self._Xt[k] = x
        self.rows.append(row)
        self.side.append(side)

    def drop(self, j: int) -> None:
        k = self.k
        for arr in (self._A, self._Xt):
            arr[j:k - 1] = arr[j + 1:k]
        self._S[j:k - 1, :k] = self._S[j + 1:k, :k]
        self._S[:k, j:k - 1] = self._S[:k, j + 1:k]
        self.rows.pop(j)
        self.side.pop(j)

    def rhs(self) -> F:
        pool = self.pool
        return np.array([pool.hi[r] if s > 0 else -pool.lo[r]
                         for r, s in zip(self.rows, self.side, strict=True)])


def _solve_w(w: _Working, f: F, b: F, y0: F | None = None) -> tuple[F, F]:
    """[[K₀, E], [Eᵀ, 0]] [y; μ] = [f; b] through the Schur complement; ``y0``: K₀⁻¹f when
    the caller has it (a kept free point)."""
    y0 = w.kkt.solve(f) if y0 is None else y0
    if not w.rows:
        return y0.copy(), np.zeros(0)
    mu = np.asarray(np.linalg.solve(w.S, w.A @ y0[: w.kkt.n] - b), float)
    return y0 - w.X @ mu, mu


def _exact(w: _Working, d: F) -> tuple[F, F] | None:
    """z and μ of W held, refined on the unregularized system; None if it does not solve."""
    kkt = w.kkt
    f = np.concatenate([np.zeros(kkt.n), d])
    b = w.rhs() if w.rows else np.zeros(0)
    A = w.A
    try:
        y, mu = _solve_w(w, f, b, kkt.free_point(d))
        scale = max(1.0, float(np.abs(f).max()), float(np.abs(b).max()) if b.size else 0.0)
        def residual(y: F, mu: F) -> tuple[F, F, float]:
            rf = f - kkt.apply(y)
            if w.rows:
                rf[: kkt.n] -= A.T @ mu
            rb = b - A @ y[: kkt.n] if w.rows else np.zeros(0)
            return rf, rb, max(float(np.abs(rf).max()), float(np.abs(rb).max()) if rb.size else 0.0)

        rf, rb, worst = residual(y, mu)
        for _ in range(REFINE_STEPS):
            if not worst > 1e-12 * scale:
                break
            dy, dmu = _solve_w(w, rf, rb)
            y, mu = y + dy, mu + dmu
            rf, rb, worst = residual(y, mu)  # every correction is measured
    except np.linalg.LinAlgError:
        return None
    # the system solved to round-off (as refine's eqp requires), else no answer
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(mu))) or not worst <= 1e-9 * scale:
        return None
    return y[: kkt.n], mu


def dual_active_set(eq: Equalities, pool: Pool, active: I | None = None,
                    side: I | None = None, max_steps: int = MAX_STEPS) -> ActiveSetResult:
    """Solve (30) (see the module docstring), from the working set (active, side) when given
    (rows whose multiplier comes out negative leave it first); ``ok`` with the optimality
    certificate, or a Farkas ``certificate`` when a violated row can be met by no step.
    At most ``max_steps`` steps: the planner's QP solvers take over past them."""
    kkt = kkt_of(eq)
    if kkt is None:
        return ActiveSetResult(False, None)
    t0 = time.perf_counter()  # the time bound is the iteration's (a factorization is kept)
    warm_rows = np.asarray(active if active is not None else [], np.int64).tolist()
    w = _Working(kkt, pool, len(warm_rows) + max_steps, len(warm_rows) + 8)
    for r, s in zip(warm_rows,
                    np.asarray(side if side is not None else [], np.int64).tolist(), strict=True):
        a, _ = w.signed(r, s)
        w.add(r, s, a, kkt.column(a))
    f = np.concatenate([np.zeros(kkt.n), eq.d])
    steps = 0
    try:
        z, mu = _start(w, f, kkt.free_point(eq.d))
        while steps < max_steps and time.perf_counter() - t0 < TIME_LIMIT_S:
            up, dn = violations(pool, z, np.asarray(w.rows, np.int64),
                                np.asarray(w.side, np.int64))
            viol = np.maximum(up, dn)
            p = int(np.argmax(viol)) if viol.size else -1
            if p < 0 or not viol[p] > PRIMAL_TOL:
                break
            sp_ = 1 if up[p] >= dn[p] else -1
            ap, bp = w.signed(p, sp_)
            xp = kkt.column(ap)
            # the curvature of p with W empty, dzᵀPdz of its direction: the scale for
            # "dependent" (never below round-off of ‖a_p‖²: a row the equalities fix has none)
            x0 = xp[: kkt.n]
            base = max(float(x0 @ (kkt.P @ x0)), 1e-12 * float(ap @ ap))
            t_p = 0.0
            while True:
                steps += 1
                if w.rows:
                    dmu = -np.asarray(np.linalg.solve(w.S, w.A @ xp[: kkt.n]), float)
                    dy = -xp - w.X @ dmu
                else:
                    dmu, dy = np.zeros(0), -xp
                dz = dy[: kkt.n]
                # dzᵀPdz: how far p's multiplier moves the point (0: p depends on W and
                # the equalities); −a_pᵀdz equals it on the exact system and meets p
                curv = float(dz @ (kkt.P @ dz))
                meet = -float(ap @ dz)
                gap = float(ap @ z) - bp
                t_full = gap / meet if curv > DEPENDENT * base and meet > 0.0 else np.inf
                neg = np.flatnonzero(dmu < 0)
                # a multiplier drifted below zero by round-off leaves at once (a zero step)
                ratios = np.maximum(mu[neg], 0.0) / -dmu[neg] if neg.size else np.zeros(0)
                t_drop = float(ratios.min()) if ratios.size else np.inf
                if not np.isfinite(t_full) and not np.isfinite(t_drop):
                    return ActiveSetResult(False, z, np.asarray(w.rows, np.int64),
                                           np.asarray(w.side, np.int64), solves=steps,
                                           certificate=_farkas(eq, w, ap, bp, dy[kkt.n:], dmu))
                t = min(t_full, t_drop)
                if np.isfinite(t_full):
                    z = z + t * dz
                mu = mu + t * dmu
                t_p += t
                if t_full <= t_drop:
                    w.add(p, sp_, ap, xp)
                    mu = np.append(mu, t_p)
                    break
                j = int(neg[int(np.argmin(ratios))])
                w.drop(j)
                mu = np.delete(mu, j)
    except np.linalg.LinAlgError:
        return ActiveSetResult(False, None, solves=steps)
    return _certify(eq, pool, w, steps)


def _farkas(eq: Equalities, w: _Working, ap: F, bp: float, dlam: F, dmu: F) -> Certificate:
    """The infeasibility certificate where row p can be met by no step: p depends on W and
    the equalities (Cᵀdλ + A_Wᵀdμ + a_p = −P dz ≈ 0) with dμ ≥ 0, so y = (dλ, dμ, 1) over
    (C; A_W; a_p) is a Farkas vector (bᵀy = b_p − a_pᵀz < 0 at the current z, which holds W
    and the equalities). Checked like Clarabel's (:func:`farkas_verdict`): over these
    rows alone it proves the whole QP infeasible."""
    m = eq.C.shape[0]
    dense = np.vstack([w.A, ap[None]])
    b = np.concatenate([eq.d, w.rhs() if w.rows else np.zeros(0), [bp]])
    y = np.concatenate([dlam, dmu, [1.0]])

    def transposed(v: F) -> F:  # (C; A_W; a_p)ᵀ v
        return np.asarray(eq.C.T @ v[:m]) + dense.T @ v[m:]

    return replace(farkas_verdict(b, y, m, transposed), solver="dual active set")


def _start(w: _Working, f: F, y0: F | None) -> tuple[F, F]:
    """The solution with W held, after rows of a negative multiplier left W (dual feasible);
    ``y0``: K₀⁻¹f when kept."""
    while True:
        y, mu = _solve_w(w, f, w.rhs() if w.rows else np.zeros(0), y0)
        if not mu.size or float(mu.min()) >= 0.0:
            return y[: w.kkt.n], mu
        w.drop(int(np.argmin(mu)))


def _certify(eq: Equalities, pool: Pool, w: _Working, steps: int) -> ActiveSetResult:
    """The exact solution on W and its KKT check (:func:`kkt_verdict`, as :func:`refine`)."""
    act = np.asarray(w.rows, np.int64)
    sd = np.asarray(w.side, np.int64)
    out = _exact(w, eq.d)
    if out is None:
        return ActiveSetResult(False, None, act, sd, solves=steps)
    z, mu = out
    up, dn = violations(pool, z, act, sd)
    return kkt_verdict(z, act, sd, mu * sd, steps, up, dn)  # μ·s: the multiplier of g z = bound
