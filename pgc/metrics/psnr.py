"""Peak signal-to-noise ratio (dB) for images in [0, 1]: ``10 log10(1 / MSE)``, optionally at a fixed exposure."""

from __future__ import annotations

from typing import Literal

import numpy as np

from pgc.errors import PGCDataError
from pgc.metrics.common import check_images, masked_mean

BLACK = 1e-6
"""A target whose mean linear value (over the mask) is below this is black: no exposure brings it to a grey."""


def psnr(pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None,
         color_space: Literal["srgb", "linear"] = "srgb", exposure: float | None = None) -> float:
    """PSNR in dB of (H, W, C) linear images; compared as sRGB-encoded values unless ``color_space='linear'``.

    With ``mask`` the MSE is the mask-weighted mean over pixels and channels. Identical images give +inf.
    With ``exposure`` (a linear grey, e.g. 0.18) both images are first multiplied by the one factor that brings
    the target's mean over the mask (all channels) to ``exposure``, as a camera's auto-exposure would: the PSNR of
    a frame under a darker light then measures the same relative error as under a brighter one (plain sRGB PSNR
    rises as the light dims). A target darker than :data:`BLACK` is refused.
    NaN/Inf inputs, empty images and mismatched shapes are refused (:func:`pgc.metrics.common.check_images`).
    """
    pred, target = check_images("psnr", pred, target, mask, rgb=False)
    if exposure is not None:
        pred, target = exposed(pred, target, mask, exposure)
    if color_space == "srgb":
        from pgc.io.images import linear_to_srgb

        pred, target = linear_to_srgb(pred), linear_to_srgb(target)
    mse = masked_mean((np.asarray(pred, np.float64) - np.asarray(target, np.float64)) ** 2, mask, "psnr")
    return float("inf") if mse == 0 else float(-10.0 * np.log10(mse))


def exposed(pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None,
            exposure: float) -> tuple[np.ndarray, np.ndarray]:
    """``pred`` and ``target`` (float64) scaled by ``exposure / mean(target over mask)``."""
    if not exposure > 0:
        raise PGCDataError(f"psnr: exposure {exposure!r} must be a positive linear value (e.g. 0.18, mid-grey)")
    target = np.asarray(target, np.float64)
    mean = masked_mean(target, mask, "psnr")
    if not mean >= BLACK:
        raise PGCDataError(f"psnr: the target's mean over the {'mask' if mask is not None else 'image'} is {mean:.3g}, "
                           f"black (below {BLACK:g}); no exposure brings it to {exposure:g}: leave the exposure-"
                           "normalised PSNR out of a black region's metrics")
    scale = exposure / mean
    return np.asarray(pred, np.float64) * scale, target * scale
