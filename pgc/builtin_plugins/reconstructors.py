"""Built-in reconstructors: ``visual_hull`` (fast baseline) and ``mesh`` (a user's own scan)."""

from __future__ import annotations

import time

import numpy as np

from pgc.builtin_plugins.specs_reconstruct import MeshFileOptions, VisualHullOptions
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.geometry.finish import finish
from pgc.geometry.hull import SilhouetteField, check_views, hull_bounds, pixel_footprint, visual_hull
from pgc.geometry.raster import rasterize
from pgc.roles.reconstructor import Reconstruction, Reconstructor
from pgc.types import Capture, Mesh


class VisualHullReconstructor(Reconstructor):
    Options = VisualHullOptions

    def reconstruct(self, capture: Capture, reporter: Reporter | None = None) -> Reconstruction:
        opt = self.options
        reporter = reporter or Reporter.silent()
        t0 = time.perf_counter()
        with reporter.stage("mesh.visual_hull"):
            field = SilhouetteField.from_views(capture.views, opt.min_views)
            lo, hi = hull_bounds(field)
            voxel = opt.voxel_px * pixel_footprint(capture.cameras, 0.5 * (lo + hi))
            v, f, _ = visual_hull(capture.views, voxel=voxel, field=field)
        t1 = time.perf_counter()
        mesh, figures = finish(v, f, capture.views, capture.labels, opt, reporter, name="visual_hull")
        figures.update(seconds_hull=t1 - t0, hull_voxel_m=voxel)
        return Reconstruction(mesh, figures)


def silhouette_iou(mesh: Mesh, capture: Capture) -> float:
    """Mean over views of the IoU between the mesh's rendered silhouette and the foreground mask."""
    masks = check_views(capture.views, 1)
    ious = []
    for view, mask in zip(capture.views, masks):
        sil = rasterize(view.camera, mesh.vertices, mesh.faces).face_id >= 0
        union = np.count_nonzero(sil | mask)
        ious.append(np.count_nonzero(sil & mask) / union if union else 1.0)
    return float(np.mean(ious))


def rigid_icp(source: np.ndarray, target: np.ndarray, target_normals: np.ndarray, iterations: int = 20,
              max_distance: float | None = None) -> np.ndarray:
    """4x4 rigid transform moving ``source`` points onto the ``target`` surface (point-to-plane ICP,
    linearised rotation per step). ``max_distance`` rejects pairs farther apart (metres)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(target)
    T = np.eye(4)
    p = source.copy()
    for _ in range(iterations):
        d, idx = tree.query(p, workers=-1)
        keep = d < (max_distance if max_distance is not None else np.percentile(d, 90) + 1e-12)
        q, n, s = target[idx[keep]], target_normals[idx[keep]], p[keep]
        a = np.concatenate([np.cross(s, n), n], axis=1)
        b = np.einsum("ij,ij->i", q - s, n)
        x, *_ = np.linalg.lstsq(a, b, rcond=None)
        wx, wy, wz = x[:3]
        rot = np.array([[1, -wz, wy], [wz, 1, -wx], [-wy, wx, 1]])
        u, _, vt = np.linalg.svd(rot)  # nearest rotation
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = u @ vt, x[3:]
        p = p @ step[:3, :3].T + step[:3, 3]
        T = step @ T
        if np.linalg.norm(x) < 1e-7:
            break
    return T


class MeshFileReconstructor(Reconstructor):
    Options = MeshFileOptions

    def reconstruct(self, capture: Capture, reporter: Reporter | None = None) -> Reconstruction:
        from pgc.io.mesh import read_mesh

        opt = self.options
        reporter = reporter or Reporter.silent()
        check_views(capture.views, opt.min_views)
        t0 = time.perf_counter()
        mesh = read_mesh(opt.path)
        v = mesh.vertices
        if opt.transform is not None:
            m = np.asarray(opt.transform, dtype=np.float64).reshape(4, 4)
            if abs(np.linalg.det(m[:3, :3])) < 1e-12:
                raise PGCDataError("reconstructor.mesh.transform: the 3x3 part is singular; give a similarity")
            v = v @ m[:3, :3].T + m[:3, 3]
        figures: dict = {}
        if opt.refine_alignment:
            with reporter.stage("mesh.align"):
                hv, hf, _ = visual_hull(capture.views, min_views=opt.min_views)
                hull = Mesh(hv, hf)
                T = rigid_icp(v, hv, hull.vertex_normals())
                v = v @ T[:3, :3].T + T[:3, 3]
                figures["icp_translation_m"] = float(np.linalg.norm(T[:3, 3]))
        mesh = Mesh(v, mesh.faces, name=mesh.name)
        iou = silhouette_iou(mesh, capture)
        figures["silhouette_iou"] = iou
        if iou < opt.min_silhouette_iou:
            raise PGCDataError(f"{opt.path}: the mesh's silhouettes overlap the capture masks with IoU {iou:.2f} < "
                               f"{opt.min_silhouette_iou}: it is not in the capture's frame; give "
                               "reconstructor.mesh.transform (4x4, to metres) or set refine_alignment = true")
        t1 = time.perf_counter()
        out, fin = finish(mesh.vertices, mesh.faces, capture.views, capture.labels, opt, reporter, name="mesh",
                          keep_topology=not opt.remesh)
        figures.update(fin)
        figures.update(seconds_load=t1 - t0, seconds_finish=time.perf_counter() - t1)
        return Reconstruction(out, figures)
