"""Multi-view depth maps on the CPU: plane sweep with zero-mean NCC, guided by the visual hull.

For every reference view, depth hypotheses are swept per pixel from the visual hull's front depth (the hull
contains the object, so the surface lies at or behind it) over ``band`` metres, in steps of
``step_px`` pixel footprints (the sampling the images can resolve; finer steps cannot be told apart).
Each hypothesis warps the neighbour images (bilinear, cv2.remap) and scores a windowed zero-mean NCC; the
score of a hypothesis is the mean of the best ``top_k`` neighbours (robust to occlusion). The winner is
refined to sub-step precision with a parabola. Pixels outside the (eroded) foreground or with a low score are
invalid. A geometric consistency check then keeps a depth only where at least ``min_consistent`` neighbours'
depth maps agree with it (relative depth difference under ``consistency`` after reprojection).

Depth is camera z in metres; invalid pixels are 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.events import Reporter
from pgc.types import Camera, View


@dataclass(frozen=True)
class StereoSettings:
    neighbours: int = 6
    """Neighbour views per reference view (closest viewing directions, 5-70 degrees apart)."""
    top_k: int = 3
    """Neighbours whose NCC is averaged per hypothesis (the best ones)."""
    window: int = 7
    """NCC window side (pixels, odd)."""
    band: float = 0.12
    """Depth range swept behind the hull's front surface (metres)."""
    front_margin: float = 0.01
    """Depth range swept in front of the hull surface (metres; covers the hull's discretisation)."""
    step_px: float = 0.5
    """Depth step in pixel footprints."""
    max_planes: int = 96
    """Upper bound on hypotheses per pixel."""
    min_score: float = 0.5
    """Lowest accepted NCC."""
    min_consistent: int = 2
    """Neighbours whose depth must agree."""
    hull_tolerance: float = 0.05
    """Keep the visual hull's depth where its NCC is within this of the best hypothesis: where the hull is
    already photo-consistent (convex parts) the sweep's winner only adds noise."""
    consistency: float = 0.01
    """Relative depth agreement of the consistency check."""


def gray(view: View) -> np.ndarray:
    img = view.image
    return (0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]).astype(np.float32)


def select_neighbours(cameras: list[Camera], index: int, count: int, centre: np.ndarray,
                      min_deg: float = 5.0, max_deg: float = 70.0) -> list[int]:
    """Views whose direction to ``centre`` is closest to the reference's, between min and max degrees."""
    dirs = np.stack([centre - c.center for c in cameras])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(dirs @ dirs[index], -1, 1)))
    ok = [i for i in np.argsort(ang) if i != index and min_deg <= ang[i] <= max_deg]
    return [int(i) for i in ok[:count]]


def _box(x: np.ndarray, w: int) -> np.ndarray:
    import cv2

    return cv2.boxFilter(x, -1, (w, w), normalize=True, borderType=cv2.BORDER_REFLECT)


def _ncc(ref: np.ndarray, ref_mean: np.ndarray, ref_std: np.ndarray, src: np.ndarray, w: int) -> np.ndarray:
    mu = _box(src, w)
    var = np.maximum(_box(src * src, w) - mu * mu, 0.0)
    cov = _box(ref * src, w) - ref_mean * mu
    return cov / np.maximum(ref_std * np.sqrt(var), 1e-4)


def sweep_depth(views: list[View], index: int, hull_depth: np.ndarray, masks: list[np.ndarray],
                settings: StereoSettings, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Depth (H, W) and NCC score (H, W) of view ``index``; 0 depth / -1 score where invalid.

    Work is restricted to the bounding box of the foreground (plus the NCC window). For a neighbour with
    ``A = K_s R_s R_r^T K_r^-1`` and ``b = K_s (t_s - R_s R_r^T t_r)``, a reference pixel x at depth z maps
    to the homogeneous source pixel ``z A x + b``.
    """
    import cv2

    cams = [v.camera for v in views]
    cam = cams[index]
    h, w = cam.height, cam.width
    depth = np.zeros((h, w), np.float32)
    score = np.full((h, w), -1.0, np.float32)
    fg = cv2.erode(masks[index].astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    valid_full = fg & np.isfinite(hull_depth)
    nbrs = select_neighbours(cams, index, settings.neighbours, centre)
    if not valid_full.any() or not nbrs:
        return depth, score
    win = settings.window
    ys, xs = np.nonzero(valid_full)
    pad = win
    y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, h)
    x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, w)
    valid = valid_full[y0:y1, x0:x1]
    ref = gray(views[index])[y0:y1, x0:x1]
    ref_mean = _box(ref, win)
    ref_std = np.sqrt(np.maximum(_box(ref * ref, win) - ref_mean ** 2, 0.0))
    hd = hull_depth[y0:y1, x0:x1]
    z0 = np.where(valid, hd, np.median(hd[valid])).astype(np.float32)
    step = settings.step_px * float(np.median(z0[valid])) / cam.fx
    planes = int(min(settings.max_planes, np.ceil((settings.band + settings.front_margin) / step) + 1))
    offsets = -settings.front_margin + step * np.arange(planes)
    gy, gx = np.mgrid[y0:y1, x0:x1].astype(np.float64) + 0.5
    pix = np.stack([gx, gy, np.ones_like(gx)])  # (3, h, w)
    warps = []
    for n in nbrs:
        src = cams[n]
        rel = src.R @ cam.R.T
        A = src.K @ rel @ np.linalg.inv(cam.K)
        b = src.K @ (src.t - rel @ cam.t)
        warps.append((np.einsum("ij,jhw->ihw", A, pix).astype(np.float32), b.astype(np.float32),
                      gray(views[n]), src.width, src.height))
    costs = np.full((planes, y1 - y0, x1 - x0), -1.0, np.float32)
    for j, off in enumerate(offsets):
        z = z0 + np.float32(off)
        scores = []
        for ax, b, img, sw, sh in warps:
            hx, hy, hz = ax[0] * z + b[0], ax[1] * z + b[1], ax[2] * z + b[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                mx, my = hx / hz - 0.5, hy / hz - 0.5
            inside = (hz > 0) & (mx >= 0) & (mx <= sw - 1) & (my >= 0) & (my <= sh - 1)
            warped = cv2.remap(img, np.nan_to_num(mx, nan=-1.0), np.nan_to_num(my, nan=-1.0), cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            scores.append(np.where(inside, _ncc(ref, ref_mean, ref_std, warped, win), -1.0))
        stack = np.stack(scores)
        k = min(settings.top_k, len(scores))
        costs[j] = np.partition(stack, len(scores) - k, axis=0)[len(scores) - k:].mean(0)
    best = costs.argmax(0)
    best_score = np.take_along_axis(costs, best[None], 0)[0]
    # Sub-step refinement: vertex of the parabola through the best score and its neighbours.
    b0 = np.clip(best, 1, planes - 2)
    c_m = np.take_along_axis(costs, (b0 - 1)[None], 0)[0]
    c_0 = np.take_along_axis(costs, b0[None], 0)[0]
    c_p = np.take_along_axis(costs, (b0 + 1)[None], 0)[0]
    denom = c_m - 2 * c_0 + c_p
    curved = (best == b0) & (denom < -1e-6)
    shift = np.where(curved, 0.5 * (c_m - c_p) / np.where(curved, denom, -1.0), 0.0)
    refined = z0 + offsets[0] + step * (best + np.clip(shift, -0.5, 0.5))
    at_hull = int(np.argmin(np.abs(offsets)))
    hull_ok = costs[at_hull] >= best_score - settings.hull_tolerance
    refined = np.where(hull_ok, z0 + offsets[at_hull], refined)
    ok = valid & (best_score >= settings.min_score) & ((best > 0) & (best < planes - 1) | hull_ok)
    depth[y0:y1, x0:x1][ok] = refined[ok]
    score[y0:y1, x0:x1][ok] = best_score[ok]
    return depth, score


def consistency_filter(cameras: list[Camera], depths: list[np.ndarray], settings: StereoSettings,
                       centre: np.ndarray) -> list[np.ndarray]:
    """Keep depths that at least ``min_consistent`` neighbour depth maps confirm after reprojection."""
    out = []
    for i, cam in enumerate(cameras):
        d = depths[i]
        ys, xs = np.nonzero(d > 0)
        if len(ys) == 0:
            out.append(d.copy())
            continue
        z = d[ys, xs].astype(np.float64)
        pix = np.stack([xs + 0.5, ys + 0.5, np.ones_like(xs, dtype=np.float64)], 1)
        world = ((pix @ np.linalg.inv(cam.K).T) * z[:, None] - cam.t) @ cam.R
        agree = np.zeros(len(z), np.int64)
        for n in select_neighbours(cameras, i, settings.neighbours, centre):
            other = cameras[n]
            uv, zn = other.project(world)
            x, y = np.floor(uv[:, 0]).astype(np.int64), np.floor(uv[:, 1]).astype(np.int64)
            inside = (x >= 0) & (x < other.width) & (y >= 0) & (y < other.height) & (zn > 0)
            dn = np.zeros(len(z))
            dn[inside] = depths[n][y[inside], x[inside]]
            agree += (dn > 0) & (np.abs(dn - zn) < settings.consistency * zn)
        keep = np.zeros_like(d)
        good = agree >= settings.min_consistent
        keep[ys[good], xs[good]] = d[ys[good], xs[good]]
        out.append(keep)
    return out


def depth_maps(views: list[View], hull_depths: list[np.ndarray], masks: list[np.ndarray], centre: np.ndarray,
               settings: StereoSettings = StereoSettings(), reporter: Reporter | None = None) -> list[np.ndarray]:
    """Filtered depth maps of every view (camera z, metres; 0 where invalid)."""
    from concurrent.futures import ThreadPoolExecutor

    from pgc.cores import allotted_cores

    reporter = reporter or Reporter.silent()
    with reporter.stage("mesh.stereo", total=len(views)) as st, \
            ThreadPoolExecutor(max_workers=allotted_cores()) as pool:  # numpy and OpenCV release the GIL
        futures = [pool.submit(sweep_depth, views, i, hull_depths[i], masks, settings, centre)
                   for i in range(len(views))]
        raw = []
        for i, future in enumerate(futures):
            raw.append(future.result()[0])
            st.progress(i + 1)
    with reporter.stage("mesh.stereo_consistency"):
        out = consistency_filter([v.camera for v in views], raw, settings, centre)
    return out


def depth_normals(camera: Camera, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera-space points (H, W, 3), unit normals (H, W, 3) facing the camera (central differences of the
    back-projected points) and the (H, W) mask of pixels with four valid neighbours."""
    h, w = depth.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    pc = np.stack([xs, ys, np.ones_like(xs)], -1) @ np.linalg.inv(camera.K).T * depth[..., None]
    valid = depth > 0
    ok = np.zeros_like(valid)
    ok[1:-1, 1:-1] = valid[1:-1, 1:-1] & valid[:-2, 1:-1] & valid[2:, 1:-1] & valid[1:-1, :-2] & valid[1:-1, 2:]
    dx = np.zeros_like(pc)
    dy = np.zeros_like(pc)
    dx[:, 1:-1] = pc[:, 2:] - pc[:, :-2]
    dy[1:-1] = pc[2:] - pc[:-2]
    n = np.cross(dx, dy)
    length = np.linalg.norm(n, axis=-1)
    ok &= length > 0
    n = np.divide(n, length[..., None], out=np.zeros_like(n), where=ok[..., None])
    n *= np.where(np.einsum("hwk,hwk->hw", n, pc) > 0, -1.0, 1.0)[..., None]  # towards the camera
    return pc, n, ok


def depth_to_points(camera: Camera, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points (N, 3) and unit normals (N, 3) facing the camera from a depth map (pixels without four
    valid neighbours are dropped)."""
    pc, n, ok = depth_normals(camera, depth)
    return (pc[ok] - camera.t) @ camera.R, n[ok] @ camera.R
