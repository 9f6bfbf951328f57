"""Closed-form segment distance (core.links) against the paper's QP (24) in cvxpy."""

from __future__ import annotations

import warnings

import cvxpy as cp
import numpy as np
import pytest

from spm_console.core.kinematics.links import segment_distance

KINDS = ("general", "parallel", "collinear", "touching", "zero_one", "zero_both", "shared_end",
         "tiny")


def _pair(kind: str, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    p1, q1, p2, q2 = rng.uniform(-100.0, 100.0, (4, 3))
    d1 = q1 - p1
    if kind == "parallel":
        q2 = p2 + d1 * rng.uniform(-2.0, 2.0)
    elif kind == "collinear":  # same line, overlapping or apart
        p2 = p1 + d1 * rng.uniform(-1.5, 2.5)
        q2 = p1 + d1 * rng.uniform(-1.5, 2.5)
    elif kind == "touching":  # crossing segments: distance 0
        pt = p1 + rng.uniform(0.0, 1.0) * d1
        q2 = pt + (pt - p2) * rng.uniform(0.0, 1.0)
    elif kind == "zero_one":
        q2 = p2.copy()
    elif kind == "zero_both":
        q1, q2 = p1.copy(), p2.copy()
    elif kind == "shared_end":
        p2 = q1.copy()
    elif kind == "tiny":  # nearly degenerate
        q1 = p1 + rng.normal(size=3) * 1e-7
    return p1, q1, p2, q2


@pytest.fixture(scope="module")
def qp24() -> tuple[cp.Problem, cp.Parameter, cp.Parameter]:
    """min ‖x1 − x2‖ with x1 ∈ conv{p1, q1}, x2 ∈ conv{p2, q2} (eq. 24), compiled once."""
    x1, x2 = cp.Variable(3), cp.Variable(3)
    l1, l2 = cp.Variable(2, nonneg=True), cp.Variable(2, nonneg=True)
    V1, V2 = cp.Parameter((3, 2)), cp.Parameter((3, 2))
    prob = cp.Problem(
        cp.Minimize(cp.norm(x1 - x2)),
        [x1 == V1 @ l1, x2 == V2 @ l2, cp.sum(l1) == 1, cp.sum(l2) == 1],
    )
    assert prob.is_dpp()
    return prob, V1, V2


def test_closed_form_matches_qp24(qp24: tuple[cp.Problem, cp.Parameter, cp.Parameter]) -> None:
    prob, V1, V2 = qp24
    rng = np.random.default_rng(20240601)
    n = 1200
    P1, Q1, P2, Q2, ref = [], [], [], [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in range(n):
            p1, q1, p2, q2 = _pair(KINDS[i % len(KINDS)], rng)
            V1.value = np.column_stack([p1, q1])
            V2.value = np.column_stack([p2, q2])
            prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
            assert prob.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)
            P1.append(p1)
            Q1.append(q1)
            P2.append(p2)
            Q2.append(q2)
            ref.append(prob.value)
    got = segment_distance(np.array(P1), np.array(Q1), np.array(P2), np.array(Q2))
    err = np.abs(got - np.array(ref))
    kinds = np.array([KINDS[i % len(KINDS)] for i in range(n)])
    for k in KINDS:
        assert err[kinds == k].max() <= 1e-6, f"{k}: max error {err[kinds == k].max():.2e} mm"
    # the touching cases really are at distance 0 (the test would miss bugs otherwise)
    assert np.all(got[(kinds == "touching") | (kinds == "shared_end")] < 1e-9)


def test_symmetry_and_swap() -> None:
    rng = np.random.default_rng(3)
    p1, q1, p2, q2 = rng.uniform(-50, 50, (4, 500, 3))
    a = segment_distance(p1, q1, p2, q2)
    assert np.allclose(a, segment_distance(p2, q2, p1, q1), atol=1e-9)
    assert np.allclose(a, segment_distance(q1, p1, q2, p2), atol=1e-9)


def test_brute_force_upper_bound() -> None:
    """The exact distance never exceeds any sampled pair of points, and nearly attains it."""
    rng = np.random.default_rng(5)
    s = np.linspace(0, 1, 201)
    for _ in range(50):
        p1, q1, p2, q2 = rng.uniform(-50, 50, (4, 3))
        X = p1 + s[:, None] * (q1 - p1)
        Y = p2 + s[:, None] * (q2 - p2)
        brute = np.linalg.norm(X[:, None] - Y[None], axis=-1).min()
        d = float(segment_distance(p1, q1, p2, q2))
        assert d <= brute + 1e-9
        assert brute - d < 1.0  # 0.5 % grid on ~100 mm segments


def test_every_link_pair_is_the_distance_of_its_two_segments() -> None:
    """``LinkModel.pair_distances`` (per axis, per segment, gathered into pairs) gives, for
    every pair of :meth:`pairs`, the segment distance of that pair's end points (18)-(23)."""
    from spm_console.config.load import load_profile
    from spm_console.config.models import link_model_of, model_of
    from spm_console.core.kinematics.links import SEGMENT_ENDS, LinkModel
    from spm_console.core.kinematics.model import platform_axes
    from spm_console.core.kinematics.rotations import random_rotations

    prof = load_profile("profiles/agile_wrist.toml")
    model = model_of(prof)
    rng = np.random.default_rng(17)
    w = model.geom.w(rng.uniform(-np.pi, np.pi, (300, 3)))
    v = platform_axes(random_rotations(300, 17), model.v_home)
    for segments in (link_model_of(prof).segments, ("AB", "BC", "DE", "EF")):
        links = LinkModel(**{**link_model_of(prof).__dict__, "segments": segments})
        pts = links.points(model.u, w, v)
        got = links.pair_distances(model.u, w, v)
        pairs = links.pairs()
        assert got.shape == (300, len(pairs))
        for k, (i, s1, j, s2) in enumerate(pairs):
            (a1, b1), (a2, b2) = SEGMENT_ENDS[s1], SEGMENT_ENDS[s2]
            ref = segment_distance(pts[a1][:, i], pts[b1][:, i], pts[a2][:, j], pts[b2][:, j])
            assert np.abs(got[:, k] - ref).max() <= 1e-9, (i, s1, j, s2)
        d, at = links.min_distance(model.u, w, v)
        assert np.array_equal(d, got.min(-1)) and np.array_equal(at, got.argmin(-1))
