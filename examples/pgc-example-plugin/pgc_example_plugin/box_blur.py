"""A separable box blur obeying the ``filter`` role contract (see ``pgc/roles/filter.py``).

The low-pass is ``l(I)(p) = sum_q B(p - q) a(q) I(q) / sum_q B(p - q) a(q)`` with ``B`` a box of
``kernel_size`` x ``kernel_size`` pixels (instead of the role's Gaussian), so the background does not
bleed into the foreground. Pixels outside the image count as alpha 0 (the kernel is clamped to the
image and renormalised). Where the denominator is below ``DENOMINATOR_EPS`` the result is the input.
Each pass costs O(1) per pixel whatever the kernel size (running sums). With several passes, numerator and
denominator are each blurred ``passes`` times, zero outside the image after every pass.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from pgc.errors import PGCDataError
from pgc.options import Options
from pgc.roles.filter import DENOMINATOR_EPS, Filter


class BoxBlurOptions(Options):
    passes: int = Field(1, ge=1, le=8, description="box passes: n passes of a k-pixel box have variance "
                                                   "n (k^2 - 1) / 12 and tend to a Gaussian")


def box_sum(x: np.ndarray, radius: int, axis: int) -> np.ndarray:
    """Sum of ``x`` over a window of ``2 radius + 1`` samples along ``axis``, zero outside (float64)."""
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    n = x.shape[0]
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
    idx = np.arange(n)
    hi = np.minimum(idx + radius + 1, n)
    lo = np.maximum(idx - radius, 0)
    return np.moveaxis(c[hi] - c[lo], 0, axis)


class BoxBlurFilter(Filter):
    """Alpha-aware box low-pass; ``highpass`` comes from the role (image - lowpass)."""

    Options = BoxBlurOptions

    def lowpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        image = np.asarray(image, dtype=np.float32)
        alpha = np.asarray(alpha, dtype=np.float32)
        if image.ndim != 3 or alpha.shape != image.shape[:2]:
            raise PGCDataError(f"box filter: image (H, W, C) and alpha (H, W) expected, got {image.shape} and "
                               f"{alpha.shape}")
        if kernel_size < 1 or kernel_size % 2 == 0:
            raise PGCDataError(f"box filter: kernel_size must be a positive odd number, got {kernel_size}")
        radius = kernel_size // 2
        a = np.clip(alpha.astype(np.float64), 0.0, 1.0)
        num = image.astype(np.float64) * a[..., None]
        den = a
        for _ in range(self.options.passes):
            num = box_sum(box_sum(num, radius, 0), radius, 1)
            den = box_sum(box_sum(den, radius, 0), radius, 1)
        ok = den > DENOMINATOR_EPS * (kernel_size * kernel_size) ** self.options.passes
        out = np.where(ok[..., None], num / np.where(ok, den, 1.0)[..., None], image)
        return out.astype(np.float32)
