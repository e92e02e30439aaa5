"""The ``open3d`` reconstructor: dense oriented points (pgc.geometry.dense) -> Open3D screened Poisson ->
trim (low density, outside the visual hull) -> shared finishing (pgc.geometry.finish)."""

from __future__ import annotations

import time

import numpy as np

from pgc.events import Reporter
from pgc.geometry.dense import dense_points, poisson_depth_for, trim_outside
from pgc.geometry.finish import finish
from pgc.roles.reconstructor import Reconstruction, Reconstructor
from pgc.types import Capture
from pgc_open3d.specs_reconstruct import Open3DReconstructorOptions


def poisson_surface(points: np.ndarray, normals: np.ndarray, depth: int, density_quantile: float) -> tuple[np.ndarray, np.ndarray]:
    """Screened Poisson (Open3D) of oriented points; vertices under the density quantile are removed.

    One solver thread: Open3D's multi-threaded Poisson accumulates in a racy order, so its vertices change from
    call to call (and with the thread count); one thread gives the same mesh every time."""
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd.normals = o3d.utility.Vector3dVector(normals)
    mesh, density = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=depth, n_threads=1)
    density = np.asarray(density)
    if density_quantile > 0:
        mesh.remove_vertices_by_mask(density < np.quantile(density, density_quantile))
    return np.asarray(mesh.vertices), np.asarray(mesh.triangles, dtype=np.int64)


class Open3DReconstructor(Reconstructor):
    Options = Open3DReconstructorOptions

    def reconstruct(self, capture: Capture, reporter: Reporter | None = None) -> Reconstruction:
        opt = self.options
        reporter = reporter or Reporter.silent()
        t0 = time.perf_counter()
        dense = dense_points(capture, opt, reporter)
        t1 = time.perf_counter()
        with reporter.stage("mesh.poisson"):
            depth = opt.poisson_depth or poisson_depth_for(dense.points, opt.poisson_cell_px * dense.footprint)
            v, f = poisson_surface(dense.points, dense.normals, depth, opt.density_quantile)
            v, f = trim_outside(v, f, dense.field(v) <= opt.hull_margin_px * dense.footprint)
        t2 = time.perf_counter()
        mesh, figures = finish(v, f, capture.views, capture.labels, opt, reporter, name="open3d")
        figures.update(seconds_dense=t1 - t0, seconds_poisson=t2 - t1, poisson_depth=depth,
                       stereo_points=dense.stereo_points, hull_points=dense.hull_points,
                       footprint_m=dense.footprint)
        return Reconstruction(mesh, figures)
