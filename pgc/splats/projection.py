"""EWA projection of world Gaussians to screen space and their view-dependent colour, written once over
:mod:`pgc.arrays` (numpy float64 for the reference rasteriser, torch and JAX differentiable; the fused C++ kernel
is the other implementation, tested against the reference).

Conventions of the rendering contract (pgc/roles/splat_renderer.py) that every backend follows exactly:
- world scales are clamped to ``[0, MAX_SCALE]`` before use (keeps float32 covariances finite);
- ``x_c = R x_w + t``; Gaussians with ``z_c < near`` are culled; the mean projects to
  ``u = (K00 x + K01 y) / z + K02``, ``v = K11 y / z + K12``;
- ``Sigma2D = J W Sigma W^T J^T + DILATION I`` with J the Jacobian of (u, v) at the camera-space mean, and the
  opacity scaled by the coverage ``sqrt(det(J W Sigma W^T J^T) / det(Sigma2D))`` (Mip-Splatting's 2D filter, the
  "antialiased" mode of gsplat): the dilation stands for the pixel's box filter, and the coverage keeps each
  Gaussian's integrated alpha (its mass on the image plane) what it was before the filter, so a Gaussian thinner
  than a pixel, or a disc seen edge-on, covers the area it has instead of a dilated pixel-wide stroke;
- footprint radius ``r = ceil(3 sqrt(lambda_max(Sigma2D)))`` (pixels), exact largest eigenvalue
  ``lambda_max = (a + c) / 2 + sqrt(((a - c) / 2)^2 + b^2)`` of ``Sigma2D = [[a, b], [b, c]]``;
  a Gaussian touches exactly the pixels whose centre c satisfies ``|c_x - u| <= r`` and ``|c_y - v| <= r``;
- colour ``max(0, SH . basis(d) + 0.5)`` with ``d`` the unit direction from the camera centre to the mean.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from pgc.arrays import array_ops_for
from pgc.splats.quaternion import quat_to_rotmat
from pgc.splats.sh import MAX_SH_DEGREE, sh_basis_terms
from pgc.types import Camera, WorldGaussians

DILATION = 0.1
"""Low-pass filter added to the diagonal of the 2D covariance (pixels^2): about the variance of a one-pixel box
(1/12), the filter of the capture's pixels (3DGS adds 0.3 without the coverage factor)."""
MAX_SCALE = 1e4
"""World standard deviations are clamped to this (metres)."""
ALPHA_MIN = 1.0 / 255.0
ALPHA_MAX = 0.99
T_MIN = 1e-4


class Screen(NamedTuple):
    """Screen-space Gaussians, one row per input Gaussian, in the arrays of the inputs (pixel units)."""

    mean2d: Any
    """(N, 2) projected centres (x right, y down); 0 where culled."""
    conic: Any
    """(N, 3) inverse 2D covariance (a, b, c): ``q = a dx^2 + 2 b dx dy + c dy^2``; 0 where culled."""
    depth: Any
    """(N,) camera depth z (metres); 1 where culled."""
    valid: Any
    """(N,) bool: in front of the near plane."""
    radius: Any
    """(N,) footprint box half-width ``ceil(3 sqrt(lambda_max))`` (px); 0 where culled. No gradient."""
    lambda_max: Any
    """(N,) largest eigenvalue of the dilated 2D covariance (px^2); 0 where culled. No gradient."""
    coverage: Any
    """(N,) ``sqrt(det(Sigma2D - DILATION I) / det(Sigma2D))``, the factor of the opacity; 0 where culled."""


def screen_space(means: Any, rotmats: Any, scales: Any, K: Any, R: Any, t: Any, near: float) -> Screen:
    """Project Gaussians with centres ``means`` (N, 3), axes ``rotmats`` (N, 3, 3) (columns) and standard
    deviations ``scales`` (N, 3) through the camera (K, R, t; arrays of the same library, or numpy).

    The 2D covariance is ``T T^T + DILATION I`` with ``T = J R_cam Rot diag(s)`` and ``J`` the Jacobian of the
    perspective map at the centre. The inverse is formed on ``T`` rescaled to unit size, with the determinant
    from its 2x2 minors (Cauchy-Binet), so needles and huge Gaussians stay finite and positive definite in
    float32. Differentiable and NaN-free for degenerate input (culled Gaussians get finite placeholders).
    """
    ops = array_ops_for(means)
    xp = ops.xp
    pc = means @ R.T + t
    x, y, z = pc[:, 0], pc[:, 1], pc[:, 2]
    valid = z >= near
    zs = ops.where(valid, z, 1.0)
    u = (K[0, 0] * x + K[0, 1] * y) / zs + K[0, 2]
    v = (K[1, 1] * y) / zs + K[1, 2]
    zero = xp.zeros_like(zs)
    J = ops.stack([ops.stack([K[0, 0] / zs, K[0, 1] / zs, -(K[0, 0] * x + K[0, 1] * y) / (zs * zs)], -1),
                   ops.stack([zero, K[1, 1] / zs, -K[1, 1] * y / (zs * zs)], -1)], -2)
    M = rotmats * ops.clip(scales, 0.0, MAX_SCALE)[:, None, :]
    T = xp.einsum("nij,jk,nkl->nil", J, R, M)
    size = ops.maximum(xp.amax(xp.abs(T), axis=(1, 2)), 1.0)
    Ts = T / size[:, None, None]
    eps = DILATION / (size * size)
    a = (Ts[:, 0] ** 2).sum(-1) + eps
    b = (Ts[:, 0] * Ts[:, 1]).sum(-1)
    c = (Ts[:, 1] ** 2).sum(-1) + eps
    minors = ops.cross(Ts[:, 0], Ts[:, 1])
    raw_det = (minors * minors).sum(-1)
    det = raw_det + eps * (a + c - 2 * eps) + eps * eps
    some = valid & (raw_det > 0)  # sqrt's gradient at 0 is infinite: no coverage, no gradient there
    coverage = ops.where(some, ops.sqrt(ops.where(some, raw_det, 1.0) / det), 0.0)
    inv = 1.0 / (det * size * size)
    conic = ops.stack([c * inv, -b * inv, a * inv], -1)
    a_, b_, c_, size_ = (ops.stop_gradient(q) for q in (a, b, c, size))  # the footprint carries no gradient
    lam = ops.where(valid, (0.5 * (a_ + c_) + ops.sqrt((0.5 * (a_ - c_)) ** 2 + b_ * b_)) * size_ * size_, 0.0)
    mean2d = ops.stack([u, v], -1)
    return Screen(ops.where(valid[:, None], mean2d, 0.0), ops.where(valid[:, None], conic, 0.0), zs, valid,
                  ops.where(valid, xp.ceil(3.0 * ops.sqrt(lam)), 0.0), lam, coverage)


def view_colors(means: Any, sh: Any, center: Any, degree: int) -> Any:
    """(N, 3) colours ``max(0, SH . basis + 0.5)`` seen from ``center`` (3,); ``degree`` (static) is clipped to
    what ``sh`` (N, K, 3) holds."""
    ops = array_ops_for(means)
    degree = min(int(degree), int(round(sh.shape[1] ** 0.5)) - 1)
    d = means - center
    n2 = (d * d).sum(-1)[:, None]
    d = d / ops.sqrt(ops.where(n2 > 0, n2, 1.0))
    basis = ops.stack(sh_basis_terms(d[:, 0], d[:, 1], d[:, 2], degree), -1)
    return ops.maximum(ops.xp.einsum("nk,nkc->nc", basis, sh[:, :basis.shape[1]]) + 0.5, 0.0)


def expected_depth(depth_sum: Any, alpha: Any) -> Any:
    """The alpha-weighted depth sum divided by alpha: the expected depth, 0 where alpha is 0."""
    ops = array_ops_for(alpha)
    has = alpha > 0
    return ops.where(has, depth_sum / ops.where(has, alpha, 1.0), 0.0)


@dataclass
class Projected:
    """Screen-space Gaussians (float64 numpy), one row per input Gaussian; ``valid`` marks the unculled ones."""

    means2d: np.ndarray   # (N, 2) pixels
    conics: np.ndarray    # (N, 3) inverse 2D covariance (a, b, c) = [[a, b], [b, c]]
    depths: np.ndarray    # (N,) camera z
    radii: np.ndarray     # (N,) footprint half-width in pixels (0 when culled)
    colors: np.ndarray    # (N, 3)
    opacities: np.ndarray  # (N,) the world opacities times the coverage
    valid: np.ndarray     # (N,) bool


def project(world: WorldGaussians, camera: Camera, sh_degree: int | None = None, near: float = 0.01) -> Projected:
    """Project world Gaussians through ``camera`` following the rendering contract (float64 numpy)."""
    means = np.asarray(world.means, np.float64)
    sh = np.asarray(world.sh, np.float64)
    s = screen_space(means, quat_to_rotmat(world.quats), np.asarray(world.scales, np.float64), camera.K, camera.R,
                     camera.t, near)
    colors = view_colors(means, sh, camera.center, MAX_SH_DEGREE if sh_degree is None else sh_degree)
    return Projected(s.mean2d, s.conic, s.depth, s.radius, colors,
                     np.asarray(world.opacities, np.float64) * s.coverage, s.valid)
