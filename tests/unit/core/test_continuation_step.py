"""The continuation step's two forms (the array :class:`Step` and the component
:class:`KernelStep` the workspace checks use) give one verdict."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.continuation import (
    PATH_ZETA_FLOOR,
    Kernel,
    continuation_step,
    from_mat,
    to_mat,
    to_vec,
)


def test_kernel_step_and_step_agree_on_every_row(agile: Profile) -> None:
    """Short steps that converge, long ones that jump or leave the home modes, and a
    non-finite start: both forms mark the same rows good, at every ζ floor."""
    model = model_of(agile)
    rng = np.random.default_rng(7)
    n = 400
    th0 = np.tile(model.theta_home, (n, 1))
    R0 = np.tile(np.eye(3), (n, 1, 1))
    R0[0] = np.nan
    size = np.where(np.arange(n) % 2 == 0, 0.01, 1.5)[:, None]  # rad
    th1 = th0 + size * rng.uniform(-1.0, 1.0, (n, 3))
    ks = Kernel(model).step(to_vec(th0), to_mat(R0), to_vec(th1))
    st = continuation_step(model, th0, R0, th1)
    np.testing.assert_array_equal(from_mat(ks.R), st.R)
    for floor in (PATH_ZETA_FLOOR, 0.2, 0.5):
        good = ks.good(floor)
        np.testing.assert_array_equal(good, st.good(floor))
        assert good.any() and not good.all()


def test_one_row_on_floats_agrees_with_the_array_form(agile: Profile) -> None:
    """The one-row step (Python floats) and the array step of the same rows: the same
    verdict at every ζ floor and the same numbers to rounding, on steps that converge, jump,
    leave the home modes, start from a non-finite rotation or go to a non-finite θ."""
    model = model_of(agile)
    rng = np.random.default_rng(11)
    n = 300
    th0 = np.tile(model.theta_home, (n, 1)) + rng.uniform(-0.3, 0.3, (n, 3))
    R0 = np.stack([model.track(t).pose.R for t in th0])
    R0[0] = np.nan
    size = np.where(np.arange(n) % 3 == 0, 0.01, np.where(np.arange(n) % 3 == 1, 0.2, 1.5))
    th1 = th0 + size[:, None] * rng.uniform(-1.0, 1.0, (n, 3))
    th1[1, 2] = np.inf
    th1[2, 0] = np.nan
    whole = continuation_step(model, th0, R0, th1)
    rows = [continuation_step(model, th0[k:k + 1], R0[k:k + 1], th1[k:k + 1]) for k in range(n)]
    for floor in (PATH_ZETA_FLOOR, 0.2, 0.5):
        good = np.concatenate([r.good(floor) for r in rows])
        np.testing.assert_array_equal(good, whole.good(floor))
        assert good.any() and not good.all()
    ok = whole.good()
    one_R = np.concatenate([r.R for r in rows])
    np.testing.assert_allclose(one_R[ok], whole.R[ok], rtol=0, atol=1e-14)
    for name in ("zeta", "det_side", "leg_sides"):
        one = np.concatenate([np.atleast_1d(getattr(r, name)) for r in rows])
        np.testing.assert_allclose(one[ok], getattr(whole, name)[ok], rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(np.concatenate([r.converged for r in rows]), whole.converged)


def test_tracking_one_pose_on_floats_agrees_with_tracking_it_in_a_batch(agile: Profile) -> None:
    """``track`` of one θ (the float march) against the same θ tracked in a batch (the array
    march): the same verdict, reason, steps and path, and the same pose to rounding, for
    targets reached, past a singularity, with steps too long to converge, and refused."""
    model = model_of(agile)
    rng = np.random.default_rng(5)
    targets = list(model.theta_home + rng.uniform(-2.5, 2.5, (24, 3)))
    targets += [model.theta_home + np.array([0.0, 0.0, np.nan]), model.theta_home + 20.0]
    verdicts = set()
    for t in targets:
        for step_deg in (2.0, 40.0):
            step = np.radians(step_deg)
            one = model.track(t, max_step=step)
            pair = model.track_batch(np.stack([t, model.theta_home]), max_step=step)[0]
            assert (one.ok, one.reason, one.steps) == (pair.ok, pair.reason, pair.steps)
            assert one.path_min_zeta == pytest.approx(pair.path_min_zeta, rel=1e-12)
            assert one.pose is not None and pair.pose is not None
            np.testing.assert_allclose(one.pose.R, pair.pose.R, rtol=0, atol=1e-13)
            assert one.pose.zeta == pytest.approx(pair.pose.zeta, rel=1e-12)
            kept = model.track_batch(t[None], max_step=step, keep_path=True)[0]
            both = model.track_batch(np.stack([t, t]), max_step=step, keep_path=True)[0]
            np.testing.assert_allclose(np.array(kept.path_theta_deg),
                                       np.array(both.path_theta_deg), rtol=0, atol=1e-12)
            verdicts.add("refused" if one.reason.startswith("θ =") else one.reason[:17] or "ok")
    assert verdicts == {"ok", "crosses a type-2 ", "corrector did not", "refused"}, verdicts


def test_one_pose_takes_its_start_in_the_shapes_a_batch_takes(agile: Profile) -> None:
    """A start θ of shape (1, 3) and R of shape (1, 3, 3) are broadcast as in a batch, and a
    one-row step towards several targets steps every target."""
    model = model_of(agile)
    h = model.theta_home
    plain = model.track(h + 0.1)
    for kw in ({"theta_from": h[None]}, {"R_from": np.eye(3)[None]}):
        r = model.track(h + 0.1, **kw)  # type: ignore[arg-type]
        assert r.ok and r.steps == plain.steps
        np.testing.assert_allclose(r.pose.R, plain.pose.R, rtol=0, atol=1e-15)
    st = continuation_step(model, h[None], np.eye(3)[None], np.stack([h + 0.01, h - 0.01]))
    assert st.R.shape == (2, 3, 3) and st.good().all()
