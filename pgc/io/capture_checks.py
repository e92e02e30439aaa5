"""Sanity checks of a capture as a whole: inputs that read without error but that nothing can be reconstructed
from (every camera at one point, masks that say nothing) are refused instead of giving an asset without a word.
"""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError
from pgc.types import Capture

MIN_BASELINE = 1e-4
"""Smallest accepted spread of the camera centres, as a fraction of the scene's scale (the cameras' median
distance to the point their optical axes converge on, or to the world origin, whichever is larger)."""
MASK_THRESHOLD = 0.5
"""Mask values at or above this are foreground (as in the visual hull)."""


def check_capture(capture: Capture, source: str, min_views: int = 1) -> None:
    """Refuse, with :class:`PGCDataError` naming ``source`` (the capture's file), a capture with fewer than
    ``min_views`` views, several views without baseline (:data:`MIN_BASELINE`), masks all foreground or all
    background in every view, or a segmentation of one single label in every view."""
    views = capture.views
    if len(views) < min_views:
        raise PGCDataError(f"{source}: frames: the capture has {len(views)} view(s); reconstruction needs views "
                           f"from at least {min_views} camera positions")
    centres = np.array([v.camera.center for v in views])
    spread = float(np.linalg.norm(centres - centres.mean(axis=0), axis=1).max())
    scale = _scene_scale(capture, centres)
    if len(views) > 1 and spread <= MIN_BASELINE * scale:
        raise PGCDataError(f"{source}: frames: the {len(views)} cameras have no baseline: every centre lies within "
                           f"{spread:.3g} of their mean, at a scene scale of {scale:.3g} (the limit is "
                           f"{MIN_BASELINE:g} of it); the views must be taken from different positions (check "
                           "'transform_matrix')")
    masks = [v.mask for v in views if v.mask is not None]
    if len(masks) == len(views):
        if all(float(m.min()) >= MASK_THRESHOLD for m in masks):
            raise PGCDataError(f"{source}: mask_path: every mask is foreground everywhere (all values >= "
                               f"{MASK_THRESHOLD}), so it says nothing about the silhouette; give masks that are 1 "
                               "on the person and 0 elsewhere")
        if all(float(m.max()) < MASK_THRESHOLD for m in masks):
            raise PGCDataError(f"{source}: mask_path: every mask is background everywhere (all values < "
                               f"{MASK_THRESHOLD}): nothing is seen; give masks that are 1 on the person")
    segs = [v.segmentation for v in views if v.segmentation is not None]
    if len(segs) == len(views):
        first = int(segs[0].flat[0])
        if all(np.all(s == first) for s in segs):
            raise PGCDataError(f"{source}: pgc_segmentation_path: every segmentation holds the single label "
                               f"{first} ({capture.labels.get(first, 'unknown')}) everywhere; it must separate the "
                               "garment from the body and the background")


def _scene_scale(capture: Capture, centres: np.ndarray) -> float:
    """The cameras' median distance to the least-squares meeting point of their optical axes (when the axes are
    not all parallel) or to the world origin, whichever is larger."""
    scale = float(np.median(np.linalg.norm(centres, axis=1)))
    axes = np.array([v.camera.R[2] for v in capture.views])  # viewing directions in world coordinates
    projectors = np.eye(3)[None] - axes[:, :, None] * axes[:, None, :]
    A, b = projectors.sum(axis=0), np.einsum("nij,nj->i", projectors, centres)
    eig = np.linalg.eigvalsh(A)
    if eig[0] > 1e-3 * eig[-1]:
        point = np.linalg.solve(A, b)
        scale = max(scale, float(np.median(np.linalg.norm(centres - point, axis=1))))
    return scale


def require_segmentation(capture: Capture, source: str, what: str) -> None:
    """Refuse, naming ``source`` and what needs them (``what``), a capture with views lacking segmentation labels;
    the message says how to make them (masks are optional: the labels' foreground stands in)."""
    missing = [v.camera.name for v in capture.views if v.segmentation is None]
    if missing:
        raise PGCDataError(
            f"{source}: {what} needs segmentation labels for every view, and {len(missing)} of {len(capture.views)} "
            f"views have none ({', '.join(missing[:4])}{', ...' if len(missing) > 4 else ''}); add a grey 8-bit PNG "
            "per view with 0 background, 1 body (skin, hair, shoes), 2 garment, and name it in transforms.json as "
            "each frame's 'pgc_segmentation_path' (e.g. segmentation/<view>.png, made with a person/clothing "
            "segmenter; docs/your-capture.md); a 'mask_path' foreground mask per frame is optional")
