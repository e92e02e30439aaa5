"""EWA projection of 3D Gaussians to screen space in JAX (docs/method.md section 2, the 3DGS conventions).

Follows :mod:`pgc.splats.projection` (the float64 oracle) exactly: camera in the OpenCV convention,
world scales clamped to ``MAX_SCALE``, Gaussians with camera depth ``z < near`` culled, ``DILATION`` px^2 dilation
and the coverage factor of the opacity,
footprint box half-width ``ceil(3 sqrt(lambda_max))``, SH colour along ``normalize(mean - centre)``.
Everything here is differentiable and NaN-free for degenerate input (culled Gaussians get finite
placeholder values).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from pgc.splats.projection import DILATION, MAX_SCALE
from pgc.splats.quaternion import QUAT_EPS
from pgc.splats.sh import sh_basis_terms


class Projected(NamedTuple):
    """Screen-space Gaussians. All (N, ...) arrays; pixel units."""

    mean2d: jnp.ndarray
    """(N, 2) projected centres (x right, y down)."""
    conic: jnp.ndarray
    """(N, 3) inverse 2D covariance (a, b, c): ``q = a dx^2 + 2 b dx dy + c dy^2``."""
    depth: jnp.ndarray
    """(N,) camera depth z (metres); 1 where invalid."""
    valid: jnp.ndarray
    """(N,) bool: in front of the near plane."""
    radius: jnp.ndarray
    """(N,) footprint box half-width ``ceil(3 sqrt(lambda_max))`` (px); 0 where invalid. No gradient."""
    lambda_max: jnp.ndarray
    """(N,) largest eigenvalue of the dilated 2D covariance (px^2); 0 where invalid. No gradient."""
    coverage: jnp.ndarray
    """(N,) ``sqrt(det(Sigma2D - DILATION I) / det(Sigma2D))``, the factor of the opacity; 0 where invalid."""


def quat_to_rotmat(quats: jnp.ndarray) -> jnp.ndarray:
    """(N, 3, 3) rotation matrices of (w, x, y, z) quaternions (N, 4), normalised here.

    A zero quaternion gives the identity (its normalised value is 0 and the formula reduces to I).
    """
    n2 = jnp.sum(quats * quats, axis=-1, keepdims=True)
    big = n2 > QUAT_EPS * QUAT_EPS
    q = quats * jnp.where(big, 1.0 / jnp.sqrt(jnp.where(big, n2, 1.0)), 0.0)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    rows = [
        jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        jnp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ]
    return jnp.stack(rows, axis=-2)


def project(means: jnp.ndarray, rotmats: jnp.ndarray, scales: jnp.ndarray, K: jnp.ndarray,
            R: jnp.ndarray, t: jnp.ndarray, near: float) -> Projected:
    """Project Gaussians with centres ``means`` (N, 3), axes ``rotmats`` (N, 3, 3) (columns) and standard
    deviations ``scales`` (N, 3) through the camera (K, R, t).

    The 2D covariance is ``T T^T + DILATION I`` with ``T = J R_cam Rot diag(s)`` and ``J`` the Jacobian of the
    perspective map at the centre. The inverse is formed on ``T`` rescaled to unit size, with the
    determinant from its 2x2 minors (Cauchy-Binet), so needles and huge Gaussians stay finite and positive.
    """
    pc = means @ R.T + t
    z = pc[:, 2]
    valid = z >= near
    zs = jnp.where(valid, z, 1.0)
    x, y = pc[:, 0], pc[:, 1]
    u = (K[0, 0] * x + K[0, 1] * y) / zs + K[0, 2]
    v = (K[1, 1] * y) / zs + K[1, 2]
    zero = jnp.zeros_like(zs)
    J = jnp.stack([jnp.stack([K[0, 0] / zs, K[0, 1] / zs, -(K[0, 0] * x + K[0, 1] * y) / (zs * zs)], -1),
                   jnp.stack([zero, K[1, 1] / zs, -K[1, 1] * y / (zs * zs)], -1)], axis=-2)
    M = rotmats * jnp.clip(scales, 0.0, MAX_SCALE)[:, None, :]
    T = jnp.einsum("nij,jk,nkl->nil", J, R, M)
    size = jnp.maximum(1.0, jnp.max(jnp.abs(T), axis=(1, 2)))
    Ts = T / size[:, None, None]
    eps = DILATION / (size * size)
    a = jnp.sum(Ts[:, 0] ** 2, -1) + eps
    b = jnp.sum(Ts[:, 0] * Ts[:, 1], -1)
    c = jnp.sum(Ts[:, 1] ** 2, -1) + eps
    minors = jnp.cross(Ts[:, 0], Ts[:, 1])
    raw_det = jnp.sum(minors * minors, -1)
    det = raw_det + eps * (a + c - 2 * eps) + eps * eps
    some = valid & (raw_det > 0)  # sqrt's gradient at 0 is infinite: no coverage, no gradient there
    coverage = jnp.where(some, jnp.sqrt(jnp.where(some, raw_det, 1.0) / det), 0.0)
    inv = 1.0 / (det * size * size)
    conic = jnp.stack([c * inv, -b * inv, a * inv], -1)
    a_, b_, c_, size_ = jax.lax.stop_gradient((a, b, c, size))  # footprint only: no gradient
    lam = (0.5 * (a_ + c_) + jnp.sqrt((0.5 * (a_ - c_)) ** 2 + b_ * b_)) * size_ * size_
    lam = jnp.where(valid, lam, 0.0)
    mean2d = jnp.stack([u, v], -1)
    return Projected(jnp.where(valid[:, None], mean2d, 0.0), jnp.where(valid[:, None], conic, 0.0),
                     zs, valid, jnp.where(valid, jnp.ceil(3.0 * jnp.sqrt(lam)), 0.0), lam, coverage)


def view_colors(means: jnp.ndarray, sh: jnp.ndarray, center: jnp.ndarray, degree: int) -> jnp.ndarray:
    """(N, 3) colours ``max(0, SH . basis + 0.5)`` seen from ``center``; ``degree`` (static) is clipped to
    what ``sh`` (N, K, 3) holds."""
    degree = min(int(degree), int(round(sh.shape[1] ** 0.5)) - 1)
    d = means - center
    n2 = jnp.sum(d * d, axis=-1, keepdims=True)
    d = d * jnp.where(n2 > 0, 1.0 / jnp.sqrt(jnp.where(n2 > 0, n2, 1.0)), 0.0)
    basis = jnp.stack(sh_basis_terms(d[:, 0], d[:, 1], d[:, 2], degree), -1)
    return jnp.maximum(jnp.einsum("nk,nkc->nc", basis, sh[:, :basis.shape[1]]) + 0.5, 0.0)
