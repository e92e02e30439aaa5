"""Body collision geometry on the CPU (numpy/scipy): candidate triangles, normals, penetration, pairs."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from pgc.arrays import array_ops
from pgc.sim.xpbd import closest_contact
from pgc.types import Mesh


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(B, 3) area-weighted unit vertex normals (zero where undefined), see :meth:`Mesh.vertex_normals`."""
    return Mesh(vertices, faces).vertex_normals()


def candidate_corners(points: np.ndarray, body: np.ndarray, faces: np.ndarray, k: int) -> np.ndarray:
    """(V, k, 3) body vertex indices of the ``k`` triangles whose centroids are nearest each point.

    One KD-tree per call (once per frame); the exact closest point among them is refined every substep.
    """
    k = min(k, len(faces))
    centroids = body[faces].mean(axis=1)
    _, idx = cKDTree(centroids).query(points, k=k)
    return faces[np.asarray(idx, dtype=np.int64).reshape(len(points), k)]


def signed_distance(points: np.ndarray, body: np.ndarray, faces: np.ndarray, k: int = 16) -> np.ndarray:
    """(V,) signed distance (m) of ``points`` to the body surface (negative inside), using the ``k`` nearest
    triangles by centroid and the blended vertex normal at the closest point for the sign."""
    corners = candidate_corners(points, body, faces, k)
    con = closest_contact(array_ops("numpy"), points.astype(np.float64), body.astype(np.float64),
                          vertex_normals(body.astype(np.float64), faces), corners)
    return con.signed


def penetration_fraction(points: np.ndarray, body: np.ndarray, faces: np.ndarray, depth: float) -> float:
    """Fraction of points deeper than ``depth`` (m) inside the body."""
    return float(np.mean(signed_distance(points, body, faces) < -depth))


def self_collision_pairs(points: np.ndarray, radius: float, exclude: set[tuple[int, int]],
                         pad_to: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Vertex pairs closer than ``radius`` that are not in ``exclude`` (topological neighbours).

    Padded to a multiple of ``pad_to`` (so that a JIT backend recompiles rarely); returns (P, 2) pairs and
    the (P,) validity mask.
    """
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    if len(pairs) and exclude:
        keep = np.array([(int(a), int(b)) not in exclude for a, b in pairs], dtype=bool)
        pairs = pairs[keep]
    n = max(pad_to, int(np.ceil(len(pairs) / pad_to)) * pad_to)
    out = np.zeros((n, 2), dtype=np.int64)
    out[: len(pairs)] = pairs
    valid = np.zeros(n, dtype=bool)
    valid[: len(pairs)] = True
    return out, valid
