"""Role ``filter``: the alpha-aware low-pass of the hybrid composition (docs/method.md, section 5).

Contract
- ``lowpass(image, alpha, kernel_size)``: Gaussian blur whose kernel is multiplied by ``alpha`` and
  renormalised per pixel: ``l(I)(p) = sum_q G(p - q) a(q) I(q) / sum_q G(p - q) a(q)``, so background does
  not bleed into the garment. ``kernel_size`` is odd, in pixels, with ``sigma = kernel_size / 6``; the
  image border is handled by clamping the kernel to the image (renormalised like alpha). Where the
  blurred alpha ``d`` is below 1e-6 the result blends continuously toward ``image``:
  ``(num + (1e-6 - d) image) / 1e-6``, exactly ``image`` at d = 0, finite everywhere (continuous, so
  backends whose sums differ in the last bit cannot jump between two answers).
- ``image`` (H, W, C) float32, ``alpha`` (H, W) in [0, 1]; output (H, W, C) float32.
- ``highpass = image - lowpass`` (so high + low is the identity).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from pgc.roles._base import RoleImplementation

DENOMINATOR_EPS = 1e-6


class Filter(RoleImplementation, ABC):
    role = "filter"

    @abstractmethod
    def lowpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        """Alpha-aware low-pass of ``image``."""

    def highpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        return np.asarray(image, dtype=np.float32) - self.lowpass(image, alpha, kernel_size)
