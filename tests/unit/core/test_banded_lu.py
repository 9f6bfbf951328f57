"""The banded LU of a KKT matrix (:mod:`spm_console.core.planning.solvers.banded`) against
numpy's dense solve, its SuperLU fallback, and singular matrices."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from spm_console.core.planning.active_set import REG_DUAL, REG_PRIMAL
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.qp_build import equalities
from spm_console.core.planning.solvers.banded import MAX_BAND, BandedLu, factor
from spm_console.core.polytope.region import Region
from tests.support.ws_helpers import agile_profile


def _kkt(N: int) -> tuple[sp.csr_matrix, np.ndarray]:
    from spm_console.config.models import servo_model_of

    box = Region(np.vstack([np.eye(3), -np.eye(3)]), np.full(6, 200.0))
    pb = PlanProblem(servo_model_of(agile_profile()), np.array([90.0, 90, 90]),
                     np.array([100.0, 110, 95]), N, box)
    eq = equalities(pb)
    n, m = eq.P.shape[0], eq.C.shape[0]
    K = sp.bmat([[eq.P, eq.C.T], [eq.C, None]], format="csr")
    return K, np.concatenate([np.full(n, REG_PRIMAL), np.full(m, -REG_DUAL)])


def test_the_kkt_matrix_is_banded_and_solves_as_a_dense_solve() -> None:
    rng = np.random.default_rng(3)
    for N in (5, 40, 150):
        K, shift = _kkt(N)
        lu = factor(K, shift)
        assert isinstance(lu, BandedLu) and lu.band <= 8  # a chain of small blocks
        dense = K.toarray() + np.diag(shift)
        rhs = rng.normal(size=K.shape[0])
        np.testing.assert_allclose(lu.solve(rhs), np.linalg.solve(dense, rhs),
                                   rtol=1e-8, atol=1e-8 * np.abs(rhs).max())


def test_a_wide_band_goes_to_superlu_with_the_same_answer() -> None:
    rng = np.random.default_rng(4)
    n = 3 * MAX_BAND
    dense = rng.normal(size=(n, n))
    dense = dense + dense.T + 4 * n * np.eye(n)  # full, symmetric, well conditioned
    shift = rng.uniform(0.5, 1.0, n)
    lu = factor(sp.csr_matrix(dense), shift)
    assert lu is not None and not isinstance(lu, BandedLu)
    rhs = rng.normal(size=n)
    np.testing.assert_allclose(lu.solve(rhs), np.linalg.solve(dense + np.diag(shift), rhs),
                               rtol=1e-10)


def test_a_singular_matrix_has_no_factor() -> None:
    # a path graph (banded) whose second row repeats the first: an exactly zero pivot
    K = sp.csr_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    assert factor(K, np.zeros(3)) is None
