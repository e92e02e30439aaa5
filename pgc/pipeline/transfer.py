"""Carry points rigidly along a deforming surface: embed them on a rest mesh, re-place them per frame.

Used to give the ground-truth garment exactly the simulated motion of the reconstructed one, so that
appearance is judged on matching geometry: each ground-truth vertex is tied to its closest point on the
reconstructed rest garment (face, barycentrics, offset along the interpolated normal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.arrays import array_ops
from pgc.sim.xpbd import closest_barycentric
from pgc.types import Mesh


@dataclass
class Embedding:
    face: np.ndarray
    """(N,) face of the rest mesh each point is tied to."""
    bary: np.ndarray
    """(N, 3) barycentric coordinates of the closest point on that face."""
    offset: np.ndarray
    """(N,) signed distance along the interpolated vertex normal (metres)."""


def embed(points: np.ndarray, mesh: Mesh, candidates: int = 12) -> Embedding:
    """Tie ``points`` (N, 3) to their closest points on ``mesh`` (among the nearest ``candidates`` faces)."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64)
    k = min(candidates, len(mesh.faces))
    _, cand = cKDTree(mesh.vertices[mesh.faces].mean(axis=1)).query(pts, k=k)
    cand = np.asarray(cand, dtype=np.int64).reshape(len(pts), k)  # (N, k) face ids, nearest centroids
    corners = mesh.faces[cand]
    a, b, c = (mesh.vertices[corners[..., i]] for i in range(3))
    u, v, w = closest_barycentric(array_ops("numpy"), pts[:, None], a, b, c)
    closest = u[..., None] * a + v[..., None] * b + w[..., None] * c
    best = np.argmin(np.linalg.norm(closest - pts[:, None], axis=-1), axis=1)
    rows = np.arange(len(pts))
    face = cand[rows, best]
    bary = np.stack([u[rows, best], v[rows, best], w[rows, best]], axis=1)
    normals = _interpolated_normals(mesh, mesh.vertices, face, bary)
    offset = np.einsum("ij,ij->i", pts - closest[rows, best], normals)
    return Embedding(face, bary, offset)


def place(embedding: Embedding, mesh: Mesh, vertices: np.ndarray) -> np.ndarray:
    """The embedded points on the mesh deformed to ``vertices`` (V, 3)."""
    v = np.asarray(vertices, np.float64)
    base = np.einsum("nk,nkc->nc", embedding.bary, v[mesh.faces[embedding.face]])
    return base + embedding.offset[:, None] * _interpolated_normals(mesh, v, embedding.face, embedding.bary)


def _interpolated_normals(mesh: Mesh, vertices: np.ndarray, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    vn = Mesh(vertices, mesh.faces).vertex_normals()
    n = np.einsum("nk,nkc->nc", bary, vn[mesh.faces[face]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)

