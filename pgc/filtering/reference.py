"""Float64 numpy references of the alpha-aware low-pass: the test oracle and the benchmark's baseline.

``lowpass_direct`` is the obviously-correct O(k^2)-per-pixel 2-D sum of the contract; ``lowpass_separable``
is the same in two 1-D passes (exact, since the Gaussian and the zero border both factor over x and y).
"""

from __future__ import annotations

import numpy as np

from pgc.filtering.kernel import check_filter_inputs, gaussian_kernel_1d, renormalise


def _weighted(image: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(H, W, C + 1) float64 stack of ``alpha * image`` and ``alpha``: blurred together, divided after."""
    a = alpha.astype(np.float64)[..., None]
    return np.concatenate([a * image.astype(np.float64), a], axis=-1)


def lowpass_direct(image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
    """Alpha-aware low-pass by the direct 2-D sum over the k x k window (float64 result)."""
    image, alpha = check_filter_inputs(image, alpha)
    taps = gaussian_kernel_1d(kernel_size)
    kernel2d = np.outer(taps, taps)
    r = kernel_size // 2
    h, w, _ = image.shape
    padded = np.pad(_weighted(image, alpha), ((r, r), (r, r), (0, 0)))
    acc = np.zeros((h, w, image.shape[2] + 1))
    for dy in range(kernel_size):
        for dx in range(kernel_size):
            acc += kernel2d[dy, dx] * padded[dy:dy + h, dx:dx + w]
    return renormalise(acc[..., :-1], acc[..., -1:], image.astype(np.float64))


def lowpass_separable(image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
    """Alpha-aware low-pass in two 1-D passes with zero borders (float64 result)."""
    from scipy.ndimage import correlate1d

    image, alpha = check_filter_inputs(image, alpha)
    taps = gaussian_kernel_1d(kernel_size)
    acc = _weighted(image, alpha)
    for axis in (0, 1):
        acc = correlate1d(acc, taps, axis=axis, mode="constant", cval=0.0)
    return renormalise(acc[..., :-1], acc[..., -1:], image.astype(np.float64))
