"""SSIM (Wang et al. 2004) with the standard settings, written once over :mod:`pgc.arrays`: the metric (numpy)
and the splat fit's loss (torch, JAX; differentiable) share the window and the formula.

Gaussian window sigma 1.5 truncated at 3.5 sigma (11 taps), K1 = 0.01, K2 = 0.03, data range 1, population
(co)variances, per channel. The metric (:func:`ssim`) compares sRGB-encoded values, extends the image by
reflection and drops the border of 5 px (where the window leaves the image) before averaging, as in Wang's
reference and ``skimage.metrics.structural_similarity(..., gaussian_weights=True, sigma=1.5,
use_sample_covariance=False, data_range=1)``; channels are averaged. The loss (:func:`mean_ssim`) is 3DGS's:
zero padding, the mean over every pixel.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.arrays import float_operands
from pgc.metrics.common import check_images, masked_mean

SIGMA = 1.5
TRUNCATE = 3.5
K1, K2 = 0.01, 0.03
BORDER = int(TRUNCATE * SIGMA + 0.5)  # 5 px: half the 11-tap window
_OFFSETS = np.arange(-BORDER, BORDER + 1)
TAPS = tuple(np.exp(-0.5 / SIGMA ** 2 * _OFFSETS ** 2) / np.exp(-0.5 / SIGMA ** 2 * _OFFSETS ** 2).sum())
"""The normalised 1D Gaussian window (11 weights; scipy's ``gaussian_filter`` weights); the 2D window is
its outer product."""


def ssim_map(x: Any, y: Any, padding: str = "reflect") -> Any:
    """Per-pixel, per-channel SSIM of two (H, W, C) images in [0, 1] (same shape, borders included), in the
    arrays of ``x`` (torch, JAX; anything else float64 numpy). ``padding``: "reflect" (the metric) or "zeros"
    (3DGS's loss)."""
    ops, x = float_operands(x)
    _, y = float_operands(y)
    x, y = ops.transpose(x[None], (0, 3, 1, 2)), ops.transpose(y[None], (0, 3, 1, 2))  # (1, C, H, W) once

    def blur(a: Any) -> Any:
        return ops.separable_filter(a, TAPS, padding)

    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    c1, c2 = K1 ** 2, K2 ** 2
    images = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return ops.transpose(images, (0, 2, 3, 1))[0]


def mean_ssim(x: Any, y: Any) -> Any:
    """The splat fit's SSIM of two (H, W, C) sRGB images: zero padding, mean over every pixel and channel
    (3DGS's loss term; differentiable in torch and JAX)."""
    return ssim_map(x, y, "zeros").mean()


def ssim(pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean SSIM of (H, W, 3) linear images, compared as sRGB; with ``mask`` the mask-weighted mean of the map
    (both cropped by the 5 px border). Images need at least 11 px a side; NaN/Inf are refused."""
    from pgc.io.images import linear_to_srgb

    pred, target = check_images("ssim", pred, target, mask, 2 * BORDER + 1,
                                f"the {2 * BORDER + 1} x {2 * BORDER + 1} px Gaussian window")
    inner = (slice(BORDER, -BORDER), slice(BORDER, -BORDER))
    values = ssim_map(linear_to_srgb(pred), linear_to_srgb(target))[inner]
    return masked_mean(values, None if mask is None else np.asarray(mask)[inner], "ssim")
