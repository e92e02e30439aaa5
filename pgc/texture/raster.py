"""Vectorised triangle rasterisation on a pixel grid (numpy): coverage, barycentrics and a z-buffer.

One routine serves both the UV atlas (triangles in texel coordinates, no depth) and screen space
(projected triangles with a z-buffer). Pixel (row i, col j) is sampled at its centre (j + 0.5, i + 0.5).
Triangles are processed in chunks; each chunk enumerates the pixels of every triangle's bounding box at
once (``np.repeat`` over box sizes), so there is no Python loop per triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EDGE_EPS = 1e-9


@dataclass
class Raster:
    face: np.ndarray
    """(H, W) int64 index of the covering triangle, -1 where none."""
    bary: np.ndarray
    """(H, W, 3) float64 barycentric coordinates of the pixel centre in that triangle (0 where none);
    perspective-correct (barycentrics of the 3D surface point) when depths are given."""
    depth: np.ndarray | None = None
    """(H, W) float64 depth of the nearest triangle (inf where none), when depth was given."""


def rasterize(tri_xy: np.ndarray, height: int, width: int, tri_depth: np.ndarray | None = None,
              chunk_pixels: int = 4_000_000) -> Raster:
    """Rasterise triangles given in pixel coordinates.

    tri_xy: (F, 3, 2) vertex positions (x right, y down, in pixels); tri_depth: (F, 3) per-vertex depth
    for a z-buffer (nearest wins; triangles with any depth <= 0 are skipped), or None (later triangles
    overwrite earlier ones where charts overlap, which a valid atlas never does). Degenerate (zero-area)
    triangles cover nothing.
    """
    tri_xy = np.asarray(tri_xy, dtype=np.float64)
    face = np.full((height, width), -1, dtype=np.int64)
    bary = np.zeros((height, width, 3))
    zbuf = np.full((height, width), np.inf) if tri_depth is not None else None
    if len(tri_xy) == 0:
        return Raster(face, bary, zbuf)
    valid = np.all(np.isfinite(tri_xy.reshape(len(tri_xy), -1)), axis=1)
    if tri_depth is not None:
        tri_depth = np.asarray(tri_depth, dtype=np.float64)
        valid &= np.all(tri_depth > 0, axis=1) & np.all(np.isfinite(tri_depth), axis=1)
    x0 = np.clip(np.floor(tri_xy[..., 0].min(1) - 0.5), 0, width).astype(np.int64)
    x1 = np.clip(np.ceil(tri_xy[..., 0].max(1) - 0.5) + 1, 0, width).astype(np.int64)
    y0 = np.clip(np.floor(tri_xy[..., 1].min(1) - 0.5), 0, height).astype(np.int64)
    y1 = np.clip(np.ceil(tri_xy[..., 1].max(1) - 0.5) + 1, 0, height).astype(np.int64)
    bw, bh = np.maximum(x1 - x0, 0), np.maximum(y1 - y0, 0)
    count = np.where(valid, bw * bh, 0)
    ids = np.nonzero(count)[0]
    start = 0
    while start < len(ids):
        # A chunk of triangles whose boxes hold about chunk_pixels pixels in total.
        cum = np.cumsum(count[ids[start:]])
        stop = start + max(1, int(np.searchsorted(cum, chunk_pixels, side="right")))
        _raster_chunk(ids[start:stop], tri_xy, tri_depth, x0, y0, bw, count, face, bary, zbuf)
        start = stop
    return Raster(face, bary, zbuf)


def _raster_chunk(ids, tri_xy, tri_depth, x0, y0, bw, count, face, bary, zbuf) -> None:
    n = count[ids]
    tri = np.repeat(ids, n)
    local = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    px = x0[tri] + local % bw[tri]
    py = y0[tri] + local // bw[tri]
    p = np.stack([px + 0.5, py + 0.5], axis=1)
    a, b, c = tri_xy[tri, 0], tri_xy[tri, 1], tri_xy[tri, 2]
    area = _cross(b - a, c - a)
    ok = np.abs(area) > EDGE_EPS
    safe = np.where(ok, area, 1.0)
    w0 = _cross(b - p, c - p) / safe
    w1 = _cross(c - p, a - p) / safe
    w2 = 1.0 - w0 - w1
    inside = ok & (w0 >= -1e-12) & (w1 >= -1e-12) & (w2 >= -1e-12)
    tri, px, py = tri[inside], px[inside], py[inside]
    w = np.stack([w0[inside], w1[inside], w2[inside]], axis=1)
    if zbuf is None:
        face[py, px] = tri
        bary[py, px] = w
        return
    # Perspective-correct: 1/z is affine in screen space; attributes follow (w_i / z_i) * z.
    w_over_z = w / tri_depth[tri]
    z = 1.0 / w_over_z.sum(axis=1)
    w = w_over_z * z[:, None]
    # Keep, per pixel, the nearest candidate of this chunk, then merge with the z-buffer.
    order = np.lexsort((z, py * face.shape[1] + px))
    flat = (py * face.shape[1] + px)[order]
    first = np.ones(len(flat), dtype=bool)
    first[1:] = flat[1:] != flat[:-1]
    sel = order[first]
    closer = z[sel] < zbuf[py[sel], px[sel]]
    sel = sel[closer]
    zbuf[py[sel], px[sel]] = z[sel]
    face[py[sel], px[sel]] = tri[sel]
    bary[py[sel], px[sel]] = w[sel]


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
