"""IK∘FK and FK∘IK round trips on random configurations; residuals; modes; ζ."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.kinematics.ik import ik, ik_rpy
from spm_console.core.kinematics.jacobian import conditioning_index, jacobian
from spm_console.core.kinematics.modes import assembly_modes, seeded_solve
from spm_console.errors import BadInputError


def test_ik_of_fk_1200_random(agile_model) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(1)
    T = np.radians(rng.uniform(65.0, 155.0, (1200, 3)))
    results = agile_model.track_batch(T)
    ok = [r for r in results if r.ok]
    assert len(ok) >= 1100  # a few straight paths from home cross a singularity: refused, not wrong
    for th, r in zip(T, results, strict=True):
        if not r.ok:
            assert "singularity" in r.reason
            continue
        assert r.pose.residual <= 1e-12
        back = ik(agile_model, r.pose.v).theta
        np.testing.assert_allclose(back, th, atol=1e-9)


def test_fk_of_ik_1000_random_orientations(agile_model) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(2)
    sols = [ik_rpy(agile_model, *rpy) for rpy in np.radians(rng.uniform(-30.0, 30.0, (1000, 3)))]
    results = agile_model.track_batch(np.array([s.theta for s in sols]))
    checked = 0
    for sol, r in zip(sols, results, strict=True):
        if not r.ok:
            continue
        np.testing.assert_allclose(r.pose.v, sol.v, atol=1e-9)
        checked += 1
    assert checked >= 990


def test_ik_rejects_bad_orientation(agile_model) -> None:  # type: ignore[no-untyped-def]
    v = agile_model.v_home.copy()
    v[0] *= 1.1
    with pytest.raises(BadInputError, match="unit vectors"):
        ik(agile_model, v)
    with pytest.raises(BadInputError, match="handedness"):
        ik(agile_model, agile_model.v_home * np.array([-1.0, 1.0, 1.0]))


def test_assembly_modes_home_flagged(agile_model) -> None:  # type: ignore[no-untyped-def]
    th = np.radians([95.0, 110.0, 105.0])
    r = agile_model.track(th)
    modes = assembly_modes(agile_model, th, r.pose.R)
    assert 2 <= len(modes) <= 8
    assert sum(m.home_connected for m in modes) == 1
    assert all(m.residual < 1e-10 for m in modes)
    home = next(m for m in modes if m.home_connected)
    np.testing.assert_allclose(home.v, r.pose.v, atol=1e-9)


def test_seeded_solve_agrees_at_paper_point(agile_model, agile) -> None:  # type: ignore[no-untyped-def]
    th = np.radians([95.0, 110.0, 105.0])
    v, ok = seeded_solve(agile_model.geom, th, np.asarray(agile.home.sign_seed, float))
    assert ok
    np.testing.assert_allclose(v, agile_model.track(th).pose.v, atol=1e-9)


def test_zeta_matches_direct_formula_and_is_zero_at_singularity(agile_model) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(3)
    thetas = np.radians(rng.uniform(80, 140, (50, 3)))
    for th, r in zip(thetas, agile_model.track_batch(thetas), strict=True):
        assert r.ok
        w = agile_model.geom.w(th)
        J = jacobian(agile_model.u, r.pose.v, w)
        W = np.eye(3) / 3
        k = np.sqrt(np.trace(J.T @ W @ J)) * np.sqrt(np.trace(np.linalg.inv(J).T @ W @ np.linalg.inv(J)))
        assert conditioning_index(agile_model.u, r.pose.v, w) == pytest.approx(1 / k, rel=1e-10)
    # exact singularities: v1 = w1 makes a zero row of J1; a leg in the u-w plane zeroes J2
    w = agile_model.geom.w(np.radians([135.0, 135.0, 135.0]))
    v = agile_model.v_home.copy()
    v[0] = w[0]
    assert conditioning_index(agile_model.u, v, w) == 0.0
    v = agile_model.v_home.copy()
    v[1] = agile_model.u[1]
    assert conditioning_index(agile_model.u, v, w) == 0.0


def test_mode_search_finds_the_same_poses_from_scipys_random_rotations(  # type: ignore[no-untyped-def]
        agile_model, monkeypatch) -> None:
    """The multi-start search seeds from our own uniform rotations; seeding it instead from
    scipy's ``Rotation.random`` (an independent sampler) finds the same set of poses."""
    from scipy.spatial.transform import Rotation

    import spm_console.core.kinematics.modes as modes

    rng = np.random.default_rng(4)
    thetas = np.radians(np.vstack([[95.0, 110.0, 105.0], rng.uniform(70.0, 150.0, (5, 3))]))
    ours = [modes.solve_all(agile_model.geom, th, agile_model.v_home) for th in thetas]
    monkeypatch.setattr(modes, "random_rotations",
                        lambda n, seed: Rotation.random(n, random_state=seed).as_matrix())
    theirs = [modes.solve_all(agile_model.geom, th, agile_model.v_home) for th in thetas]
    for a, b in zip(ours, theirs, strict=True):
        assert len(a) == len(b) >= 2
        for Ra in a:
            assert min(np.abs(Ra - Rb).max() for Rb in b) < 1e-8
