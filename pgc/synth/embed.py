"""Points embedded in a triangle mesh: barycentric position in a parent face plus an offset along the
interpolated vertex normal. They follow any deformation of the mesh (fibre roots, near-field detail)."""

from __future__ import annotations

import numpy as np

from pgc.types import Mesh


def embedded_points(vertices: np.ndarray, faces: np.ndarray, face: np.ndarray, bary: np.ndarray,
                    offset: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) points at barycentrics ``bary`` (N, 3) of ``faces[face]`` on a garment with ``vertices``,
    moved ``offset`` (N,) metres along the interpolated area-weighted vertex normal (unit length)."""
    v = np.asarray(vertices, np.float64)
    p = np.einsum("nk,nkd->nd", bary, v[faces[face]])
    if offset is None:
        return p
    vn = Mesh(v, faces).vertex_normals()
    n = np.einsum("nk,nkd->nd", bary, vn[faces[face]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
    return p + np.asarray(offset, np.float64)[:, None] * n
