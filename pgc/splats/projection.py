"""EWA projection of world Gaussians to screen space, numpy float64 (shared by the reference rasteriser).

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
  a Gaussian touches exactly the pixels whose centre c satisfies ``|c_x - u| <= r`` and ``|c_y - v| <= r``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.splats.quaternion import quat_to_rotmat
from pgc.splats.sh import sh_basis
from pgc.types import Camera, WorldGaussians

DILATION = 0.1
"""Low-pass filter added to the diagonal of the 2D covariance (pixels^2): about the variance of a one-pixel box
(1/12), the filter of the capture's pixels (3DGS adds 0.3 without the coverage factor)."""
MAX_SCALE = 1e4
"""World standard deviations are clamped to this (metres)."""
ALPHA_MIN = 1.0 / 255.0
ALPHA_MAX = 0.99
T_MIN = 1e-4


@dataclass
class Projected:
    """Screen-space Gaussians (float64), one row per input Gaussian; ``valid`` marks the uncoulled ones."""

    means2d: np.ndarray   # (N, 2) pixels
    conics: np.ndarray    # (N, 3) inverse 2D covariance (a, b, c) = [[a, b], [b, c]]
    depths: np.ndarray    # (N,) camera z
    radii: np.ndarray     # (N,) footprint half-width in pixels (0 when culled)
    colors: np.ndarray    # (N, 3)
    opacities: np.ndarray  # (N,) the world opacities times the coverage
    valid: np.ndarray     # (N,) bool


def project(world: WorldGaussians, camera: Camera, sh_degree: int | None = None, near: float = 0.01) -> Projected:
    """Project world Gaussians through ``camera`` following the rendering contract."""
    means = np.asarray(world.means, np.float64)
    n = len(means)
    pc = means @ camera.R.T + camera.t
    x, y, z = pc[:, 0], pc[:, 1], pc[:, 2]
    valid = z >= near
    zs = np.where(valid, z, 1.0)
    K = camera.K
    u = (K[0, 0] * x + K[0, 1] * y) / zs + K[0, 2]
    v = K[1, 1] * y / zs + K[1, 2]
    J = np.zeros((n, 2, 3))
    J[:, 0, 0], J[:, 0, 1], J[:, 0, 2] = K[0, 0] / zs, K[0, 1] / zs, -(K[0, 0] * x + K[0, 1] * y) / zs ** 2
    J[:, 1, 1], J[:, 1, 2] = K[1, 1] / zs, -K[1, 1] * y / zs ** 2
    Rg = quat_to_rotmat(world.quats)
    s = np.clip(np.asarray(world.scales, np.float64), 0.0, MAX_SCALE)
    M = (camera.R[None] @ Rg) * s[:, None, :]
    T = J @ M
    cov = T @ np.swapaxes(T, 1, 2) + DILATION * np.eye(2)
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    det = a * c - b * b
    raw_det = np.sum(np.cross(T[:, 0], T[:, 1]) ** 2, -1)  # det(T T^T) by Cauchy-Binet: exact for needles
    coverage = np.sqrt(raw_det / det)
    conics = np.stack([c / det, -b / det, a / det], -1)
    lam = 0.5 * (a + c) + np.sqrt((0.5 * (a - c)) ** 2 + b * b)
    radii = np.where(valid, np.ceil(3.0 * np.sqrt(lam)), 0.0)
    sh = np.asarray(world.sh, np.float64)
    degree = int(round(np.sqrt(sh.shape[1]))) - 1
    degree = degree if sh_degree is None else min(sh_degree, degree)
    dirs = means - camera.center
    dirs = dirs / np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-300)
    basis = sh_basis(dirs, degree)
    colors = np.maximum(np.einsum("nk,nkc->nc", basis, sh[:, :basis.shape[1]]) + 0.5, 0.0)
    opacities = np.asarray(world.opacities, np.float64) * coverage
    return Projected(np.stack([u, v], -1), conics, z, radii, colors, opacities, valid)
