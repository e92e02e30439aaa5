"""Mesh binding of Gaussians in JAX: the rules of :mod:`pgc.splats.binding`, differentiable in the vertices.

Frame of face (v0, v1, v2): ``tau`` = centroid, ``R`` = columns [a, b, c] (a the normalised edge, b the unit
normal, c = a x b), ``k = (base + height) / 2``. World Gaussians: ``Rot = R Rot(r)`` (the matrix of the
quaternion product ``R r``), ``mu' = k R mu + tau``, ``s' = k s``, opacity ``sigmoid(logit)``.
Degenerate faces follow the numpy fallbacks with the same thresholds, except that in float32 a face counts
as flat when its normal is below the rounding error of the cross product (``8 eps32 L^2``), so that a face
that is flat in float64 gets the same fallback frame in float32. Every norm and division is guarded so
that values *and* gradients stay finite.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from pgc.splats.binding import AREA_ABS_EPS, AREA_REL_EPS, EDGE_EPS, K_MIN, Bound
from pgc_jax.splat.project import quat_to_rotmat


def _safe_norm(x: jnp.ndarray) -> jnp.ndarray:
    """|x| along the last axis with a zero (not NaN) gradient at x = 0."""
    s = jnp.sum(x * x, axis=-1)
    return jnp.where(s > 0, jnp.sqrt(jnp.where(s > 0, s, 1.0)), 0.0)


def _unit(x: jnp.ndarray, length: jnp.ndarray) -> jnp.ndarray:
    return x / jnp.where(length > 0, length, 1.0)[..., None]


def triangle_frames(vertices: jnp.ndarray, faces: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray, jnp.ndarray]:
    """``tau`` (F, 3), ``R`` (F, 3, 3) and ``k`` (F,) of every face (see the module docstring)."""
    v0, v1, v2 = (vertices[faces[:, i]] for i in range(3))
    tau = (v0 + v1 + v2) / 3.0
    e01, e02, e12 = v1 - v0, v2 - v0, v2 - v1
    l01, l02, l12 = _safe_norm(e01), _safe_norm(e02), _safe_norm(e12)
    x_axis = jnp.broadcast_to(jnp.array([1.0, 0.0, 0.0], vertices.dtype), e01.shape)
    use01, use02, use12 = (l > EDGE_EPS for l in (l01, l02, l12))
    edge = jnp.where(use01[:, None], e01, jnp.where(use02[:, None], e02, jnp.where(use12[:, None], e12, x_axis)))
    a = _unit(edge, _safe_norm(edge))
    n = jnp.cross(e01, e02)
    n_len = _safe_norm(n)
    longest = jnp.maximum(jnp.maximum(l01, l02), l12)
    rel = max(AREA_REL_EPS, 8.0 * float(jnp.finfo(vertices.dtype).eps))
    flat = n_len <= rel * longest ** 2 + AREA_ABS_EPS
    helper = jnp.eye(3, dtype=vertices.dtype)[jnp.argmin(jnp.abs(jax.lax.stop_gradient(a)), axis=1)]
    ortho = helper - jnp.sum(helper * a, axis=1, keepdims=True) * a
    fallback = _unit(ortho, _safe_norm(ortho))
    b = jnp.where(flat[:, None], fallback, _unit(n, jnp.where(flat, 1.0, n_len)))
    c = jnp.cross(a, b)
    R = jnp.stack([a, b, c], axis=2)
    height = n_len / jnp.maximum(l01, EDGE_EPS)
    k = jnp.maximum(0.5 * (l01 + height), K_MIN)
    return tau, R, k


def bind(parent: jnp.ndarray, means: jnp.ndarray, quats: jnp.ndarray, log_scales: jnp.ndarray,
         opacity_logits: jnp.ndarray, vertices: jnp.ndarray, faces: jnp.ndarray) -> Bound:
    """World Gaussians of local parameters (GaussianSet layout) on the mesh (vertices (V, 3), faces (F, 3))."""
    return apply_frames(*triangle_frames(vertices, faces), parent, means, quats, log_scales, opacity_logits)


def apply_frames(tau: jnp.ndarray, R: jnp.ndarray, k: jnp.ndarray, parent: jnp.ndarray, means: jnp.ndarray,
                 quats: jnp.ndarray, log_scales: jnp.ndarray, opacity_logits: jnp.ndarray) -> Bound:
    """World Gaussians from face frames (``tau``, ``R``, ``k`` of :func:`triangle_frames`)."""
    Rp, kp = R[parent], k[parent][:, None]
    return Bound(means=kp * jnp.einsum("nij,nj->ni", Rp, means) + tau[parent],
                 rotmats=Rp @ quat_to_rotmat(quats),
                 scales=kp * jnp.exp(log_scales),
                 opacities=jax.nn.sigmoid(opacity_logits))
