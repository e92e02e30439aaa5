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
from pgc.roles.filter import DENOMINATOR_EPS, check_filter_inputs, check_kernel_size  # noqa: F401 (re-exported)

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


def gaussian_kernel_1d(kernel_size: int) -> np.ndarray:
    """Normalised 1-D Gaussian taps (float64, length ``kernel_size``, sigma = kernel_size / 6)."""
    kernel_size = check_kernel_size(kernel_size)
    radius = kernel_size // 2
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    taps = np.exp(-0.5 * (x / (kernel_size / 6.0)) ** 2)
    return taps / taps.sum()


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
