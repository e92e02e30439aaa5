"""Helpers shared by the metrics: input checks, display encoding, masked means, the mask's bounding box."""

from __future__ import annotations

import numpy as np

from pgc.checks import require_finite, require_min_size
from pgc.errors import PGCDataError


def check_images(metric: str, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None,
                 min_size: int = 1, why: str = "", rgb: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The checks every metric makes before measuring, so that none returns NaN: ``pred`` and ``target`` of one
    shape, (H, W, 3) (or (H, W[, C]) when not ``rgb``), finite, at least ``min_size`` px a side (``why``: the
    window that needs it); ``mask`` (H, W) finite. A comparison that cannot be made is refused, not scored."""
    pred, target = np.asarray(pred), np.asarray(target)
    if pred.shape != target.shape:
        raise PGCDataError(f"{metric}: pred shape {pred.shape} != target shape {target.shape}; compare images of "
                           "one size")
    if (pred.ndim != 3 or pred.shape[2] != 3) if rgb else pred.ndim not in (2, 3):
        raise PGCDataError(f"{metric}: images must be {'(H, W, 3)' if rgb else '(H, W) or (H, W, C)'}, got shape "
                           f"{pred.shape}")
    require_finite(metric, "pred", pred)
    require_finite(metric, "target", target)
    if mask is not None:
        if np.shape(mask) != pred.shape[:2]:
            raise PGCDataError(f"{metric}: mask shape {np.shape(mask)} != image size {pred.shape[:2]}")
        require_finite(metric, "mask", mask)
    require_min_size(metric, pred.shape[0], pred.shape[1], min_size, why or "one pixel")
    return pred, target


def display_255(linear: np.ndarray) -> np.ndarray:
    """Linear RGB in [0, 1] -> sRGB-encoded values scaled to [0, 255], float64 (FSIM's constants assume 255)."""
    from pgc.io.images import linear_to_srgb

    return linear_to_srgb(linear).astype(np.float64) * 255.0


def masked_mean(values: np.ndarray, mask: np.ndarray | None, what: str) -> float:
    """Mean of ``values`` (H, W) or (H, W, C) weighted by ``mask`` (H, W) in [0, 1] (plain mean if None)."""
    if mask is None:
        return float(np.mean(values))
    weights = require_nonempty(mask, what)
    if values.ndim == 3:
        weights = np.broadcast_to(weights[..., None], values.shape)
    return float((values * weights).sum() / weights.sum())


def require_nonempty(mask: np.ndarray, what: str) -> np.ndarray:
    """``mask`` as float64 if it has positive weight somewhere, else the error every metric gives for an empty
    (all-zero) mask: nothing to measure."""
    weights = np.asarray(mask, np.float64)
    if not weights.sum() > 0:
        raise PGCDataError(f"{what}: the mask is empty (all zero); nothing to measure")
    return weights


def mask_bbox(mask: np.ndarray, min_size: int = 1) -> tuple[slice, slice]:
    """Row and column slices of the bounding box of ``mask > 0``, grown symmetrically (clamped to the image)
    to at least ``min_size`` px a side where the image allows."""
    rows, cols = np.nonzero(np.asarray(mask) > 0)
    if rows.size == 0:
        raise PGCDataError("metric: the mask is empty (all zero); nothing to measure")

    def grow(lo: int, hi: int, n: int) -> slice:
        size = max(hi - lo, min(min_size, n))
        start = min(max(0, (lo + hi - size) // 2), n - size)
        return slice(start, start + size)

    return grow(rows.min(), rows.max() + 1, mask.shape[0]), grow(cols.min(), cols.max() + 1, mask.shape[1])
