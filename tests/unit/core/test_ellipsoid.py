"""The maximum-volume inscribed ellipsoid in conic form against cvxpy's own formulation."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.polytope.ellipsoid import _conic_mvie, _cvxpy_mvie, inscribed_ellipsoid


def _polytope(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    N = rng.normal(size=(m, 3))
    N /= np.linalg.norm(N, axis=1)[:, None]
    b = rng.uniform(0.3, 1.5, m) + N @ rng.normal(scale=0.1, size=3)
    return np.vstack([N, np.eye(3), -np.eye(3)]), np.r_[b, np.full(6, 2.0)]


@pytest.mark.parametrize("m", [4, 12, 40, 90])
def test_conic_form_matches_cvxpy_and_fits_inside(m: int) -> None:
    rng = np.random.default_rng(m)
    A, b = _polytope(rng, m)
    got = _conic_mvie(A, b)
    assert got is not None
    E = inscribed_ellipsoid(A, b)
    ref = _cvxpy_mvie(A, b)  # cvxpy's log_det canonicalization, an independent formulation
    assert E.log_volume == pytest.approx(ref.log_volume, abs=1e-6)
    assert np.allclose(E.d, ref.d, atol=1e-4)
    # inside: ‖C a_i‖ + a_iᵀ d ≤ b_i for every row
    assert (np.linalg.norm(A @ E.C, axis=1) + A @ E.d - b).max() <= 1e-12


def test_a_box_gives_its_inscribed_ball() -> None:
    """The cube [-1, 1]³ holds the unit ball, and no larger ellipsoid (by symmetry)."""
    A = np.vstack([np.eye(3), -np.eye(3)])
    E = inscribed_ellipsoid(A, np.ones(6))
    assert np.allclose(E.C, np.eye(3), atol=1e-6)
    assert np.allclose(E.d, 0.0, atol=1e-6)
