"""Alpha-aware low-pass with OpenCV: the exact separable Gaussian (``cv2.sepFilter2D``) or, with
``method = "box3"``, an O(1)-per-pixel almost-Gaussian cascade of three box filters of the same sigma
(``cv2.boxFilter``); both with a zero border and the role's renormalisation."""

from __future__ import annotations

import cv2
import numpy as np

from pgc.filtering.kernel import box_widths, gaussian_kernel_1d, renormalise
from pgc.roles.filter import Filter
from pgc_opencv.specs_filter import OpenCVFilterOptions

_MAX_CHANNELS = 4
"""Channels blurred per OpenCV call (its filters take at most 4 interleaved channels)."""


class OpenCVFilter(Filter):
    """``filter`` 'opencv': float32, ``BORDER_CONSTANT`` (zeros), exact Gaussian or 3-box approximation."""

    Options = OpenCVFilterOptions

    def _blur(self, stack: np.ndarray, kernel_size: int) -> np.ndarray:
        if self.options.method == "box3":
            for width in box_widths(kernel_size):
                if width > 1:
                    stack = cv2.boxFilter(stack, -1, (width, width), normalize=True, borderType=cv2.BORDER_CONSTANT)
            return stack
        taps = gaussian_kernel_1d(kernel_size).astype(np.float32)
        return cv2.sepFilter2D(stack, cv2.CV_32F, taps, taps, borderType=cv2.BORDER_CONSTANT)

    def lowpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        stack = np.concatenate([image * alpha[..., None], alpha[..., None]], axis=-1)
        blurred = np.concatenate([
            self._blur(np.ascontiguousarray(stack[..., c:c + _MAX_CHANNELS]), kernel_size).reshape(*stack.shape[:2], -1)
            for c in range(0, stack.shape[-1], _MAX_CHANNELS)], axis=-1)
        return renormalise(blurred[..., :-1], blurred[..., -1:], image).astype(np.float32, copy=False)
