"""SSIM (Wang et al. 2004) with the standard settings, on sRGB-encoded values.

Gaussian window sigma 1.5 truncated at 3.5 sigma (11 taps), K1 = 0.01, K2 = 0.03, data range 1, population
(co)variances; the map is computed per channel and its border of 5 px (where the window leaves the image) is
dropped before averaging, as in Wang's reference and ``skimage.metrics.structural_similarity(...,
gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1)``; channels are averaged.
"""

from __future__ import annotations

import numpy as np

from pgc.metrics.common import check_images, masked_mean

SIGMA = 1.5
TRUNCATE = 3.5
K1, K2 = 0.01, 0.03
BORDER = int(TRUNCATE * SIGMA + 0.5)  # 5 px: half the 11-tap window


def ssim_map(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per-pixel, per-channel SSIM of two (H, W, C) images in [0, 1] (float64, same shape, borders included)."""
    from scipy.ndimage import gaussian_filter

    def blur(a: np.ndarray) -> np.ndarray:
        return gaussian_filter(a, sigma=(SIGMA, SIGMA, 0), truncate=TRUNCATE, mode="reflect")

    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    c1, c2 = K1 ** 2, K2 ** 2
    return ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))


def ssim(pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean SSIM of (H, W, 3) linear images, compared as sRGB; with ``mask`` the mask-weighted mean of the map
    (both cropped by the 5 px border). Images need at least 11 px a side; NaN/Inf are refused."""
    from pgc.io.images import linear_to_srgb

    pred, target = check_images("ssim", pred, target, mask, 2 * BORDER + 1,
                                f"the {2 * BORDER + 1} x {2 * BORDER + 1} px Gaussian window")
    inner = (slice(BORDER, -BORDER), slice(BORDER, -BORDER))
    values = ssim_map(linear_to_srgb(pred), linear_to_srgb(target))[inner]
    return masked_mean(values, None if mask is None else np.asarray(mask)[inner], "ssim")
