"""Oriented dense points of a capture: visual hull -> hull-guided plane-sweep depth maps -> points with
normals (plus hull points where stereo found none). Shared by the open3d and colmap reconstructors."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.geometry.hull import SilhouetteField, _axis_centre, check_views, pixel_footprint, visual_hull
from pgc.geometry.metrics import sample_surface
from pgc.geometry.options import DenseOptions
from pgc.geometry.raster import rasterize
from pgc.geometry.stereo import depth_maps, depth_to_points
from pgc.sampling import spread
from pgc.types import Capture, Mesh


@dataclass
class DenseResult:
    points: np.ndarray
    """(N, 3) world points (metres)."""
    normals: np.ndarray
    """(N, 3) unit normals, outward."""
    depths: list[np.ndarray]
    """Filtered depth map per stereo view (camera z, 0 where invalid)."""
    stereo_ids: list[int]
    """Indices in ``capture.views`` of the views with a depth map (:attr:`DenseOptions.stereo_views`)."""
    field: SilhouetteField
    hull: Mesh
    """The visual hull's surface."""
    footprint: float
    """Median pixel footprint at the object (metres)."""
    stereo_points: int
    hull_points: int


def dense_points(capture: Capture, options: DenseOptions, reporter: Reporter | None = None) -> DenseResult:
    reporter = reporter or Reporter.silent()
    views = capture.views
    masks = check_views(views, options.min_views)
    with reporter.stage("mesh.visual_hull"):
        field = SilhouetteField.from_masks([v.camera for v in views], masks)
        hv, hf, field = visual_hull(views, field=field)
    centre = _axis_centre(capture.cameras)
    footprint = pixel_footprint(capture.cameras, hv.mean(0))
    ids = spread(range(len(views)), options.stereo_views or len(views))
    stereo = [views[i] for i in ids]
    hull_depths = [rasterize(v.camera, hv, hf).depth for v in stereo]
    depths = depth_maps(stereo, hull_depths, [masks[i] for i in ids], centre, options.stereo(), reporter)
    pts, nrm = [], []
    for v, d in zip(stereo, depths):
        p, n = depth_to_points(v.camera, d)
        pts.append(p)
        nrm.append(n)
    points, normals = np.concatenate(pts), np.concatenate(nrm)
    n_stereo = len(points)
    n_hull = 0
    hull = Mesh(hv, hf)
    if options.hull_fill:
        hp, hn = hull_fill_points(hull, points, footprint)
        points, normals = np.concatenate([points, hp]), np.concatenate([normals, hn])
        n_hull = len(hp)
    return DenseResult(points, normals, depths, ids, field, hull, footprint, n_stereo, n_hull)


def hull_fill_points(hull: Mesh, points: np.ndarray, footprint: float) -> tuple[np.ndarray, np.ndarray]:
    """Samples of the hull surface (one per footprint squared) farther than three footprints from every
    point of ``points``, with the hull's outward normals."""
    from scipy.spatial import cKDTree

    count = int(hull.face_areas().sum() / footprint ** 2)
    hp, hfid = sample_surface(hull, count, seed=0)
    far = np.ones(len(hp), bool) if len(points) == 0 else cKDTree(points).query(hp, workers=-1)[0] > 3 * footprint
    return hp[far], hull.face_normals()[hfid[far]]


def poisson_depth_for(points: np.ndarray, cell: float) -> int:
    """Octree depth whose cell size (Open3D scales the bounding cube by 1.1) is at most ``cell``."""
    if len(points) == 0:
        raise PGCDataError("no points to mesh: stereo found no consistent depth (too few views or too little "
                           "texture at this resolution)")
    extent = 1.1 * float(np.max(points.max(0) - points.min(0)))
    return int(np.clip(np.ceil(np.log2(extent / cell)), 5, 11))


def trim_outside(vertices: np.ndarray, faces: np.ndarray, inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep faces whose three vertices are ``inside`` (V,) bool; drop unused vertices."""
    keep = inside[faces].all(1)
    f = faces[keep]
    used = np.unique(f)
    remap = np.full(len(vertices), -1, np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[f]
