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
- Inputs are checked before any implementation runs (every subclass's ``lowpass`` is wrapped): ``image`` and
  ``alpha`` of the shapes above, finite, alpha in [0, 1], ``kernel_size`` a positive odd integer, else
  :class:`pgc.errors.PGCDataError` naming the array and the count (:func:`check_filter_inputs`).
"""

from __future__ import annotations

import math
import numbers
from abc import ABC, abstractmethod
from typing import Any, Callable

import numpy as np

from pgc.checks import require_finite
from pgc.errors import PGCDataError
from pgc.roles._base import RoleImplementation

DENOMINATOR_EPS = 1e-6


def check_kernel_size(kernel_size: int) -> int:
    """``kernel_size`` as an int, or a PGCDataError if it is not a positive odd integer."""
    whole = isinstance(kernel_size, numbers.Real) and not isinstance(kernel_size, (bool, np.bool_)) \
        and math.isfinite(kernel_size) and float(kernel_size).is_integer()
    if not whole or kernel_size < 1 or int(kernel_size) % 2 == 0:
        raise PGCDataError(f"filter: kernel_size must be a positive odd integer (pixels), got {kernel_size!r}; "
                           "use pgc.filtering.odd_size(x) to round a size")
    return int(kernel_size)


def check_filter_inputs(image: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate the role's inputs: ``image`` (H, W, C) and ``alpha`` (H, W), finite; returned as float32.

    NaN/Inf are refused (naming the array and the count) rather than given a mask semantics: a blur spreads one
    NaN over its whole kernel (a box filter's running sums over the rest of the row)."""
    image = np.asarray(image, dtype=np.float32)
    alpha = np.asarray(alpha, dtype=np.float32)
    if image.ndim != 3:
        raise PGCDataError(f"filter: image must be (H, W, C), got shape {image.shape}")
    if alpha.shape != image.shape[:2]:
        raise PGCDataError(f"filter: alpha shape {alpha.shape} must equal the image size {image.shape[:2]}")
    require_finite("filter", "image", image)
    require_finite("filter", "alpha", alpha)
    if alpha.size and (alpha.min() < -1e-6 or alpha.max() > 1 + 1e-6):
        raise PGCDataError(f"filter: alpha must lie in [0, 1], got [{alpha.min()}, {alpha.max()}]")
    return image, np.clip(alpha, 0.0, 1.0)


def _checked(lowpass: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
    """``lowpass`` given the inputs as (:func:`check_filter_inputs` and
    :func:`pgc.filtering.kernel.check_kernel_size` return them (float32, alpha clipped to [0, 1])."""

    def checked(self: "Filter", image: np.ndarray, alpha: np.ndarray, kernel_size: int, *args: Any,
                **kwargs: Any) -> np.ndarray:
        image, alpha = check_filter_inputs(image, alpha)
        return lowpass(self, image, alpha, check_kernel_size(kernel_size), *args, **kwargs)

    return checked


class Filter(RoleImplementation, ABC):
    role = "filter"
    input_checks = {"lowpass": _checked}
    """Every implementation's ``lowpass`` checks its inputs first (see the contract)."""

    @abstractmethod
    def lowpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        """Alpha-aware low-pass of ``image``."""

    def highpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        return np.asarray(image, dtype=np.float32) - self.lowpass(image, alpha, kernel_size)
