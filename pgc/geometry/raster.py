"""A vectorised numpy z-buffer rasteriser: face ids, depth and barycentrics of a mesh seen by a camera.

Conventions: pgc.types.Camera (OpenCV, pixel centres at integer + 0.5); depth is camera z in metres;
``face_id`` is -1 where no face covers a pixel centre. Perspective-correct depth (1/z interpolated in screen
space). Faces with a vertex closer than ``near`` are skipped (the scenes we raster lie well in front of the
cameras; no clipping is done). Faces whose projection has (near) zero area are skipped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from pgc.types import Camera


@dataclass
class Raster:
    face_id: np.ndarray
    """(H, W) int64, -1 for empty pixels."""
    depth: np.ndarray
    """(H, W) float64 camera z (metres), +inf for empty pixels."""
    bary: np.ndarray
    """(H, W, 3) float64 perspective-correct barycentric coordinates (zero for empty pixels)."""


def covered_pixels(tri: np.ndarray, width: int, height: int, eps: float = 1e-9,
                   chunk: int = 2_000_000) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Pixel centres covered by 2D triangles ``tri`` (T, 3, 2) (pixel units), in chunks.

    Yields ``(triangle index, pixel index y * width + x, screen-space barycentrics (N, 3))``. A centre is
    covered when every barycentric is >= -eps (edges shared by two triangles cover both). Triangles with
    |signed area| <= 1e-12 px^2 cover nothing.
    """
    p = np.asarray(tri, dtype=np.float64)
    area = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])
    x0 = np.clip(np.ceil(p[..., 0].min(1) - 0.5), 0, width).astype(np.int64)
    x1 = np.clip(np.floor(p[..., 0].max(1) - 0.5), -1, width - 1).astype(np.int64)
    y0 = np.clip(np.ceil(p[..., 1].min(1) - 0.5), 0, height).astype(np.int64)
    y1 = np.clip(np.floor(p[..., 1].max(1) - 0.5), -1, height - 1).astype(np.int64)
    nx, ny = x1 - x0 + 1, y1 - y0 + 1
    ids = np.nonzero((nx > 0) & (ny > 0) & (np.abs(area) > 1e-12))[0]
    count = nx[ids] * ny[ids]
    ends = np.cumsum(count)
    start = 0
    while start < len(ids):
        stop = max(int(np.searchsorted(ends, (ends[start - 1] if start else 0) + chunk, side="right")), start + 1)
        t = ids[start:stop]
        c = count[start:stop]
        rep = np.repeat(t, c)
        local = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        px = x0[rep] + local % nx[rep]
        py = y0[rep] + local // nx[rep]
        cx, cy = px + 0.5, py + 0.5
        q = p[rep]
        b0 = (q[:, 1, 0] - cx) * (q[:, 2, 1] - cy) - (q[:, 2, 0] - cx) * (q[:, 1, 1] - cy)
        b1 = (q[:, 2, 0] - cx) * (q[:, 0, 1] - cy) - (q[:, 0, 0] - cx) * (q[:, 2, 1] - cy)
        bary = np.stack([b0, b1, area[rep] - b0 - b1], axis=1) / area[rep, None]
        inside = np.all(bary >= -eps, axis=1)
        yield rep[inside], (py * width + px)[inside], bary[inside]
        start = stop


def rasterize(camera: Camera, vertices: np.ndarray, faces: np.ndarray, near: float = 1e-3) -> Raster:
    """Rasterise ``faces`` of ``vertices`` (world metres) into ``camera``'s image."""
    h, w = camera.height, camera.width
    uv, z = camera.project(np.asarray(vertices, dtype=np.float64))
    faces = np.asarray(faces, dtype=np.int64)
    front = np.nonzero(np.all(z[faces] > near, axis=1))[0]
    best_depth = np.full(h * w, np.inf)
    best_face = np.full(h * w, -1, dtype=np.int64)
    best_bary = np.zeros((h * w, 3))
    zf = z[faces[front]]
    for tri, pix, bary in covered_pixels(uv[faces[front]], w, h):
        inv_z = bary / zf[tri]
        depth = 1.0 / inv_z.sum(1)
        bary = inv_z * depth[:, None]
        order = np.lexsort((depth, pix))
        first = order[np.r_[True, pix[order][1:] != pix[order][:-1]]]
        closer = first[depth[first] < best_depth[pix[first]]]
        px = pix[closer]
        best_depth[px], best_face[px], best_bary[px] = depth[closer], front[tri[closer]], bary[closer]
    return Raster(best_face.reshape(h, w), best_depth.reshape(h, w), best_bary.reshape(h, w, 3))
