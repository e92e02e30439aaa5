"""Quaternion helpers, (w, x, y, z) layout, written once over :mod:`pgc.arrays` (numpy, torch and JAX arrays).

Convention shared by every backend: a quaternion is normalised by its norm; one of norm at most ``QUAT_EPS``
counts as zero and means the identity rotation. Torch and JAX arrays keep their dtype (and autodiff graph, with
finite gradients at zero); anything else is computed as a float64 numpy array.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.arrays import float_operands

QUAT_EPS = 1e-12
"""Norm below which a quaternion counts as zero (it then means the identity rotation)."""


def quat_normalize(q: Any) -> Any:
    """(..., 4) -> unit quaternions; zero quaternions become (1, 0, 0, 0)."""
    ops, q = float_operands(q)
    n2 = (q * q).sum(-1)[..., None]
    big = n2 > QUAT_EPS * QUAT_EPS
    unit = q / ops.sqrt(ops.where(big, n2, 1.0))  # the guard keeps the gradient finite at zero
    return ops.where(big, unit, ops.asarray([1.0, 0.0, 0.0, 0.0], like=q))


def quat_to_rotmat(q: Any) -> Any:
    """(..., 4) quaternions (any norm; zero means identity) -> (..., 3, 3) rotation matrices."""
    ops, q = float_operands(q)
    u = quat_normalize(q)
    w, x, y, z = u[..., 0], u[..., 1], u[..., 2], u[..., 3]
    return ops.stack([
        ops.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        ops.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        ops.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def quat_multiply(a: Any, b: Any) -> Any:
    """Hamilton product ``a b`` of (..., 4) quaternions (rotation b first, then a)."""
    ops, a = float_operands(a)
    _, b = float_operands(b)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return ops.stack([aw * bw - ax * bx - ay * by - az * bz,
                      aw * bx + ax * bw + ay * bz - az * by,
                      aw * by - ax * bz + ay * bw + az * bx,
                      aw * bz + ax * by - ay * bx + az * bw], -1)


def rotmat_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions with w >= 0 (Shepperd's method), numpy float64:
    only the numpy binding (world quaternions of stored Gaussians) needs it."""
    m = np.asarray(m, dtype=np.float64)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    cands = np.stack([
        np.stack([1 + m00 + m11 + m22, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                  m[..., 1, 0] - m[..., 0, 1]], -1),
        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0],
                  m[..., 0, 2] + m[..., 2, 0]], -1),
        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 - m00 + m11 - m22,
                  m[..., 1, 2] + m[..., 2, 1]], -1),
        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1],
                  1 - m00 - m11 + m22], -1),
    ], -2)  # row i is 4 q_i q (up to sign), largest for the largest |q_i|
    pick = np.argmax(np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22,
                               1 - m00 - m11 + m22], -1), axis=-1)
    q = np.take_along_axis(cands, pick[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)
