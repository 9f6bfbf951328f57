"""Sparse matrices of the QP (30): min ½ zᵀPz s.t. C z = d (equalities), lo ≤ G z ≤ hi (pool).

* Equalities: boundary conditions (30b, c), dynamics (30f) and θ*(0) = θ(0).
* The inequality *pool*: region rows (30e) and speed rows (30d) at the samples
  k = 1..N−1, optional bounds on the references, the reference's steps (the
  runtime's largest step between two references, from θ(0) to the goal), and the region and
  speed rows at the K − 1 instants of ``intersample``, and speed rows at the runtime's check
  instants with its own between-sample bound
  (:func:`~spm_console.core.planning.problem.sub_instants`), so a plan meets the runtime's
  speed rules where the runtime checks them. Most pool rows are inactive at the
  optimum, so the pool is evaluated densely on a trajectory (:meth:`Pool.slack`)
  and only the rows that matter are assembled (:meth:`Pool.rows`).

Variable layout: see :class:`~spm_console.core.planning.problem.Layout`.
Pool families: 0 region at samples, 1 region between samples, 2 speed between
samples, 3 speed at samples, 4 reference bounds, 5 reference steps, 6 the reference's lead
θ*(k) − θ(k) at the samples k = 0..N−1 within the servo's linear range (when it has one).
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass, fields

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from spm_console.core.plan_rules import MAX_REFERENCE_STEP_DEG
from spm_console.core.planning.problem import Layout, PlanProblem, sub_instants
from spm_console.core.regions.route import RegionRoute

#: The largest reference step a plan may take, deg: the runtime's bound less a margin above
#: the solver's tolerance (a step the QP holds at its bound must pass the runtime's check).
PLAN_STEP_DEG = MAX_REFERENCE_STEP_DEG - 1e-6

F = NDArray[np.float64]
I = NDArray[np.int64]

FAMILY_NAMES = ("region", "region_between", "speed_between", "speed", "reference_bound",
                "reference_step", "lead")


@dataclass(frozen=True)
class Equalities:
    """Cost and equality constraints of (30)."""

    layout: Layout
    P: sp.csc_matrix
    """(n, n): 2 on every θ̇ variable — the cost Σ_k θ̇(k)ᵀθ̇(k), (deg/s)²."""
    C: sp.csc_matrix
    """(m_e, n) equality rows."""
    d: F
    """(m_e,) right-hand sides."""


def equalities(problem: PlanProblem) -> Equalities:
    """The cost and equality rows of (30) for ``problem``: the matrices depend only on the
    servo model, N and whether θ*(0) is held (kept for the next call: minimum time's probes
    and searches ask for the same N again), the right-hand sides on the start and goal."""
    N = problem.N
    A, B = problem.model.A, problem.model.B
    P, C = _equality_matrices(np.ascontiguousarray(A, float).tobytes(),
                              np.ascontiguousarray(B, float).tobytes(), N, problem.hold_first)
    rhs = [problem.start_deg, np.zeros(3), problem.goal_deg, np.zeros(3)]
    if problem.hold_first:  # (30b) as printed: θ*(0) = θ(0)
        rhs.append(problem.start_deg)
    rhs.append(np.zeros(6 * N))
    return Equalities(Layout(N), P, C, np.concatenate(rhs))


@functools.lru_cache(maxsize=32)
def _equality_matrices(a_bytes: bytes, b_bytes: bytes, N: int,
                       hold_first: bool) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """(P, C) of :func:`equalities` for the model (A, B given as their float64 bytes)."""
    Am = np.frombuffer(a_bytes, float).reshape(2, 2)
    Bm = np.frombuffer(b_bytes, float).reshape(2)
    L = Layout(N)
    n = L.n
    J = np.arange(3)
    om_all = L.om(np.repeat(np.arange(N + 1), 3), np.tile(J, N + 1)).ravel()
    P = sp.csc_matrix((np.full(om_all.size, 2.0), (om_all, om_all)), shape=(n, n))

    rows: list[I] = []
    cols: list[I] = []
    vals: list[F] = []
    m = 0

    def add(r: I, c: I, v: F | float) -> None:
        r = np.asarray(r, np.int64).ravel()
        rows.append(r)
        cols.append(np.asarray(c, np.int64).ravel())
        vals.append(np.broadcast_to(np.asarray(v, float), r.shape).ravel())

    # θ(0) = start, θ̇(0) = 0, θ(N) = goal, θ̇(N) = 0
    add(m + np.arange(12), np.concatenate([L.th(0, J), L.om(0, J), L.th(N, J), L.om(N, J)]), 1.0)
    m += 12
    if hold_first:  # θ*(0) = θ(0)
        add(m + J, L.u(0, J), 1.0)
        m += 3
    # dynamics x_i(k+1) − A x_i(k) − B θ*_i(k) = 0; rows ordered (k, i, component)
    kg, ig = np.meshgrid(np.arange(N), J, indexing="ij")
    kk, ii = kg.ravel(), ig.ravel()
    base = m + 6 * kk + 2 * ii
    for c, nxt in ((0, L.th), (1, L.om)):
        add(base + c, nxt(kk + 1, ii), 1.0)
        add(base + c, L.th(kk, ii), -Am[c, 0])
        add(base + c, L.om(kk, ii), -Am[c, 1])
        add(base + c, L.u(kk, ii), -Bm[c])
    m += 6 * N
    C = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(m, n))
    return P, C


def _same(a: object, b: object) -> bool:
    """The same field value: the same object, equal arrays or equal plain values."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    return type(a) in (int, float, bool, str) and a == b


class Pool:
    """The inequality rows of (30d, e) (and their sub-sample versions), evaluated lazily."""

    def __init__(self, problem: PlanProblem) -> None:
        self.pb = problem
        N = problem.N
        self.L = Layout(N)
        # every region of the route stacked; a row binds only the samples and intervals of
        # its region (elsewhere its bound is +∞, so it is never active)
        route = problem.regions
        self.Ap, self.bp, self.owner = route.stacked()
        self.nr = self.Ap.shape[0]
        self.route_count = route.count
        self.ApT = np.ascontiguousarray(self.Ap.T)
        anorm = np.linalg.norm(self.Ap, axis=1)
        self.sub = sub_instants(problem)
        self.Phis, self.Gams = self.sub.phis, self.sub.gams
        self._speed_weights = np.stack([self.Phis[:, 1, 0], self.Phis[:, 1, 1], self.Gams[:, 1]])
        """(3, K1): the speed at each instant between samples from [θ, θ̇, θ*] at the sample."""
        self.K1 = self.sub.count
        """Instants between samples with speed rows: intersample's and the runtime's."""
        self.req = np.flatnonzero(self.sub.requested)
        """Those of intersample's (the only ones with region rows: the runtime checks the
        workspace's certified set, which holds every region, between samples)."""
        self.KR = int(self.req.size)
        self.k0 = 1 if problem.hold_first else 0
        v = problem.vmax_degps
        has_ref = problem.ref_lo_deg is not None or problem.ref_hi_deg is not None
        sizes = [
            (N - 1) * self.nr,
            N * self.KR * self.nr,
            N * self.K1 * 3 if v is not None else 0,
            (N - 1) * 3 if v is not None else 0,
            (N - self.k0) * 3 if has_ref else 0,
            (N + 1) * 3,
            N * 3 if problem.lead_max_deg is not None else 0,
        ]
        self.sizes = sizes
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.m = int(self.offsets[-1])
        inf = np.inf
        rlo = problem.ref_lo_deg if problem.ref_lo_deg is not None else np.full(3, -inf)
        rhi = problem.ref_hi_deg if problem.ref_hi_deg is not None else np.full(3, inf)
        vv = v if v is not None else inf
        # the reference's steps θ*(k) − θ*(k−1), k = 0..N, from θ*(−1) = θ(0) (the reference
        # held before the plan) to θ*(N) = goal: the runtime refuses a step above STEP
        step = np.full((N + 1, 3), PLAN_STEP_DEG)
        start = np.asarray(problem.start_deg, float)
        goal = np.asarray(problem.goal_deg, float)
        step_lo, step_hi = -step.copy(), step.copy()
        step_lo[0] += start
        step_hi[0] += start
        step_lo[N] -= goal
        step_hi[N] -= goal
        lead = problem.lead_max_deg if problem.lead_max_deg is not None else inf
        # the speed rows between samples: v_max at intersample's instants, the runtime's
        # between-sample bound at its own check instants (row order k, instant, joint)
        sub_speed = (np.broadcast_to(self.sub.speed_bound_degps[None, :, None], (N, self.K1, 3)).ravel()
                     if sizes[2] else np.zeros(0))
        self.lo = np.concatenate([
            np.full(sizes[0], -inf), np.full(sizes[1], -inf), -sub_speed,
            np.full(sizes[3], -vv), np.tile(rlo, sizes[4] // 3), step_lo.ravel(),
            np.full(sizes[6], -lead)])
        self.hi = np.concatenate([
            self._region_bounds(route), sub_speed, np.full(sizes[3], vv), np.tile(rhi, sizes[4] // 3), step_hi.ravel(),
            np.full(sizes[6], lead)])
        self.scale = np.concatenate([
            np.tile(anorm, N - 1), np.tile(anorm, N * self.KR),
            np.ones(sizes[2] + sizes[3] + sizes[4] + sizes[5] + sizes[6])])
        self.family = np.repeat(np.arange(len(sizes)), sizes)
        """Each row's family (module docstring)."""

    def switched(self, problem: PlanProblem) -> Pool:
        """This pool for ``problem``, the same problem through the same regions with other
        switch samples (a route's switch search): only the region rows' bounds change, which
        samples and intervals each region binds."""
        old, new = self.pb.regions, problem.regions
        same_regions = len(new.regions) == len(old.regions) and all(
            a is b for a, b in zip(new.regions, old.regions, strict=True))
        others = [f.name for f in fields(problem) if f.name not in ("region", "route")]
        if not same_regions or any(not _same(getattr(problem, f), getattr(self.pb, f))
                                   for f in others):
            raise ValueError("switched: only the switch samples may differ")
        pool = copy.copy(self)
        pool.pb = problem
        pool.hi = self.hi.copy()
        pool.hi[: self.offsets[2]] = self._region_bounds(new)
        return pool

    def _region_bounds(self, route: RegionRoute) -> F:
        """Upper bounds of the region rows (families 0 and 1) for ``route``: a row binds
        only the samples and intervals of its region (elsewhere +∞, never active)."""
        N = self.pb.N
        at_samples = route.sample_mask(N)[1:N][:, self.owner]  # (N−1, nr)
        between = np.repeat(route.interval_mask(N)[:, self.owner], self.KR, axis=0)  # (N·KR, nr)
        return np.concatenate([np.where(at_samples, self.bp, np.inf).ravel(),
                               np.where(between, self.bp, np.inf).ravel()])

    def requested_speed_rows(self) -> NDArray[np.bool_]:
        """(m,) mask of the speed rows between samples at ``intersample``'s own instants
        (bound v_max; not the runtime's check instants, bound 10 % above)."""
        mask = np.zeros(self.m, bool)
        if self.sizes[2]:
            instant = (np.arange(self.sizes[2]) // 3) % self.K1  # row order: k, instant, joint
            mask[self.offsets[2]:self.offsets[3]] = self.sub.requested[instant]
        return mask

    def _split(self, z: F) -> tuple[F, F, F]:
        N = self.pb.N
        x = z[: 6 * (N + 1)].reshape(N + 1, 6)
        return x[:, :3], x[:, 3:], z[6 * (N + 1):].reshape(N, 3)

    def values(self, z: F) -> F:
        """G z for every pool row: (m,)."""
        th, om, u = self._split(z)
        N = self.pb.N
        parts = [(th[1:N] @ self.ApT).ravel()]
        if self.K1:
            Ph, Ga = self.Phis, self.Gams
            if self.KR:
                Pr, Gr = Ph[self.req], Ga[self.req]
                ths = (th[:N, None, :] * Pr[None, :, 0, 0, None] + om[:N, None, :] * Pr[None, :, 0, 1, None]
                       + u[:, None, :] * Gr[None, :, 0, None])
                parts.append((ths @ self.ApT).ravel())
            if self.sizes[2]:  # θ̇ at instant j of interval k: [θ, θ̇, θ*](k) · (Φ_j[1], Γ_j[1])
                oms = np.stack([th[:N], om[:N], u], axis=-1) @ self._speed_weights
                parts.append(oms.transpose(0, 2, 1).ravel())
        if self.sizes[3]:
            parts.append(om[1:N].ravel())
        if self.sizes[4]:
            parts.append(u[self.k0:].ravel())
        zero = np.zeros((1, 3))
        parts.append(np.diff(np.vstack([zero, u, zero]), axis=0).ravel())
        if self.sizes[6]:
            parts.append((u - th[:N]).ravel())
        return np.concatenate(parts) if parts else np.zeros(0)

    def slack(self, z: F) -> F:
        """Normalized slack (deg for region rows, deg/s for speed rows); < 0 = violated."""
        gz = self.values(z)
        with np.errstate(invalid="ignore"):
            s = np.minimum(self.hi - gz, gz - self.lo)
        return np.asarray(s / self.scale)

    def rows(self, idx: I) -> sp.csr_matrix:
        """The pool rows ``idx`` as a sparse (len(idx), n) matrix."""
        idx = np.asarray(idx, np.int64)
        r, c, v = self.triplets(idx)
        return sp.csr_matrix((v, (r, c)), shape=(idx.size, self.L.n))

    def dense_row(self, i: int) -> F:
        """Pool row ``i`` as a dense (n,) vector (the same entries as :meth:`rows`)."""
        _, c, v = self.triplets(np.array([i], np.int64))
        out = np.zeros(self.L.n)
        np.add.at(out, c, v)
        return out

    def triplets(self, idx: I) -> tuple[I, I, F]:
        """(row position, column, value) of the entries of the pool rows ``idx``."""
        L = self.L
        N = self.pb.N
        fam = self.family[idx]
        rows: list[I] = []
        cols: list[I] = []
        vals: list[F] = []
        pos = np.arange(idx.size)
        for f in range(len(self.sizes)):
            sel = fam == f
            if not sel.any():
                continue
            loc = idx[sel] - self.offsets[f]
            rp = pos[sel]
            if f == 0:
                k, r = loc // self.nr + 1, loc % self.nr
                for i in range(3):
                    rows.append(rp)
                    cols.append(L.th(k, i))
                    vals.append(self.Ap[r, i])
            elif f == 1:
                kj, r = loc // self.nr, loc % self.nr
                k, j = kj // self.KR, self.req[kj % self.KR]
                for i in range(3):
                    a = self.Ap[r, i]
                    for var, coef in ((L.th, self.Phis[j, 0, 0]), (L.om, self.Phis[j, 0, 1]),
                                      (L.u, self.Gams[j, 0])):
                        rows.append(rp)
                        cols.append(var(k, i))
                        vals.append(a * coef)
            elif f == 2:
                kj, i = loc // 3, loc % 3
                k, j = kj // self.K1, kj % self.K1
                for var, coef in ((L.th, self.Phis[j, 1, 0]), (L.om, self.Phis[j, 1, 1]),
                                  (L.u, self.Gams[j, 1])):
                    rows.append(rp)
                    cols.append(var(k, i))
                    vals.append(coef)
            elif f == 3:
                rows.append(rp)
                cols.append(L.om(loc // 3 + 1, loc % 3))
                vals.append(np.ones(loc.size))
            elif f == 4:
                rows.append(rp)
                cols.append(L.u(loc // 3 + self.k0, loc % 3))
                vals.append(np.ones(loc.size))
            elif f == 5:  # the step into θ*(k): +θ*(k) (k < N), −θ*(k−1) (k > 0)
                k, i = loc // 3, loc % 3
                now, before = k < N, k > 0
                rows += [rp[now], rp[before]]
                cols += [L.u(k[now], i[now]), L.u(k[before] - 1, i[before])]
                vals += [np.ones(int(now.sum())), -np.ones(int(before.sum()))]
            else:  # the lead θ*(k) − θ(k)
                k, i = loc // 3, loc % 3
                rows += [rp, rp]
                cols += [L.u(k, i), L.th(k, i)]
                vals += [np.ones(loc.size), -np.ones(loc.size)]
        if not rows:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return (np.concatenate(rows).astype(np.int64), np.concatenate(cols).astype(np.int64),
                np.concatenate(vals).astype(float))

    def _row_name(self, r: int) -> str:
        if self.route_count == 1:
            return f"region half-space {r}"
        i = int(self.owner[r])
        first = int(np.flatnonzero(self.owner == i)[0])
        return f"half-space {r - first} of region {i} of the route"

    def _instant(self, j: int) -> str:
        f = self.sub.fractions[j]
        return f"{f.numerator}/{f.denominator} of the period" + (
            "" if self.sub.requested[j] else " (a runtime check instant)")

    def describe(self, i: int) -> str:
        """Human name of pool row ``i`` (e.g. 'region half-space 12 at k = 40')."""
        f = int(self.family[i])
        loc = int(i - self.offsets[f])
        if f == 0:
            return f"{self._row_name(loc % self.nr)} at k = {loc // self.nr + 1}"
        if f == 1:
            kj = loc // self.nr
            return (f"{self._row_name(loc % self.nr)} between samples k = {kj // self.KR} and "
                    f"the next, at {self._instant(int(self.req[kj % self.KR]))}")
        if f == 2:
            kj = loc // 3
            return (f"speed of joint {loc % 3 + 1} between k = {kj // self.K1} and the next, at "
                    f"{self._instant(kj % self.K1)}")
        if f == 3:
            return f"speed of joint {loc % 3 + 1} at k = {loc // 3 + 1}"
        if f == 4:
            return f"reference bound of joint {loc % 3 + 1} at k = {loc // 3 + self.k0}"
        if f == 5:
            return f"reference step of joint {loc % 3 + 1} into k = {loc // 3}"
        return (f"lead θ* − θ of joint {loc % 3 + 1} at k = {loc // 3} (the servo's linear "
                "range)")
