"""The Gaussian kernel of the alpha-aware low-pass, in the paper's terms, and input checks shared by backends.

Conventions (the ``filter`` role contract, pgc/roles/filter.py): ``kernel_size`` is odd, in pixels, the
kernel covers ``kernel_size`` taps (radius ``kernel_size // 2``) with ``sigma = kernel_size / 6``. The paper
uses a 71x71 kernel on 4096x2668 images (width x height), so sizes scale with the image height from
71 px at 2668 px.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.roles.filter import DENOMINATOR_EPS

PAPER_KERNEL_SIZE = 71
"""Kernel size (px) the paper uses on its training images."""
PAPER_IMAGE_HEIGHT = 2668
"""Height (px) of the paper's 4096x2668 (width x height) images."""


def odd_size(value: float) -> int:
    """The odd integer nearest to ``value`` (at least 1; halves round up)."""
    return max(1, 2 * int(np.floor((float(value) - 1.0) / 2.0 + 0.5)) + 1)


def kernel_size_for_height(height: int) -> int:
    """The paper's kernel (71 px at 2668 px height) scaled to an image of ``height`` px; odd, at least 3."""
    if height <= 0:
        raise PGCDataError(f"kernel_size_for_height: image height must be positive, got {height}")
    return max(3, odd_size(PAPER_KERNEL_SIZE * height / PAPER_IMAGE_HEIGHT))


def check_kernel_size(kernel_size: int) -> int:
    """``kernel_size`` as an int, or a PGCDataError if it is not a positive odd integer."""
    if isinstance(kernel_size, bool) or int(kernel_size) != kernel_size or kernel_size < 1 or kernel_size % 2 == 0:
        raise PGCDataError(f"filter: kernel_size must be a positive odd integer (pixels), got {kernel_size!r}; "
                           "use pgc.filtering.odd_size(x) to round a size")
    return int(kernel_size)


def gaussian_kernel_1d(kernel_size: int) -> np.ndarray:
    """Normalised 1-D Gaussian taps (float64, length ``kernel_size``, sigma = kernel_size / 6)."""
    kernel_size = check_kernel_size(kernel_size)
    radius = kernel_size // 2
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    taps = np.exp(-0.5 * (x / (kernel_size / 6.0)) ** 2)
    return taps / taps.sum()


def check_filter_inputs(image: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate the role's inputs: ``image`` (H, W, C) and ``alpha`` (H, W), finite; returned as float32."""
    image = np.asarray(image, dtype=np.float32)
    alpha = np.asarray(alpha, dtype=np.float32)
    if image.ndim != 3:
        raise PGCDataError(f"filter: image must be (H, W, C), got shape {image.shape}")
    if alpha.shape != image.shape[:2]:
        raise PGCDataError(f"filter: alpha shape {alpha.shape} must equal the image size {image.shape[:2]}")
    if not (np.isfinite(image).all() and np.isfinite(alpha).all()):
        raise PGCDataError("filter: image or alpha contains NaN or Inf")
    if alpha.size and (alpha.min() < -1e-6 or alpha.max() > 1 + 1e-6):
        raise PGCDataError(f"filter: alpha must lie in [0, 1], got [{alpha.min()}, {alpha.max()}]")
    return image, np.clip(alpha, 0.0, 1.0)


def renormalise(numerator: Any, denominator: Any, image: Any) -> Any:
    """``numerator / denominator`` (the alpha-weighted blur over the blurred alpha), defined where alpha vanishes.

    With ``gap = max(eps - denominator, 0)`` (eps = 1e-6) the result is ``(numerator + gap * image) /
    (denominator + gap)``: exactly the weighted mean where the denominator is at least eps, exactly ``image``
    where it is 0, and continuous in between (so backends whose sums differ in the last bit cannot jump
    between the two). Written with arithmetic and ``abs`` only, so numpy, torch and JAX arrays all work;
    ``denominator`` broadcasts against ``numerator`` (e.g. (H, W, 1) against (H, W, C)).
    """
    short = DENOMINATOR_EPS - denominator
    gap = (abs(short) + short) * 0.5
    return (numerator + gap * image) / (denominator + gap)


def box_widths(kernel_size: int, boxes: int = 3) -> list[int]:
    """Odd widths of ``boxes`` successive box filters whose combined variance best matches the Gaussian of
    ``kernel_size`` (sigma = kernel_size / 6): Kovesi's "fast almost-Gaussian filtering" (2010). A cascade of
    boxes costs O(1) per pixel whatever the size (running sums)."""
    sigma2 = (check_kernel_size(kernel_size) / 6.0) ** 2
    lower = int(np.floor(np.sqrt(12.0 * sigma2 / boxes + 1.0)))
    lower -= 1 - lower % 2  # odd
    lower = max(lower, 1)
    n_lower = int(round((12.0 * sigma2 - boxes * lower ** 2 - 4 * boxes * lower - 3 * boxes) / (-4.0 * lower - 4.0)))
    n_lower = min(max(n_lower, 0), boxes)
    return [lower] * n_lower + [lower + 2] * (boxes - n_lower)
