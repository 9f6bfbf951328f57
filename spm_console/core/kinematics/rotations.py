"""Rotation helpers, vectorized over leading batch dimensions (radians)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]


def skew(w: F) -> F:
    """Cross-product matrix [w]x of vectors ``w`` (..., 3) -> (..., 3, 3)."""
    z = np.zeros(w.shape[:-1])
    return np.stack(
        [
            np.stack([z, -w[..., 2], w[..., 1]], -1),
            np.stack([w[..., 2], z, -w[..., 0]], -1),
            np.stack([-w[..., 1], w[..., 0], z], -1),
        ],
        -2,
    )


def expm_so3(w: F) -> F:
    """Rodrigues' formula: rotation matrices exp([w]x) for rotation vectors (..., 3)."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = skew(w)
    small = th < 1e-8
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(ths)) / ths**2)
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + a * K + b * (K @ K)


def rpy_matrix(roll: F | float, pitch: F | float, yaw: F | float) -> F:
    """R = Rz(yaw) @ Ry(pitch) @ Rx(roll) (fixed-axis roll, pitch, yaw), radians."""
    r, p, y = np.broadcast_arrays(
        np.asarray(roll, float), np.asarray(pitch, float), np.asarray(yaw, float)
    )
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return np.stack([np.stack(row, -1) for row in rows], -2)


def matrix_rpy(R: F) -> F:
    """Inverse of :func:`rpy_matrix`: (..., 3, 3) -> (..., 3) [roll, pitch, yaw], radians."""
    pitch = np.arcsin(np.clip(-R[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], -1)


def random_rotations(n: int, seed: int) -> F:
    """``n`` rotation matrices (n, 3, 3) drawn uniformly (Haar measure) with a fixed seed:
    unit quaternions from normalised 4-D normal samples (uniform on S³)."""
    q = np.random.default_rng(seed).standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def matrix_quaternion(R: F) -> F:
    """Unit quaternions (..., 4) as x, y, z, w (ROS's order, w ≥ 0) of rotation matrices
    (..., 3, 3): from the largest of the four squared components (Shepperd), exact to rounding
    for any rotation."""
    R = np.asarray(R, float)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    sq = np.stack([1 + 2 * R[..., 0, 0] - tr, 1 + 2 * R[..., 1, 1] - tr,
                   1 + 2 * R[..., 2, 2] - tr, 1 + tr], -1)  # 4x², 4y², 4z², 4w²
    pick = np.argmax(sq, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(sq, pick[..., None], -1)[..., 0], 1e-300))
    # each row of candidates: 4·q for the component picked, the others from the off-diagonals
    d = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]], -1)  # 4w·(x, y, z)
    p = np.stack([R[..., 1, 0] + R[..., 0, 1], R[..., 0, 2] + R[..., 2, 0],
                  R[..., 2, 1] + R[..., 1, 2]], -1)  # 4xy, 4xz, 4yz
    cand = np.stack([
        np.stack([s * s, p[..., 0], p[..., 1], d[..., 0]], -1),  # x largest: 4x·(x, y, z, w)
        np.stack([p[..., 0], s * s, p[..., 2], d[..., 1]], -1),  # y largest
        np.stack([p[..., 1], p[..., 2], s * s, d[..., 2]], -1),  # z largest
        np.stack([d[..., 0], d[..., 1], d[..., 2], s * s], -1),  # w largest
    ], -2)
    q = np.take_along_axis(cand, pick[..., None, None], -2)[..., 0, :] / (2.0 * s[..., None])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.asarray(np.where(q[..., 3:4] < 0, -q, q))
