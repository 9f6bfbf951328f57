"""Membership tests of a region in blocks of points give what one pass over all the points
gives, for every shape of input around the block size."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.polytope.region import BLOCK_POINTS, INSIDE_TOL_DEG, Region


@pytest.mark.parametrize("shape", [(3,), (1, 3), (5, 3), (BLOCK_POINTS, 3), (BLOCK_POINTS + 1, 3),
                                   (3 * BLOCK_POINTS + 17, 3), (7, 1500, 3), (0, 3)])
def test_blocks_agree_with_one_pass_over_all_points(shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(len(shape) * 1000 + shape[0])
    region = Region(rng.normal(size=(24, 3)), rng.uniform(0.5, 2.0, 24))
    theta = rng.normal(size=shape)
    slack = region.b - theta @ region.A.T  # one pass: (..., 24)
    inside = region.contains(theta)
    assert inside.shape == shape[:-1] and inside.dtype == np.bool_
    assert np.array_equal(inside, (slack >= -INSIDE_TOL_DEG).all(-1))
    norms = np.linalg.norm(region.A, axis=1)
    out = region.violation_deg(theta)
    assert out.shape == shape[:-1]
    assert np.array_equal(out, np.maximum(0.0, (-slack / norms).max(-1, initial=-np.inf)))
    # and a few points by hand, row by row
    flat, flat_in = theta.reshape(-1, 3), inside.reshape(-1)
    for k in range(0, len(flat), max(1, len(flat) // 7)):
        by_rows = all(float(a @ flat[k]) <= float(bi) + INSIDE_TOL_DEG
                      for a, bi in zip(region.A, region.b, strict=True))
        assert by_rows == bool(flat_in[k])
    assert inside.size < 10 or 0 < inside.mean() < 1
