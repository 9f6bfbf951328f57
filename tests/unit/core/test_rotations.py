"""Quaternions of rotation matrices against SciPy's (an independent implementation)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from spm_console.core.kinematics.rotations import matrix_quaternion, random_rotations


def test_quaternions_equal_scipys_up_to_sign_including_half_turns() -> None:
    R = np.concatenate([random_rotations(2000, 3), np.eye(3)[None],
                        np.diag([1.0, -1.0, -1.0])[None], np.diag([-1.0, 1.0, -1.0])[None],
                        np.diag([-1.0, -1.0, 1.0])[None]])
    q = matrix_quaternion(R)
    ref = Rotation.from_matrix(R).as_quat()  # x, y, z, w
    err = np.minimum(np.abs(q - ref).max(axis=1), np.abs(q + ref).max(axis=1))
    assert err.max() < 1e-14
    assert np.all(q[:, 3] >= 0) and np.allclose(np.linalg.norm(q, axis=1), 1.0)
