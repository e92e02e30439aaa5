"""Torch twin of :mod:`pgc.splats.binding` (same conventions and degenerate-triangle rules), differentiable
with respect to vertex positions and every local Gaussian parameter, NaN-free gradients everywhere."""

from __future__ import annotations

import torch

from pgc.splats.binding import AREA_ABS_EPS, AREA_REL_EPS, EDGE_EPS, K_MIN, Bound
from pgc.splats.quaternion import QUAT_EPS


def _safe_norm(x: torch.Tensor) -> torch.Tensor:
    """|x| along the last axis with a finite gradient at zero (the squared norm is floored at the smallest
    normal number of the dtype, so zero gives about 1e-19 in float32 and 1e-154 in float64)."""
    return torch.sqrt(torch.clamp_min((x * x).sum(-1), torch.finfo(x.dtype).tiny))


def triangle_frames(vertices: torch.Tensor, faces: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``tau`` (F, 3), ``R`` (F, 3, 3) (columns edge, normal, edge x normal), ``k`` (F,)."""
    v0, v1, v2 = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    tau = (v0 + v1 + v2) / 3.0
    e01, e02, e12 = v1 - v0, v2 - v0, v2 - v1
    l01, l02, l12 = _safe_norm(e01), _safe_norm(e02), _safe_norm(e12)
    x_axis = torch.zeros_like(e01)
    x_axis[:, 0] = 1.0
    edge = torch.where((l01 > EDGE_EPS)[:, None], e01, torch.where(
        (l02 > EDGE_EPS)[:, None], e02, torch.where((l12 > EDGE_EPS)[:, None], e12, x_axis)))
    a = edge / _safe_norm(edge)[:, None]
    n = torch.linalg.cross(e01, e02)
    n_len = _safe_norm(n)
    longest = torch.maximum(torch.maximum(l01, l02), l12)
    flat = n_len <= AREA_REL_EPS * longest ** 2 + AREA_ABS_EPS
    helper = torch.eye(3, dtype=vertices.dtype)[torch.argmin(a.detach().abs(), dim=1)]
    ortho = helper - (helper * a).sum(-1, keepdim=True) * a
    fallback = ortho / _safe_norm(ortho)[:, None]
    b = torch.where(flat[:, None], fallback, n / n_len[:, None])
    c = torch.linalg.cross(a, b)
    R = torch.stack([a, b, c], dim=2)
    height = n_len / torch.clamp_min(l01, EDGE_EPS)
    k = torch.clamp_min(0.5 * (l01 + height), K_MIN)
    return tau, R, k


def quat_to_rotmat(q: torch.Tensor) -> torch.Tensor:
    """(N, 4) (w, x, y, z) of any norm (zero means identity) -> (N, 3, 3)."""
    n2 = (q * q).sum(-1, keepdim=True)
    identity = torch.zeros_like(q)
    identity[:, 0] = 1.0
    q = torch.where(n2 > QUAT_EPS ** 2, q * torch.rsqrt(torch.clamp_min(n2, QUAT_EPS ** 2)), identity)
    w, x, y, z = q.unbind(-1)
    return torch.stack([
        torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        torch.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        torch.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def apply_frames(tau: torch.Tensor, R: torch.Tensor, k: torch.Tensor, parent: torch.Tensor, means: torch.Tensor,
                 quats: torch.Tensor, log_scales: torch.Tensor, opacity_logits: torch.Tensor) -> Bound:
    """World Gaussians from per-face frames: means ``k R mu + tau``, rotation matrices ``R_face @ rot(r)`` (the
    numpy binding's world quaternion ``R r``), scales ``k s``, opacities ``sigmoid(logit)``."""
    Rp, kp = R[parent], k[parent][:, None]
    return Bound(means=kp * torch.einsum("nij,nj->ni", Rp, means) + tau[parent], rotmats=Rp @ quat_to_rotmat(quats),
                 scales=kp * torch.exp(log_scales), opacities=torch.sigmoid(opacity_logits))


def bind(parent: torch.Tensor, means: torch.Tensor, quats: torch.Tensor, log_scales: torch.Tensor,
         opacity_logits: torch.Tensor, vertices: torch.Tensor, faces: torch.Tensor) -> Bound:
    """World Gaussians of local parameters (GaussianSet layout) on the mesh (vertices (V, 3), faces (F, 3))."""
    return apply_frames(*triangle_frames(vertices, faces), parent, means, quats, log_scales, opacity_logits)
