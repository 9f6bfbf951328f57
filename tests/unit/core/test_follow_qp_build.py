"""The follow QP's matrices, assembled for all samples at once, are the ones written row by row
from the module docstring's equations (the reference below), for any region, horizon and
bounds."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from spm_console.core.planning.follow.qp import (
    FIXED_ROWS,
    FollowLayout,
    FollowMatrices,
    build,
)
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import ServoModel
from tests.support.planning_cases import MODEL

F = np.ndarray
I = np.ndarray


def _one_entry_at_a_time(model: ServoModel, region: Region, vmax_degps: float, H: int,
                         ref_lo_deg: F, ref_hi_deg: F, track_weight: float, margin_deg: float,
                         speed_margin_degps: float, step_deg: float = np.inf,
                         lead_deg: float = np.inf) -> FollowMatrices:
    """The follow QP written row by row from the module docstring, one sample, joint and
    entry at a time."""
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


def _region(n: int, seed: int) -> Region:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, 3))
    A[0, 1] = 0.0  # an explicit zero in A keeps its place in the pattern
    return Region(A, rng.uniform(5.0, 50.0, n) + A @ np.full(3, 135.0))


@pytest.mark.parametrize(("H", "nr", "step", "lead"),
                         [(1, 6, np.inf, np.inf), (2, 7, 3.0, np.inf), (50, 14, 2.5, 4.0),
                          (17, 1, np.inf, 1.5)])
def test_the_matrices_are_the_ones_written_row_by_row(H: int, nr: int, step: float,
                                                       lead: float) -> None:
    region = _region(nr, H)
    args = (MODEL, region, 50.0, H, np.full(3, 60.0), np.array([160.0, 161.0, 162.0]),
            0.3, 0.05, 1.0, step, lead)
    got, want = build(*args), _one_entry_at_a_time(*args)
    assert got.layout == want.layout and (got.step_deg, got.lead_deg) == (step, lead)
    for name in ("A", "P"):
        g, w = getattr(got, name), getattr(want, name)
        g.sort_indices()
        w.sort_indices()
        assert g.shape == w.shape and g.nnz == w.nnz  # the same pattern, zeros included
        np.testing.assert_array_equal(g.indptr, w.indptr)
        np.testing.assert_array_equal(g.indices, w.indices)
        np.testing.assert_array_equal(g.data, w.data)
    np.testing.assert_array_equal(got.lo, want.lo)
    np.testing.assert_array_equal(got.hi, want.hi)
