"""Small analytic scenes for PBR tests and benchmarks: a UV sphere and a folded cloth sheet with UV atlases,
a procedural base-colour texture, and a ring of cameras. numpy only.
"""

from __future__ import annotations

import numpy as np

from pgc.testing.capture_scenes import look_at
from pgc.types import Camera, Mesh


def uv_sphere(radius: float = 0.5, n_lat: int = 24, n_lon: int = 48, center=(0.0, 0.0, 0.0)) -> Mesh:
    """A latitude-longitude sphere (+Y poles); u = longitude / 2 pi, v = latitude (v up, 1 at +Y).

    The seam at u = 0/1 has separate texture vertices; the poles are rows of vertices (degenerate
    triangles there are dropped)."""
    lat = np.linspace(0.0, np.pi, n_lat + 1)
    lon = np.linspace(0.0, 2 * np.pi, n_lon + 1)
    T, P = np.meshgrid(lat, lon, indexing="ij")
    pos = np.stack([np.sin(T) * np.sin(P), np.cos(T), np.sin(T) * np.cos(P)], -1) * radius + np.asarray(center)
    uv = np.stack([P / (2 * np.pi), 1.0 - T / np.pi], -1).reshape(-1, 2)
    idx = np.arange((n_lat + 1) * (n_lon + 1)).reshape(n_lat + 1, n_lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    tris = np.concatenate([np.stack([a, b, c], -1)[:-1], np.stack([a, c, d], -1)[1:]]).reshape(-1, 3)
    # merge duplicate positions (the seam column and the pole rows) for the geometry, keep UV corners
    flat = pos.reshape(-1, 3)
    _, first, inverse = np.unique(np.round(flat, 9), axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    remap = np.empty_like(order)
    remap[order] = np.arange(len(order))
    faces = remap[inverse.reshape(-1)][tris]
    return Mesh(flat[first[order]], faces, uv.astype(np.float32), tris, name="uv_sphere")


def folded_sheet(width: float = 1.0, height: float = 0.8, n: int = 32, folds: float = 2.0,
                 depth: float = 0.12) -> Mesh:
    """A cloth sheet in the XY plane (facing +Z) with vertical sinusoidal folds of ``depth`` metres, so that
    it shadows and inter-reflects itself; UVs map the sheet's rectangle to [0, 1]^2."""
    s, t = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    x = (s - 0.5) * width
    y = (t - 0.5) * height
    z = depth * np.sin(2 * np.pi * folds * s) * (0.6 + 0.4 * np.cos(np.pi * (t - 0.5)))
    pos = np.stack([x, y, z], -1).reshape(-1, 3)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]).reshape(-1, 3)
    uv = np.stack([s, t], -1).reshape(-1, 2).astype(np.float32)
    return Mesh(pos, faces, uv, faces.copy(), name="folded_sheet")


def checker_texture(size: int = 64, cells: int = 8, colors=((0.7, 0.35, 0.2), (0.25, 0.45, 0.6))) -> np.ndarray:
    """(size, size, 3) float32 linear-RGB checkerboard."""
    i, j = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    pick = ((i * cells // size) + (j * cells // size)) % 2
    return np.asarray(colors, dtype=np.float32)[pick]


def ring_cameras(count: int, size: int = 64, radius: float = 2.5, elevation_deg: float = 15.0,
                 target=(0.0, 0.0, 0.0), fov_y_deg: float = 35.0, arc_deg: float = 360.0) -> list[Camera]:
    """``count`` square cameras evenly spread over an ``arc_deg`` arc (centred on +Z) of a ring."""
    target = np.asarray(target, dtype=np.float64)
    e = np.radians(elevation_deg)
    cams = []
    for k in range(count):
        az = np.radians(arc_deg) * ((k + 0.5) / count - 0.5)
        c = target + radius * np.array([np.cos(e) * np.sin(az), np.sin(e), np.cos(e) * np.cos(az)])
        cams.append(look_at(c, target, size, size, fov_y_deg, f"cam{k:02d}"))
    return cams
