"""Peak signal-to-noise ratio (dB) for images in [0, 1]: ``10 log10(1 / MSE)``."""

from __future__ import annotations

from typing import Literal

import numpy as np

from pgc.metrics.common import check_images, masked_mean


def psnr(pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None,
         color_space: Literal["srgb", "linear"] = "srgb") -> float:
    """PSNR in dB of (H, W, C) linear images; compared as sRGB-encoded values unless ``color_space='linear'``.

    With ``mask`` the MSE is the mask-weighted mean over pixels and channels. Identical images give +inf.
    NaN/Inf inputs, empty images and mismatched shapes are refused (:func:`pgc.metrics.common.check_images`).
    """
    pred, target = check_images("psnr", pred, target, mask, rgb=False)
    if color_space == "srgb":
        from pgc.io.images import linear_to_srgb

        pred, target = linear_to_srgb(pred), linear_to_srgb(target)
    mse = masked_mean((np.asarray(pred, np.float64) - np.asarray(target, np.float64)) ** 2, mask, "psnr")
    return float("inf") if mse == 0 else float(-10.0 * np.log10(mse))
