"""The continuation step's two forms (the array :class:`Step` and the component
:class:`KernelStep` the workspace checks use) give one verdict."""

from __future__ import annotations

import numpy as np

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
