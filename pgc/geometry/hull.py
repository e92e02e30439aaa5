"""Visual hull from foreground masks and calibrated cameras.

The hull is the intersection of the silhouette cones. Each view gives an approximate signed distance
(metres, negative inside its cone): the 2D signed distance of the pixel to the mask contour (threshold
0.5), scaled by the pixel footprint z / f. The hull's field is the maximum over views (intersection), and
its zero level set is meshed by surface nets. The object must lie inside every image (a capture dome).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError
from pgc.geometry.surface_nets import surface_nets
from pgc.types import Camera, View

OUTSIDE = 1e3
"""Field value (metres) of points behind a camera."""

PARALLEL_POINTS = 1 << 16
"""Points per thread below which the field is evaluated on one thread."""


def mask_of(view: View) -> np.ndarray:
    """Boolean foreground of a view (mask >= 0.5, else segmentation != 0)."""
    if view.mask is not None:
        return view.mask >= 0.5
    if view.segmentation is not None:
        return view.segmentation != 0
    raise PGCDataError(f"view '{view.camera.name}': has neither a foreground mask nor a segmentation; "
                       "add mask_path (or a segmentation) to the capture")


def check_views(views: list[View], min_views: int) -> list[np.ndarray]:
    """Masks of ``views`` after the checks every reconstructor needs (count, non-empty masks)."""
    if len(views) < min_views:
        raise PGCDataError(f"capture has {len(views)} views; reconstruction needs at least {min_views} "
                           "calibrated views with masks")
    masks = [mask_of(v) for v in views]
    empty = [v.camera.name for v, m in zip(views, masks) if not m.any()]
    if empty:
        raise PGCDataError(f"empty foreground mask in view(s) {', '.join(empty)}: every view must see the "
                           "person; fix the masks or remove those views")
    return masks


def _signed_pixel_distance(mask: np.ndarray) -> np.ndarray:
    from scipy.ndimage import distance_transform_edt

    outside = distance_transform_edt(~mask)
    inside = distance_transform_edt(mask)
    return np.where(mask, -(inside - 0.5), outside - 0.5)


@dataclass
class SilhouetteField:
    """The visual hull's approximate signed distance, evaluable at any world points."""

    cameras: list[Camera]
    distances: list[np.ndarray]

    @classmethod
    def from_views(cls, views: list[View], min_views: int = 3) -> "SilhouetteField":
        return cls.from_masks([v.camera for v in views], check_views(views, min_views))

    @classmethod
    def from_masks(cls, cameras: list[Camera], masks: list[np.ndarray]) -> "SilhouetteField":
        return cls(cameras, [_signed_pixel_distance(m) for m in masks])

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """(N,) signed distance in metres (negative inside every view's silhouette).

        Beyond an image border the distance continues as the border's value plus the distance past it, so
        the object must be inside every image (a capture dome); points behind a camera are outside. Many
        points are split between the allotted cores (each point's value is computed alone: the same bits)."""
        from concurrent.futures import ThreadPoolExecutor

        from pgc.cores import allotted_cores

        points = np.asarray(points, dtype=np.float64)
        threads = min(allotted_cores(), len(points) // PARALLEL_POINTS)
        if threads <= 1:
            return self._distance(points)
        with ThreadPoolExecutor(max_workers=threads) as pool:  # numpy releases the GIL
            return np.concatenate(list(pool.map(self._distance, np.array_split(points, threads))))

    def _distance(self, points: np.ndarray) -> np.ndarray:
        out = np.full(len(points), -np.inf)
        for cam, dist in zip(self.cameras, self.distances):
            uv, z = cam.project(points)
            front = z > 1e-6
            uv = np.where(front[:, None], uv, 0.0)
            d = (_bilinear(dist, uv) + _beyond(uv, cam.width, cam.height)) * np.abs(z) / cam.fx
            out = np.maximum(out, np.where(front, d, OUTSIDE))
        return out


def _bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup at pixel coordinates ``uv`` (N, 2) (centres at integer + 0.5), clamped to the border."""
    h, w = image.shape
    x = np.clip(uv[:, 0] - 0.5, 0, w - 1)
    y = np.clip(uv[:, 1] - 0.5, 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(np.int64), w - 2) if w > 1 else np.zeros(len(x), np.int64)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 2) if h > 1 else np.zeros(len(y), np.int64)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = x - x0, y - y0
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def _beyond(uv: np.ndarray, width: int, height: int) -> np.ndarray:
    """Distance (pixels) of ``uv`` outside the image rectangle (0 inside)."""
    return np.hypot(uv[:, 0] - np.clip(uv[:, 0], 0, width), uv[:, 1] - np.clip(uv[:, 1], 0, height))


def _axis_centre(cameras: list[Camera]) -> np.ndarray:
    """Least-squares point closest to every optical axis (the rig's focus)."""
    a = np.zeros((3, 3))
    b = np.zeros(3)
    for cam in cameras:
        d = cam.R[2]
        p = np.eye(3) - np.outer(d, d)
        a += p
        b += p @ cam.center
    return np.linalg.lstsq(a, b, rcond=None)[0]


def _grid(lo: np.ndarray, hi: np.ndarray, spacing: float) -> tuple[np.ndarray, tuple[int, int, int]]:
    n = np.maximum(np.ceil((hi - lo) / spacing).astype(int) + 1, 2)
    axes = [lo[i] + spacing * np.arange(n[i]) for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return pts, (int(n[0]), int(n[1]), int(n[2]))


def hull_bounds(field: SilhouetteField, coarse: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (metres) of the hull, found on a coarse grid around the rig's focus."""
    cams = field.cameras
    centre = _axis_centre(cams)
    radius = 0.95 * min(np.linalg.norm(c.center - centre) for c in cams)
    lo, hi = centre - radius, centre + radius
    for _ in range(2):  # a coarse pass, then a finer one on the shrunk box
        spacing = float(np.max(hi - lo)) / coarse
        pts, shape = _grid(lo, hi, spacing)
        occ = field(pts) < spacing
        if not occ.any():
            raise PGCDataError("the silhouettes do not intersect: the cameras do not see a common object "
                               "(check the camera poses, their convention, and the masks)")
        sel = pts[occ]
        lo, hi = sel.min(0) - 2 * spacing, sel.max(0) + 2 * spacing
    return lo, hi


def _field_on_grid(field: SilhouetteField, lo: np.ndarray, hi: np.ndarray, voxel: float, coarse: int = 3) -> np.ndarray:
    """The field on the grid of ``voxel`` spacing from ``lo``, evaluated exactly only near its zero set.

    The field is (about) 1-Lipschitz, so a trilinear interpolation from a grid ``coarse`` times coarser
    is off by less than its cell diagonal; where that interpolation is farther than two coarse cells from
    zero, its sign is right and its value is kept."""
    from scipy.ndimage import map_coordinates

    pts, shape = _grid(lo, hi, voxel)
    cpts, cshape = _grid(lo, hi + coarse * voxel, coarse * voxel)
    cvals = field(cpts).reshape(cshape)
    idx = np.stack(np.meshgrid(*[np.arange(n) / coarse for n in shape], indexing="ij"), 0).reshape(3, -1)
    values = map_coordinates(np.minimum(cvals, OUTSIDE), idx, order=1, mode="nearest")
    near = np.abs(values) < 2.0 * coarse * voxel
    values[near] = field(pts[near])
    return values.reshape(shape)


def visual_hull(views: list[View], voxel: float | None = None, min_views: int = 3,
                field: SilhouetteField | None = None) -> tuple[np.ndarray, np.ndarray, SilhouetteField]:
    """Mesh of the visual hull. ``voxel`` (metres) defaults to one pixel footprint at the rig's distance.

    Returns vertices (V, 3), faces (F, 3) and the silhouette field (reused for trimming).
    """
    field = field or SilhouetteField.from_views(views, min_views)
    lo, hi = hull_bounds(field)
    if voxel is None:
        voxel = pixel_footprint(field.cameras, 0.5 * (lo + hi))
    voxel = max(float(voxel), float(np.max(hi - lo)) / 400.0)  # at most 400 cells along the longest side
    values = _field_on_grid(field, lo, hi, voxel)
    verts, faces = surface_nets(values, lo, voxel)
    if len(faces) == 0:
        raise PGCDataError("the visual hull is empty: the masks do not agree on any 3D point "
                           "(check the camera poses and the masks)")
    return verts, faces, field


def pixel_footprint(cameras: list[Camera], point: np.ndarray) -> float:
    """Median size (metres) of one pixel at ``point`` over the cameras."""
    return float(np.median([np.linalg.norm(point - c.center) / c.fx for c in cameras]))
