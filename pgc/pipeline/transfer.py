"""Carry points rigidly along a deforming surface: embed them on a rest mesh, re-place them per frame.

Used to give the ground-truth garment exactly the simulated motion of the reconstructed one, so that
appearance is judged on matching geometry: each ground-truth vertex is tied to its closest point on the
reconstructed rest garment (face, barycentrics, offset along the interpolated normal). A surface carried along
another one's motion can sink into a body the other one only touched; :func:`clear_of_body` keeps it as clear of
the body as it rested.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.arrays import array_ops
from pgc.sim.collision import candidate_corners, signed_distance, vertex_normals
from pgc.sim.xpbd import closest_barycentric, closest_contact, contact_mask, push_out
from pgc.types import Mesh

CLEARANCE_M = 0.002
"""The clearance from the body a carried point keeps (or less, if it rested closer), metres: at zero the body and
the cloth share a surface and the body shows through in a render."""
REACH_M = 0.03
"""Points farther than this from the body are left alone (metres): far from the surface, which side of a thin limb a
point is on is not reliable."""
PASSES = 4
"""Pushes at most (each to the tangent plane at the closest point, found again: in a concave fold one is not enough)."""
SETTLED_M = 1e-5
"""A pass that pushes no point farther than this (metres) is the last."""


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


def rest_clearance(points: np.ndarray, body: Mesh, clearance: float = CLEARANCE_M) -> np.ndarray:
    """(N,) the clearance from ``body`` each of ``points`` keeps: its signed distance at rest (metres, negative
    inside), at most ``clearance``."""
    return np.minimum(signed_distance(np.asarray(points, np.float64), body.vertices, body.faces), clearance)


def clear_of_body(points: np.ndarray, body_vertices: np.ndarray, body_faces: np.ndarray,
                  clearance: np.ndarray) -> np.ndarray:
    """``points`` (N, 3) pushed out along the body's normal wherever they are closer to the body surface than their
    ``clearance`` (N,) metres (:func:`rest_clearance`); points farther than :data:`REACH_M` are left alone."""
    ops = array_ops("numpy")
    p, body = np.asarray(points, np.float64), np.asarray(body_vertices, np.float64)
    normals, every = vertex_normals(body, body_faces), np.ones(len(p))
    for _ in range(PASSES):
        contact = closest_contact(ops, p, body, normals, candidate_corners(p, body, body_faces, 16))
        p, depth = push_out(ops, p, contact.point, contact.normal, contact_mask(ops, p, contact, REACH_M, every),
                            clearance)
        if depth.max(initial=0.0) < SETTLED_M:
            break
    return p
