"""Mesh binding of Gaussians (GaussianAvatars style, docs/method.md section 2), written once over
:mod:`pgc.arrays`: numpy (float64), torch and JAX arrays, differentiable in the vertices and every local
parameter with finite gradients everywhere.

Triangle frame of face (v0, v1, v2): origin ``tau`` = centroid; rotation ``R`` with columns
[a = normalised edge v1 - v0, b = unit normal (v1 - v0) x (v2 - v0), c = a x b] (right-handed, det +1);
scale ``k = (base + height) / 2`` with base = |v1 - v0| and height = |(v1 - v0) x (v2 - v0)| / base.
World parameters: ``r' = R r`` (quaternion product, R first; as a matrix ``R Rot(r)``), ``mu' = k R mu + tau``,
``s' = k s``, opacity = sigmoid(logit).

Degenerate triangles (values and gradients stay finite):
- edge: the first of (v1 - v0, v2 - v0, v2 - v1) longer than ``EDGE_EPS``; the world x axis if none is;
- normal: when ``|(v1 - v0) x (v2 - v0)| <= max(AREA_REL_EPS, 8 eps) * L^2 + AREA_ABS_EPS`` (L the longest edge,
  eps the dtype's machine epsilon: in float32 a face flat in float64 stays flat; zero area, collinear or repeated
  vertices) the normal is the world axis least aligned with the edge, made orthogonal to it (Gram-Schmidt);
- ``height`` divides by ``max(base, EDGE_EPS)`` and ``k`` is at least ``K_MIN`` (1 micrometre), so a
  triangle collapsed to a point still gives a finite, tiny, positive scale.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from pgc.arrays import ArrayOps, array_ops_for, float_operands
from pgc.errors import PGCDataError
from pgc.splats.quaternion import quat_multiply, quat_normalize, quat_to_rotmat, rotmat_to_quat
from pgc.types import GaussianSet, WorldGaussians

EDGE_EPS = 1e-12
"""Edges shorter than this (metres) count as zero length."""
AREA_REL_EPS = 1e-12
AREA_ABS_EPS = 1e-30
K_MIN = 1e-6
"""Smallest triangle scale k (metres)."""


class Bound(NamedTuple):
    """World-space Gaussians as a rasteriser consumes them, in the arrays of the inputs (:func:`apply_frames`,
    :func:`bind_arrays`; differentiable in every input)."""

    means: Any      # (N, 3) metres
    rotmats: Any    # (N, 3, 3) columns = the Gaussian's axes
    scales: Any     # (N, 3) standard deviations (metres)
    opacities: Any  # (N,) in (0, 1)


def _length(ops: ArrayOps, x: Any) -> Any:
    """|x| along the last axis, with a zero (not NaN) gradient at x = 0."""
    s = (x * x).sum(-1)
    return ops.where(s > 0, ops.sqrt(ops.where(s > 0, s, 1.0)), 0.0)


def _unit(ops: ArrayOps, x: Any, length: Any) -> Any:
    """``x / length`` along the last axis (x itself where ``length`` is 0)."""
    return x / ops.where(length > 0, length, 1.0)[..., None]


def triangle_frames(vertices: Any, faces: Any) -> tuple[Any, Any, Any]:
    """Per-face frames: ``tau`` (F, 3) centroids, ``R`` (F, 3, 3) rotations (columns a, b, c), ``k`` (F,).

    ``vertices`` (V, 3): a torch or JAX array (its dtype kept), else float64 numpy; ``faces`` (F, 3) indices.
    """
    ops, vertices = float_operands(vertices)
    if ops.name == "numpy":
        faces = np.asarray(faces, dtype=np.int64)
        if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
            raise PGCDataError(f"binding: face indices out of range [0, {len(vertices)})")
    xp = ops.xp
    v0, v1, v2 = (vertices[faces[:, i]] for i in range(3))
    tau = (v0 + v1 + v2) / 3.0
    e01, e02, e12 = v1 - v0, v2 - v0, v2 - v1
    l01, l02, l12 = (_length(ops, e) for e in (e01, e02, e12))
    x_axis = ops.asarray([1.0, 0.0, 0.0], like=vertices)
    edge = ops.where((l01 > EDGE_EPS)[:, None], e01, ops.where(
        (l02 > EDGE_EPS)[:, None], e02, ops.where((l12 > EDGE_EPS)[:, None], e12, x_axis)))
    a = _unit(ops, edge, _length(ops, edge))
    n = ops.cross(e01, e02)
    n_len = _length(ops, n)
    longest = xp.maximum(xp.maximum(l01, l02), l12)
    rel = max(AREA_REL_EPS, 8.0 * float(xp.finfo(vertices.dtype).eps))
    flat = n_len <= rel * longest ** 2 + AREA_ABS_EPS
    helper = xp.eye(3, dtype=vertices.dtype)[xp.argmin(xp.abs(ops.stop_gradient(a)), axis=1)]
    ortho = helper - (helper * a).sum(-1)[:, None] * a
    b = ops.where(flat[:, None], _unit(ops, ortho, _length(ops, ortho)), _unit(ops, n, ops.where(flat, 1.0, n_len)))
    c = ops.cross(a, b)
    R = ops.stack([a, b, c], axis=2)
    height = n_len / ops.maximum(l01, EDGE_EPS)
    k = ops.maximum(0.5 * (l01 + height), K_MIN)
    return tau, R, k


def apply_frames(tau: Any, R: Any, k: Any, parent: Any, means: Any, quats: Any, log_scales: Any,
                 opacity_logits: Any) -> Bound:
    """World Gaussians from per-face frames (:func:`triangle_frames`) and local parameters (GaussianSet layout):
    means ``k R mu + tau``, rotation matrices ``R Rot(r)``, scales ``k s``, opacities ``sigmoid(logit)``."""
    ops = array_ops_for(means)
    Rp, kp = R[parent], k[parent][:, None]
    return Bound(means=kp * ops.xp.einsum("nij,nj->ni", Rp, means) + tau[parent],
                 rotmats=Rp @ quat_to_rotmat(quats), scales=kp * ops.exp(log_scales),
                 opacities=ops.sigmoid(opacity_logits))


def bind_arrays(parent: Any, means: Any, quats: Any, log_scales: Any, opacity_logits: Any, vertices: Any,
                faces: Any) -> Bound:
    """World Gaussians of local parameters (GaussianSet layout) on the mesh (vertices (V, 3), faces (F, 3)), in
    the inputs' arrays; differentiable in the vertices too."""
    return apply_frames(*triangle_frames(vertices, faces), parent, means, quats, log_scales, opacity_logits)


def bind(gaussians: GaussianSet, vertices: np.ndarray, faces: np.ndarray) -> WorldGaussians:
    """World-space Gaussians of ``gaussians`` on the mesh (vertices (V, 3), faces (F, 3)), float64 numpy.

    Local quaternions are normalised first (zero means identity); world quaternions are unit, w >= 0 not
    guaranteed.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(gaussians) and (gaussians.parent.min() < 0 or gaussians.parent.max() >= len(faces)):
        raise PGCDataError(f"gaussians: parent face index out of range [0, {len(faces)}); "
                           "the Gaussians belong to a different mesh")
    tau, R, k = triangle_frames(vertices, faces)
    p = gaussians.parent
    world = apply_frames(tau, R, k, p, *(np.asarray(x, np.float64) for x in (
        gaussians.means, gaussians.quats, gaussians.log_scales, gaussians.opacity_logits)))
    quats = quat_multiply(rotmat_to_quat(R[p]), quat_normalize(gaussians.quats))
    return WorldGaussians(means=world.means, quats=quats, scales=world.scales, opacities=world.opacities,
                          sh=gaussians.sh.astype(np.float64))


def unbind_points(points: np.ndarray, parent: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Local positions ``mu = R^T (p - tau) / k`` of world points (N, 3) in their parent faces' frames."""
    tau, R, k = triangle_frames(vertices, faces)
    return np.einsum("nji,nj->ni", R[parent], np.asarray(points, np.float64) - tau[parent]) / k[parent][:, None]
