"""The signed distance to the edge of P′ against a brute-force reference and the membership
test it must agree with."""

from __future__ import annotations

import numpy as np

from spm_console.core.workspace.certify import CertifiedSet
from spm_console.core.workspace.margin import certified_margin_deg


def _brute(cert: CertifiedSet, th: np.ndarray) -> np.ndarray:
    shape = np.array(cert.feasible.shape)
    lo = cert.origin_deg
    hi = lo + (shape - 1) * cert.step_deg
    out = []
    blocked = lo + np.argwhere(~cert.feasible) * cert.step_deg
    for p in th:
        m = float(np.minimum(p - lo, hi - p).min())
        if len(blocked):
            m = min(m, float(np.abs(blocked - p).max(axis=1).min()) - cert.step_deg)
        out.append(m)
    return np.array(out)


def _cert(seed: int) -> CertifiedSet:
    rng = np.random.default_rng(seed)
    feasible = rng.random((9, 8, 7)) > 0.15
    return CertifiedSet(feasible, np.array([10.0, -5.0, 40.0]), 2.5)


def test_the_margin_is_the_brute_force_distance() -> None:
    for seed in range(5):
        cert = _cert(seed)
        rng = np.random.default_rng(100 + seed)
        th = cert.origin_deg + rng.uniform(-3.0, 23.0, (400, 3))
        np.testing.assert_allclose(certified_margin_deg(cert, th), _brute(cert, th), atol=1e-12)


def test_positive_margins_are_certified_and_negative_ones_are_not() -> None:
    cert = _cert(7)
    rng = np.random.default_rng(3)
    th = cert.origin_deg + rng.uniform(0.0, 17.5, (4000, 3))
    m = certified_margin_deg(cert, th)
    inside = cert.contains(th)
    assert np.all(inside[m > 1e-9]) and not np.any(inside[m < -1e-9])


def test_shape_nan_and_a_fully_feasible_grid() -> None:
    cert = CertifiedSet(np.ones((3, 3, 3), bool), np.zeros(3), 1.0)
    m = certified_margin_deg(cert, np.array([[[1.0, 1.0, 0.5], [np.nan, 0.0, 0.0]]]))
    assert m.shape == (1, 2)
    assert m[0, 0] == 0.5 and np.isnan(m[0, 1])
