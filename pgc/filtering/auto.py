"""Choosing the low-pass kernel size: in the paper's terms, or automatically from the training frame.

- ``paper``: 71 px at 2668 px image height, scaled (:func:`kernel_size_for_height`).
- ``error`` (the paper's procedure): over candidate sizes, the reconstruction error of the training frame
  ``mean |I - (h(G) + l(S))|`` on the garment. That error keeps falling as the kernel grows (the hybrid tends
  to the 3DGS render), and the paper trades it against generalisation to new poses; so the choice is the
  SMALLEST size that achieves all but ``tolerance`` of the achievable reduction: ``err(k) <= min + tolerance
  * (max - min)``. ``tolerance = 0`` is the plain arg-min.
- ``gradient`` (the paper's proposed future work): blur the training image until the mean gradient
  magnitude on the garment falls to ``gradient_ratio`` times that of the unblurred image (a ratio, so the
  rule does not depend on resolution or exposure); the first candidate size that gets there.
Every rule only calls the ``filter`` role, so it runs on whichever backend is configured.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field

from pgc.errors import PGCDataError
from pgc.filtering.kernel import check_kernel_size, kernel_size_for_height, odd_size
from pgc.options import Options
from pgc.roles.filter import Filter


@dataclass(frozen=True)
class KernelChoice:
    """A chosen kernel size (odd, px) with the score of every candidate tried (criterion's own units)."""

    size: int
    criterion: str
    scores: dict[int, float] = field(default_factory=dict)


class KernelSelection(Options):
    """How the composition stage sets the low-pass kernel (see the module docstring)."""

    mode: Literal["paper", "fixed", "error", "gradient"] = Field("paper", description="rule for the size")
    size: int | None = Field(None, ge=1, description="kernel size in px for mode 'fixed' (odd)")
    sizes: list[int] | None = Field(None, description="candidate sizes (odd px); default: candidate_sizes(H, W)")
    tolerance: float = Field(0.1, ge=0.0, le=1.0, description="mode 'error': allowed share of the error range")
    gradient_ratio: float = Field(0.15, gt=0.0, lt=1.0,
                                  description="mode 'gradient': target mean gradient / unblurred mean gradient")


def candidate_sizes(height: int, width: int, count: int = 10) -> list[int]:
    """``count`` odd sizes, geometric from 3 px to half the smaller image side, plus the paper's size."""
    largest = max(3, odd_size(min(height, width) / 2))
    sizes = {odd_size(s) for s in np.geomspace(3, largest, count)}
    sizes.add(min(kernel_size_for_height(height), largest))
    return sorted(sizes)


def _garment_mean(values: np.ndarray, mask: np.ndarray) -> float:
    weight = mask.sum()
    if weight <= 0:
        raise PGCDataError("kernel choice: the garment mask is empty; nothing to measure the kernel on")
    return float((values * mask).sum() / weight)


def _mask(mask: np.ndarray | None, alpha: np.ndarray) -> np.ndarray:
    mask = (np.asarray(alpha) > 0.5) if mask is None else np.asarray(mask)
    if mask.shape != np.asarray(alpha).shape:
        raise PGCDataError(f"kernel choice: mask shape {mask.shape} != image size {np.asarray(alpha).shape}")
    return mask.astype(np.float64)


def _sizes(sizes: list[int] | None, shape: tuple[int, ...]) -> list[int]:
    sizes = candidate_sizes(shape[0], shape[1]) if sizes is None else sorted({check_kernel_size(s) for s in sizes})
    if not sizes:
        raise PGCDataError("kernel choice: no candidate sizes given")
    return sizes


def hybrid_error(filt: Filter, image: np.ndarray, gaussians: np.ndarray, gaussians_alpha: np.ndarray,
                 far: np.ndarray, far_alpha: np.ndarray, mask: np.ndarray, kernel_size: int) -> float:
    """``mean |I - (h(G) + l(S))|`` over ``mask`` (H, W) and channels: the error rule's score of one size."""
    hybrid = filt.highpass(gaussians, gaussians_alpha, kernel_size) + filt.lowpass(far, far_alpha, kernel_size)
    return _garment_mean(np.abs(np.asarray(image, np.float32) - hybrid), np.asarray(mask, np.float64)[..., None]
                         ) / np.asarray(image).shape[2]


def choose_kernel_by_error(filt: Filter, image: np.ndarray, gaussians: np.ndarray, gaussians_alpha: np.ndarray,
                           pbr: np.ndarray, pbr_alpha: np.ndarray, mask: np.ndarray | None = None,
                           sizes: list[int] | None = None, tolerance: float = 0.1) -> KernelChoice:
    """The smallest size whose training-frame error ``mean |I - (h(G) + l(S))|`` on ``mask`` is within
    ``tolerance`` of the error range above the minimum. Images (H, W, 3) linear, alphas and mask (H, W);
    the mask defaults to ``gaussians_alpha > 0.5``. Scores: mean absolute error per candidate size.
    """
    image, gaussians, pbr = (np.asarray(x, np.float32) for x in (image, gaussians, pbr))
    if not image.shape == gaussians.shape == pbr.shape:
        raise PGCDataError(f"kernel choice: image {image.shape}, 3DGS render {gaussians.shape} and PBR render "
                           f"{pbr.shape} must have the same shape")
    weights = _mask(mask, gaussians_alpha)
    scores = {k: hybrid_error(filt, image, gaussians, gaussians_alpha, pbr, pbr_alpha, weights, k)
              for k in _sizes(sizes, image.shape)}
    low, high = min(scores.values()), max(scores.values())
    size = min(k for k, e in scores.items() if e <= low + tolerance * (high - low))
    return KernelChoice(size, "error", scores)


def gradient_magnitude(image: np.ndarray) -> np.ndarray:
    """Per-pixel gradient magnitude (central differences, summed over channels in quadrature), (H, W)."""
    gy, gx = np.gradient(np.asarray(image, np.float64), axis=(0, 1))
    return np.sqrt((gx ** 2 + gy ** 2).sum(axis=-1))


def choose_kernel_by_gradient(filt: Filter, image: np.ndarray, alpha: np.ndarray, mask: np.ndarray | None = None,
                              sizes: list[int] | None = None, gradient_ratio: float = 0.15) -> KernelChoice:
    """The first candidate size whose low-pass has a mean gradient magnitude on the garment interior (the mask
    eroded by one pixel, so the silhouette does not count) at most ``gradient_ratio`` times the unblurred
    image's; the largest candidate if none gets there. Scores: the ratio per size tried.
    """
    from scipy.ndimage import binary_erosion

    image = np.asarray(image, np.float32)
    interior = binary_erosion(_mask(mask, alpha) > 0.5).astype(np.float64)
    if interior.sum() == 0:
        raise PGCDataError("kernel choice: the garment mask has no interior pixels (too thin or empty)")
    base = _garment_mean(gradient_magnitude(image), interior)
    scores: dict[int, float] = {}
    sizes = _sizes(sizes, image.shape)
    if base <= 0:  # a flat garment: nothing to remove, the smallest kernel does
        return KernelChoice(sizes[0], "gradient", {sizes[0]: 0.0})
    for k in sizes:
        scores[k] = _garment_mean(gradient_magnitude(filt.lowpass(image, alpha, k)), interior) / base
        if scores[k] <= gradient_ratio:
            return KernelChoice(k, "gradient", scores)
    return KernelChoice(sizes[-1], "gradient", scores)


def select_kernel(selection: KernelSelection, filt: Filter, image: np.ndarray, alpha: np.ndarray,
                  gaussians: np.ndarray | None = None, pbr: np.ndarray | None = None,
                  pbr_alpha: np.ndarray | None = None, mask: np.ndarray | None = None) -> KernelChoice:
    """Apply ``selection`` to a training frame: ``image`` (H, W, 3) with the 3DGS ``alpha``; the error rule
    also needs the 3DGS render ``gaussians`` and the PBR render ``pbr`` with its ``pbr_alpha``."""
    height = np.asarray(image).shape[0]
    if selection.mode == "paper":
        return KernelChoice(kernel_size_for_height(height), "paper")
    if selection.mode == "fixed":
        if selection.size is None:
            raise PGCDataError("kernel selection: mode 'fixed' needs 'size' (odd, px)")
        return KernelChoice(check_kernel_size(selection.size), "fixed")
    if selection.mode == "gradient":
        return choose_kernel_by_gradient(filt, image, alpha, mask, selection.sizes, selection.gradient_ratio)
    if gaussians is None or pbr is None or pbr_alpha is None:
        raise PGCDataError("kernel selection: mode 'error' needs the 3DGS render and the PBR render with its alpha")
    return choose_kernel_by_error(filt, image, gaussians, alpha, pbr, pbr_alpha, mask, selection.sizes,
                                  selection.tolerance)
