"""Mesh binding of Gaussians (GaussianAvatars style, docs/method.md section 2), numpy float64.

Triangle frame of face (v0, v1, v2): origin ``tau`` = centroid; rotation ``R`` with columns
[a = normalised edge v1 - v0, b = unit normal (v1 - v0) x (v2 - v0), c = a x b] (right-handed, det +1);
scale ``k = (base + height) / 2`` with base = |v1 - v0| and height = |(v1 - v0) x (v2 - v0)| / base.
World parameters: ``r' = R r`` (quaternion product, R first), ``mu' = k R mu + tau``, ``s' = k s``,
opacity = sigmoid(logit).

Degenerate triangles (the same rules in every backend, so values and gradients stay finite):
- edge: the first of (v1 - v0, v2 - v0, v2 - v1) longer than ``EDGE_EPS``; the world x axis if none is;
- normal: when ``|(v1 - v0) x (v2 - v0)| <= AREA_REL_EPS * L^2 + AREA_ABS_EPS`` (L the longest edge; zero area,
  collinear or repeated vertices) the normal is the world axis least aligned with the edge, made
  orthogonal to it (Gram-Schmidt);
- ``height`` divides by ``max(base, EDGE_EPS)`` and ``k`` is at least ``K_MIN`` (1 micrometre), so a
  triangle collapsed to a point still gives a finite, tiny, positive scale.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from pgc.errors import PGCDataError
from pgc.splats.quaternion import quat_multiply, quat_normalize, rotmat_to_quat
from pgc.types import GaussianSet, WorldGaussians

EDGE_EPS = 1e-12
"""Edges shorter than this (metres) count as zero length."""
AREA_REL_EPS = 1e-12
AREA_ABS_EPS = 1e-30
K_MIN = 1e-6
"""Smallest triangle scale k (metres)."""


class Bound(NamedTuple):
    """World-space Gaussians as a backend's rasteriser consumes them, in that backend's arrays. Every backend's
    ``bind(parent, means, quats, log_scales, opacity_logits, vertices, faces)`` and ``apply_frames(tau, R, k,
    parent, means, quats, log_scales, opacity_logits)`` return one (differentiable in every input)."""

    means: Any      # (N, 3) metres
    rotmats: Any    # (N, 3, 3) columns = the Gaussian's axes
    scales: Any     # (N, 3) standard deviations (metres)
    opacities: Any  # (N,) in (0, 1)


def _normalize(x: np.ndarray) -> np.ndarray:
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)


def triangle_frames(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-face frames: ``tau`` (F, 3) centroids, ``R`` (F, 3, 3) rotations (columns a, b, c), ``k`` (F,)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise PGCDataError(f"binding: face indices out of range [0, {len(vertices)})")
    v0, v1, v2 = (vertices[faces[:, i]] for i in range(3))
    tau = (v0 + v1 + v2) / 3.0
    e01, e02, e12 = v1 - v0, v2 - v0, v2 - v1
    l01, l02, l12 = (np.linalg.norm(e, axis=1) for e in (e01, e02, e12))
    x_axis = np.broadcast_to(np.array([1.0, 0.0, 0.0]), e01.shape)
    edge = np.where((l01 > EDGE_EPS)[:, None], e01,
                    np.where((l02 > EDGE_EPS)[:, None], e02, np.where((l12 > EDGE_EPS)[:, None], e12, x_axis)))
    a = _normalize(edge)
    n = np.cross(e01, e02)
    n_len = np.linalg.norm(n, axis=1)
    longest = np.maximum(np.maximum(l01, l02), l12)
    flat = n_len <= AREA_REL_EPS * longest ** 2 + AREA_ABS_EPS
    helper = np.eye(3)[np.argmin(np.abs(a), axis=1)]
    fallback = _normalize(helper - np.sum(helper * a, axis=1, keepdims=True) * a)
    b = np.where(flat[:, None], fallback, n / np.maximum(n_len, 1e-300)[:, None])
    c = np.cross(a, b)
    R = np.stack([a, b, c], axis=2)
    height = n_len / np.maximum(l01, EDGE_EPS)
    k = np.maximum(0.5 * (l01 + height), K_MIN)
    return tau, R, k


def sigmoid(x: np.ndarray) -> np.ndarray:
    """Overflow-free logistic function."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(x, dtype=np.float64)))


def bind(gaussians: GaussianSet, vertices: np.ndarray, faces: np.ndarray) -> WorldGaussians:
    """World-space Gaussians of ``gaussians`` on the mesh (vertices (V, 3), faces (F, 3)), float64.

    Local quaternions are normalised first (zero means identity); world quaternions are unit, w >= 0 not
    guaranteed.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(gaussians) and (gaussians.parent.min() < 0 or gaussians.parent.max() >= len(faces)):
        raise PGCDataError(f"gaussians: parent face index out of range [0, {len(faces)}); "
                           "the Gaussians belong to a different mesh")
    tau, R, k = triangle_frames(vertices, faces)
    p = gaussians.parent
    Rp, kp = R[p], k[p][:, None]
    means = kp * np.einsum("nij,nj->ni", Rp, gaussians.means.astype(np.float64)) + tau[p]
    quats = quat_multiply(rotmat_to_quat(Rp), quat_normalize(gaussians.quats))
    scales = kp * np.exp(gaussians.log_scales.astype(np.float64))
    return WorldGaussians(means=means, quats=quats, scales=scales,
                          opacities=sigmoid(gaussians.opacity_logits), sh=gaussians.sh.astype(np.float64))


def unbind_points(points: np.ndarray, parent: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Local positions ``mu = R^T (p - tau) / k`` of world points (N, 3) in their parent faces' frames."""
    tau, R, k = triangle_frames(vertices, faces)
    return np.einsum("nji,nj->ni", R[parent], np.asarray(points, np.float64) - tau[parent]) / k[parent][:, None]
