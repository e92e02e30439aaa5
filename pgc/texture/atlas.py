"""Geometry of the texels of a UV atlas: which face covers each texel, where it lies in 3D, its normal.

Texel (row i, col j) of an (H, W) texture has its centre at ``u = (j + 0.5) / W``, ``v = 1 - (i + 0.5) / H``
(v up, as in :class:`pgc.types.Mesh`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError
from pgc.geometry.raster import covered_pixels
from pgc.types import Mesh


@dataclass
class TexelGeometry:
    face: np.ndarray
    """(H, W) int64 covering face, -1 outside the charts."""
    bary: np.ndarray
    """(H, W, 3) barycentric coordinates within that face."""
    position: np.ndarray
    """(H, W, 3) world position of the texel centre on the surface (0 outside)."""
    normal: np.ndarray
    """(H, W, 3) unit geometric normal of the covering face (0 outside)."""

    @property
    def valid(self) -> np.ndarray:
        return self.face >= 0


def uv_to_pixel(uv: np.ndarray, height: int, width: int) -> np.ndarray:
    """UV (v up) -> continuous pixel coordinates (x right, y down) of an (H, W) image."""
    uv = np.asarray(uv, dtype=np.float64)
    return np.stack([uv[..., 0] * width, (1.0 - uv[..., 1]) * height], axis=-1)


def texel_geometry(mesh: Mesh, height: int, width: int, vertices: np.ndarray | None = None) -> TexelGeometry:
    """Rasterise the UV atlas of ``mesh`` (positions from ``vertices`` if given, e.g. a deformed frame)."""
    if mesh.uv is None:
        raise PGCDataError(f"mesh '{mesh.name}' has no UV atlas; unwrap it first (the reconstructor does)")
    verts = mesh.vertices if vertices is None else np.asarray(vertices, dtype=np.float64)
    face = np.full(height * width, -1, dtype=np.int64)
    bary = np.zeros((height * width, 3))
    for tri, pix, b in covered_pixels(uv_to_pixel(mesh.uv[mesh.face_uv], height, width), width, height):
        face[pix], bary[pix] = tri, b  # charts of a valid atlas do not overlap
    face, bary = face.reshape(height, width), bary.reshape(height, width, 3)
    valid = face >= 0
    fid = np.where(valid, face, 0)
    corners = verts[mesh.faces[fid]]  # (H, W, 3, 3)
    position = np.einsum("hwk,hwkc->hwc", bary, corners) * valid[..., None]
    n = np.cross(corners[..., 1, :] - corners[..., 0, :], corners[..., 2, :] - corners[..., 0, :])
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    normal = np.divide(n, length, out=np.zeros_like(n), where=length > 0) * valid[..., None]
    return TexelGeometry(face, bary, position, normal)
