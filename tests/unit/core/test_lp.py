"""The region builder's LP route (HiGHS through highspy, one solver per thread) against
scipy's linprog (HiGHS behind scipy's own checks and presolve): same status, same optimum."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from scipy.optimize import linprog

from spm_console.core.polytope.lp import INFEASIBLE, OPTIMAL, UNBOUNDED, solve_lp
from spm_console.core.polytope.region import Region


def _random_lp(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    A = rng.normal(size=(m, 3))
    b = rng.uniform(0.5, 2.0, m) + A @ rng.normal(scale=0.2, size=3)
    return rng.normal(size=3), A, b


def test_random_lps_agree_with_scipy() -> None:
    rng = np.random.default_rng(7)
    seen = set()
    for trial in range(300):
        c, A, b = _random_lp(rng, int(rng.integers(2, 60)))
        lo = np.where(rng.random(3) < 0.3, -1.0, -np.inf)
        hi = np.where(rng.random(3) < 0.3, 1.0, np.inf)
        if trial % 7 == 0:  # an infeasible one: x1 ≤ −1 and −x1 ≤ −1
            A = np.vstack([A, [1.0, 0, 0], [-1.0, 0, 0]])
            b = np.r_[b, -1.0, -1.0]
        ref = linprog(c, A_ub=A, b_ub=b, bounds=list(zip(lo, hi, strict=True)), method="highs")
        got = solve_lp(c, A, b, lower=lo, upper=hi)
        assert got.status == ref.status, (trial, got.status, ref.status)
        seen.add(got.status)
        if ref.status == 0:
            assert got.fun == pytest.approx(ref.fun, abs=1e-7 * max(1.0, abs(ref.fun)))
            assert np.all(A @ got.x <= b + 1e-7) and np.all(got.x >= lo - 1e-9) and np.all(got.x <= hi + 1e-9)
    assert seen == {OPTIMAL, INFEASIBLE, UNBOUNDED}


def test_chebyshev_centre_of_a_box_and_of_an_empty_region() -> None:
    c, r = Region.box(65.0, 155.0).chebyshev()
    np.testing.assert_allclose(c, [110.0] * 3)
    assert r == pytest.approx(45.0)
    empty = Region(np.array([[1.0, 0, 0], [-1.0, 0, 0]]), np.array([-1.0, -1.0]))
    assert empty.chebyshev()[1] < 0


def test_threads_each_get_their_own_solver() -> None:
    """A build in a worker thread and one in the caller's must not share a solver."""
    rng = np.random.default_rng(3)
    lps = [_random_lp(rng, 40) for _ in range(40)]
    lo = np.full(3, -10.0)
    hi = np.full(3, 10.0)
    want = [linprog(c, A_ub=A, b_ub=b, bounds=[(-10, 10)] * 3, method="highs").fun for c, A, b in lps]
    out: dict[int, list[float]] = {}

    def work(k: int) -> None:
        out[k] = [solve_lp(c, A, b, lower=lo, upper=hi).fun for c, A, b in lps]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(3):
        np.testing.assert_allclose(out[k], want, atol=1e-7)
