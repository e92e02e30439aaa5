"""Ray-cast visibility of a direction set from surface points (Open3D RaycastingScene, CPU)."""

from __future__ import annotations

import numpy as np

from pgc.types import Mesh


def visibility(mesh: Mesh, points: np.ndarray, normals: np.ndarray, directions: np.ndarray, offset: float,
               vertices: np.ndarray | None = None, batch_rays: int = 2_000_000) -> np.ndarray:
    """(P, n) float32: 1 where the ray from each point toward each direction escapes the mesh, else 0.

    Rays start ``offset`` metres off the surface on the side of the direction (two-sided surfaces: a
    direction below a point's normal is cast from below). Points with a zero normal use no offset.
    """
    import open3d as o3d

    verts = mesh.vertices if vertices is None else vertices
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(verts, np.float32)),
                        o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))
    points = np.asarray(points, np.float64)
    normals = np.asarray(normals, np.float64)
    n_dirs = len(directions)
    out = np.empty((len(points), n_dirs), dtype=np.float32)
    step = max(1, batch_rays // n_dirs)
    for s in range(0, len(points), step):
        p, nrm = points[s:s + step], normals[s:s + step]
        side = np.sign(nrm @ directions.T)  # (p, n)
        origins = p[:, None, :] + offset * side[..., None] * nrm[:, None, :]
        rays = np.concatenate([origins, np.broadcast_to(directions, origins.shape)], axis=-1)
        hit = scene.test_occlusions(o3d.core.Tensor(rays.reshape(-1, 6).astype(np.float32))).numpy()
        out[s:s + step] = 1.0 - hit.reshape(len(p), n_dirs)
    return out
