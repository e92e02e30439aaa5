"""Screen-space visibility of a mesh from a camera (a numpy z-buffer)."""

from __future__ import annotations

import numpy as np

from pgc.geometry.raster import Raster, rasterize
from pgc.types import Camera, Mesh


def render_faces(mesh: Mesh, camera: Camera, vertices: np.ndarray | None = None,
                 occluder: Mesh | None = None) -> Raster:
    """Nearest face, perspective-correct barycentrics and camera depth per pixel of ``camera``.

    With ``occluder``, pixels where the occluder is nearer are empty (face -1, depth +inf)."""
    verts = mesh.vertices if vertices is None else vertices
    if occluder is None:
        return rasterize(camera, verts, mesh.faces)
    both = rasterize(camera, np.concatenate([verts, occluder.vertices]),
                     np.concatenate([mesh.faces, occluder.faces + len(verts)]))
    hidden = both.face_id >= len(mesh.faces)
    return Raster(np.where(hidden, -1, both.face_id), np.where(hidden, np.inf, both.depth),
                  np.where(hidden[..., None], 0.0, both.bary))


def visible_points(points: np.ndarray, faces_of_points: np.ndarray | None, raster: Raster, camera: Camera,
                   depth_tolerance: float = 2e-3) -> tuple[np.ndarray, np.ndarray]:
    """Which surface ``points`` (N, 3) on faces ``faces_of_points`` (N,) are seen by ``camera``.

    A point is visible when it projects inside the image in front of the camera and either the z-buffer
    shows its own face there or its depth is within ``depth_tolerance`` (relative) of the z-buffer
    (``faces_of_points`` None: the raster is of another mesh, e.g. an occluder; depth test only).
    Returns (visible (N,) bool, pixel coordinates (N, 2)).
    """
    xy, z = camera.project(points)
    inside = (z > 0) & np.all(np.isfinite(xy), axis=1)
    inside &= (xy[:, 0] >= 0) & (xy[:, 0] < camera.width) & (xy[:, 1] >= 0) & (xy[:, 1] < camera.height)
    col = np.clip(np.where(inside, xy[:, 0], 0).astype(np.int64), 0, camera.width - 1)
    row = np.clip(np.where(inside, xy[:, 1], 0).astype(np.int64), 0, camera.height - 1)
    same_face = False if faces_of_points is None else raster.face_id[row, col] == faces_of_points
    zb = raster.depth[row, col]
    close = np.abs(zb - z) <= depth_tolerance * np.maximum(z, 1e-9)
    return inside & (same_face | close), xy


def render_texture_to_view(mesh: Mesh, texture: np.ndarray, camera: Camera,
                           vertices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The textured mesh seen by ``camera`` (unlit): ((H, W, C) texture colours, (H, W) coverage 0/1)."""
    from pgc.errors import PGCDataError
    from pgc.texture.sample import sample_uv

    if mesh.uv is None:
        raise PGCDataError(f"mesh '{mesh.name}' has no UVs to look the texture up with")
    raster = render_faces(mesh, camera, vertices)
    covered = raster.face_id >= 0
    fid = raster.face_id[covered]
    uv = np.einsum("nk,nkc->nc", raster.bary[covered], mesh.uv[mesh.face_uv[fid]].astype(np.float64))
    out = np.zeros((camera.height, camera.width, texture.shape[2]), dtype=np.float32)
    out[covered] = sample_uv(texture, uv)
    return out, covered.astype(np.float32)
