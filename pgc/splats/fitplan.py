"""The numpy pieces of the splat fit loop (:mod:`pgc.splats.fit`): initial count, schedules, contour band,
half-resolution views, held-out split, back-facing faces, checkpoint fingerprint, the held-out model selection
and the final garment / back-face selection, all following :class:`pgc.roles.splat_renderer.FitSplatsSettings`.

Schedules take the fraction ``p = step / iterations`` in [0, 1] of the planned fit.
"""

from __future__ import annotations

import hashlib
import json
import math
from typing import Any, Callable, Sequence

import numpy as np

from pgc.errors import PGCDataError
from pgc.roles.splat_renderer import FitSplatsSettings
from pgc.types import Camera, Capture, GaussianSet, Mesh, View

PAPER_ITERATIONS = 30000
COUNT_FRACTIONS = (0.3, 0.45, 0.6, 0.8)
"""Top-contribution fractions tried (smallest first) when choosing the Gaussian count."""
REST_LR_FACTOR = 1 / 20
"""3DGS: SH coefficients above the DC term learn this much slower than ``lr_other``."""


def require_labels(mesh: Mesh, s: FitSplatsSettings) -> None:
    """Raise :class:`PGCDataError` when ``keep = 'garment'`` but ``mesh`` has no face labels."""
    if s.keep == "garment" and mesh.face_labels is None:
        raise PGCDataError(f"fit_splats: mesh '{mesh.name}' has no face_labels, so the garment's Gaussians cannot "
                           "be selected; label the faces or set stages.fit_splats.keep = 'all'")


def initial_count(capture: Capture, s: FitSplatsSettings) -> int:
    """``gaussians_per_pixel`` x 2 (front and back) x mean foreground pixels per view, clamped."""
    covered = [float(np.sum(v.mask > 0.5)) if v.mask is not None else v.camera.width * v.camera.height
               for v in capture.views]
    return int(np.clip(round(s.gaussians_per_pixel * 2.0 * np.mean(covered)), s.min_gaussians, s.max_gaussians))


def sh_degree_at(p: float, s: FitSplatsSettings) -> int:
    """SH degree after fraction ``p``: one more every ``sh_interval`` of the paper's 30000 steps' worth."""
    return min(s.max_sh_degree, int(p * PAPER_ITERATIONS / s.sh_interval))


def position_lr_at(p: float, s: FitSplatsSettings) -> float:
    """Exponential decay of the local-position lr from ``lr_position`` (p = 0) to ``lr_position_final`` (p = 1)."""
    p = min(max(p, 0.0), 1.0)
    return math.exp((1 - p) * math.log(s.lr_position) + p * math.log(s.lr_position_final))


def auto_lr_factor(steps: float) -> float:
    """sqrt(30000 / steps) clamped to [1, 10]: a short run moves about as far as the paper's 30000 steps."""
    return float(np.clip(math.sqrt(PAPER_ITERATIONS / max(steps, 1.0)), 1.0, 10.0))


def outside_band(mask: np.ndarray, band: float) -> np.ndarray:
    """(H, W) float32: 1 outside the contour band of ``mask``, 0 inside it. The band lies between the erosion
    and the dilation of the binarised mask by a square of side ``band * H`` (odd, >= 1)."""
    from scipy.ndimage import binary_dilation, binary_erosion

    side = max(1, int(round(band * mask.shape[0])) | 1)
    m = np.asarray(mask) > 0.5
    square = np.ones((side, side), bool)
    ring = binary_dilation(m, square) != binary_erosion(m, square, border_value=1)
    return (~ring).astype(np.float32)


def half_resolution(view: View) -> View:
    """``view`` at half the resolution (camera scaled by 0.5; image, mask and background area-averaged), for
    the coarse phase of the fit (``coarse_fraction``)."""
    import cv2

    camera = view.camera.scaled(0.5)

    def shrink(a: np.ndarray | None) -> np.ndarray | None:
        size = (camera.width, camera.height)
        return None if a is None else cv2.resize(np.asarray(a, np.float32), size, interpolation=cv2.INTER_AREA)

    return View(camera, shrink(view.image), mask=shrink(view.mask), background=shrink(view.background))


def crop_view(view: View, x0: int, y0: int, x1: int, y1: int) -> View:
    """``view`` restricted to pixels [x0, x1) x [y0, y1) (camera, image, mask, segmentation, background)."""
    def cut(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else np.ascontiguousarray(a[y0:y1, x0:x1])

    return View(view.camera.cropped(x0, y0, x1 - x0, y1 - y0), cut(view.image), mask=cut(view.mask),
                segmentation=cut(view.segmentation), background=cut(view.background))


def focus_on_garment(capture: Capture, mesh: Mesh, s: FitSplatsSettings) -> tuple[Capture, np.ndarray | None]:
    """With ``focus = 'garment'``: the capture with every view cropped to its garment pixels' box grown by
    ``focus_margin`` x image height (views without garment pixels are dropped), and the (F,) faces of ``mesh``
    whose centroid projects inside some crop (garment faces always). Otherwise, or when the capture has no
    garment labels or a view no segmentation, ``(capture, None)``."""
    from dataclasses import replace

    if (s.focus != "garment" or not capture.garment_label_ids or mesh.face_labels is None
            or any(v.segmentation is None for v in capture.views)):
        return capture, None  # nothing to find the garment with: whole images
    ids = list(capture.garment_label_ids)
    centroids = mesh.vertices[mesh.faces].mean(axis=1)
    faces = np.isin(mesh.face_labels, ids)
    views = []
    for v in capture.views:
        rows, cols = np.nonzero(np.isin(v.segmentation, ids))
        if rows.size == 0:
            continue
        pad = int(round(s.focus_margin * v.camera.height))
        x0, y0 = max(0, int(cols.min()) - pad), max(0, int(rows.min()) - pad)
        x1, y1 = min(v.camera.width, int(cols.max()) + 1 + pad), min(v.camera.height, int(rows.max()) + 1 + pad)
        crop = crop_view(v, x0, y0, x1, y1)
        xy, z = crop.camera.project(centroids)
        faces |= (z > 0) & (xy[:, 0] >= 0) & (xy[:, 0] < x1 - x0) & (xy[:, 1] >= 0) & (xy[:, 1] < y1 - y0)
        views.append(crop)
    if not views:
        raise PGCDataError("fit_splats: no view shows the garment (segmentation); set stages.fit_splats.focus = 'all'")
    return replace(capture, views=views), faces


def initial_gaussians(capture: Capture, mesh: Mesh, s: FitSplatsSettings, rng: np.random.Generator,
                      faces: np.ndarray | None, views: Sequence[View]) -> GaussianSet:
    """:func:`initial_count` Gaussians on ``faces`` of ``mesh`` (all when None), coloured from ``views`` when
    ``init_color = 'views'``."""
    from pgc.splats.init import colors_from_views, sample_on_mesh

    g = sample_on_mesh(mesh, initial_count(capture, s), rng, s.max_sh_degree, faces)
    return colors_from_views(g, mesh, list(views)) if s.init_color == "views" else g


def heldout_split(n_views: int, every: int) -> tuple[list[int], list[int]]:
    """(train, held-out) view indices: every ``every``-th view is held out when there are >= 2 x every views."""
    held = list(range(every - 1, n_views, every)) if n_views >= 2 * every else []
    return [i for i in range(n_views) if i not in held], held


def backfacing_faces(mesh: Mesh, cameras: list[Camera]) -> np.ndarray:
    """(F,) True for faces whose front side faces no camera."""
    centroids = mesh.vertices[mesh.faces].mean(1)
    normals = mesh.face_normals()
    seen = np.zeros(len(mesh.faces), bool)
    for cam in cameras:
        seen |= np.sum(normals * (cam.center - centroids), axis=1) > 0
    return ~seen


def fingerprint(capture: Capture, mesh: Mesh, s: FitSplatsSettings, backend: str) -> str:
    """Identity of a fit (mesh, views, settings that change the result, backend): checkpoints match on it."""
    h = hashlib.sha256(backend.encode())
    h.update(np.ascontiguousarray(mesh.vertices).tobytes() + np.ascontiguousarray(mesh.faces).tobytes())
    h.update(json.dumps([v.camera.name for v in capture.views]).encode())
    h.update(json.dumps(s.model_dump(exclude={"checkpoint_dir", "checkpoint_every", "log_every"}), sort_keys=True,
                        default=str).encode())
    return h.hexdigest()[:20]


def select_model(contributions: np.ndarray, evaluate: Callable[[np.ndarray, int], float], degree: int,
                 has_heldout: bool, s: FitSplatsSettings, figures: dict[str, Any]) -> tuple[np.ndarray, int]:
    """Prune Gaussians whose summed compositing weight is below ``prune_weight``, then keep the smallest
    top-contribution subset and the lowest SH degree whose held-out PSNR (``evaluate(keep, degree)``) is within
    ``margin_db`` of the full model. Returns the keep mask and the degree; records the tables in ``figures``."""
    keep = contributions >= s.prune_weight
    figures["pruned_no_contribution"] = int((~keep).sum())
    base = evaluate(keep, degree) if has_heldout else float("nan")
    figures["psnr_heldout_full"] = base
    if s.select_count and has_heldout:
        ranked = np.argsort(-contributions)
        tried = {}
        for frac in COUNT_FRACTIONS:
            subset = np.zeros_like(keep)
            subset[ranked[:int(round(frac * keep.sum()))]] = True
            tried[str(frac)] = evaluate(subset, degree)
            if tried[str(frac)] >= base - s.margin_db:
                keep = subset
                break
        figures["count_selection"] = tried
    if s.select_sh and has_heldout:
        by_degree = {d: evaluate(keep, d) for d in range(degree + 1)}
        best = max(by_degree.values())
        degree = min(d for d, v in by_degree.items() if v >= best - s.margin_db)
        figures["sh_selection"] = {str(k): v for k, v in by_degree.items()}
    figures["sh_degree"] = degree
    figures["psnr_heldout"] = evaluate(keep, degree) if has_heldout else float("nan")
    return keep, degree


def final_keep(keep: np.ndarray, parent: np.ndarray, mesh: Mesh, cameras: list[Camera], s: FitSplatsSettings,
               garment_ids: list[int], figures: dict[str, Any]) -> np.ndarray:
    """After :func:`select_model`: drop Gaussians of back-facing faces (``drop_backfacing``), then keep the
    garment's (``keep = 'garment'``). ``parent`` (N,) face of each Gaussian; records counts in ``figures``."""
    keep = keep.copy()
    if s.drop_backfacing:
        back = backfacing_faces(mesh, cameras)[parent]
        figures["dropped_backfacing"] = int((keep & back).sum())
        keep &= ~back
    figures["gaussians_selected"] = int(keep.sum())
    if s.keep == "garment":
        keep &= np.isin(mesh.face_labels, garment_ids)[parent]
    figures["gaussians"] = int(keep.sum())
    return keep
