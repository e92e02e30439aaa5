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
- ``metric``: scores the hybrid ``h(G) + l(S)`` of every size under a ``metric`` plugin (LPIPS by default)
  against the captured image on the garment, averaged over the frame's views (the pipeline gives it views the
  splat fit held out), and takes the smallest size within ``tolerance`` of the score range from the best, as
  ``error`` does. The mean absolute error of ``error`` cannot tell a kernel that keeps the near field's fine
  detail from one that blurs it: on the knit scene its scores at 5 and 9 px differ by less than its
  tolerance, while LPIPS of the novel poses is 4 % better at 9 px. The tolerance keeps the kernel from
  growing for the last few per cent of the score: a larger kernel hands the near field more of the image
  and costs FSIM and PSNR where its low band is weaker than the PBR render's.
Every rule only calls the ``filter`` role (and ``metric`` a metric plugin), so it runs on whichever backend
is configured.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from pgc.errors import PGCDataError
from pgc.filtering.detail import hybrid_colour
from pgc.filtering.kernel import check_kernel_size, kernel_size_for_height, odd_size
from pgc.options import Options, _check_integer, count
from pgc.roles.filter import Filter
from pgc.roles.metric import Metric


@dataclass(frozen=True)
class KernelChoice:
    """A chosen kernel size (odd, px) with the score of every candidate tried (criterion's own units)."""

    size: int
    criterion: str
    scores: dict[int, float] = field(default_factory=dict)


@dataclass(frozen=True)
class TrainingFrame:
    """One view of the training frame as the kernel rules see it. Images (H, W, 3) linear RGB un-premultiplied,
    alphas and mask (H, W) in [0, 1]; the mask (garment coverage) defaults to ``near_alpha > 0.5``."""

    image: np.ndarray
    """The captured image."""
    near: np.ndarray
    """The near field: the Gaussians' render G."""
    near_alpha: np.ndarray
    far: np.ndarray | None = None
    """The far field S (the error rule needs it)."""
    far_alpha: np.ndarray | None = None
    mask: np.ndarray | None = None

    def weights(self) -> np.ndarray:
        """(H, W) float64 garment weights: the mask, or ``near_alpha > 0.5`` without one."""
        return _mask(self.mask, self.near_alpha)


MAX_KERNEL_SIZE = 4095
"""Largest low-pass kernel (px) a setting may ask for (the paper's 71 px at 2668 px scales to 437 px at 16384)."""


class KernelSelection(Options):
    """How the composition stage sets the low-pass kernel (see the module docstring)."""

    mode: Literal["paper", "fixed", "error", "gradient", "metric"] = Field("paper", description="rule for the size")
    size: int | None = count(None, 1, MAX_KERNEL_SIZE, "kernel size in px for mode 'fixed' (odd)")
    sizes: list[int] | None = Field(None, description=(
        f"candidate sizes (odd px); default: candidate_sizes(H, W); each an integer in [1, {MAX_KERNEL_SIZE}]"))
    tolerance: float = Field(0.1, ge=0.0, le=1.0, description="modes 'error' and 'metric': the smallest size whose "
                             "score is within this share of the score range from the best")
    gradient_ratio: float = Field(0.15, gt=0.0, lt=1.0,
                                  description="mode 'gradient': target mean gradient / unblurred mean gradient")
    metric: str = Field("lpips", description="mode 'metric': the metric plugin that scores each size")

    @field_validator("sizes", mode="before")
    @classmethod
    def _sizes_in_range(cls, value: object) -> object:
        """Every candidate size in [1, MAX_KERNEL_SIZE] (a list field declares no range of its own)."""
        if isinstance(value, (list, tuple)):
            for item in value:
                _check_integer(item, 1, MAX_KERNEL_SIZE, "every item: ")
        return value


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


def hybrid_image(filt: Filter, frame: TrainingFrame, kernel_size: int, detail: str = "additive") -> np.ndarray:
    """The hybrid ``h(G) + l(S)`` of one frame at one kernel size (``detail``: :mod:`pgc.filtering.detail`),
    (H, W, 3) float32."""
    near, far = np.asarray(frame.near, np.float32), np.asarray(frame.far, np.float32)
    low_near = filt.lowpass(near, frame.near_alpha, kernel_size)
    low_far = filt.lowpass(far, frame.far_alpha, kernel_size)
    return hybrid_colour(near - low_near, low_near, low_far, detail, high_far=far - low_far)


def hybrid_error(filt: Filter, frame: TrainingFrame, kernel_size: int, detail: str = "additive") -> float:
    """``mean |I - (h(G) + l(S))|`` over the frame's garment weights and channels: the error rule's score of one
    kernel size."""
    image = np.asarray(frame.image, np.float32)
    hybrid = hybrid_image(filt, frame, kernel_size, detail)
    return _garment_mean(np.abs(image - hybrid), frame.weights()[..., None]) / image.shape[2]


def _check_far(frame: TrainingFrame, rule: str) -> None:
    if frame.far is None or frame.far_alpha is None:
        raise PGCDataError(f"kernel selection: mode '{rule}' needs the far-field render and its alpha")
    shapes = [np.shape(x) for x in (frame.image, frame.near, frame.far)]
    if not shapes[0] == shapes[1] == shapes[2]:
        raise PGCDataError(f"kernel choice: image {shapes[0]}, near-field render {shapes[1]} and far-field render "
                           f"{shapes[2]} must have the same shape")


def hybrid_score(filt: Filter, frames: list[TrainingFrame], kernel_size: int, metric: Metric,
                 detail: str = "additive") -> float:
    """Mean of ``metric`` over ``frames`` of the hybrid at ``kernel_size`` against the captured image, both
    on black outside the garment weights, restricted to them (the evaluation's convention)."""
    values = []
    for frame in frames:
        weights = frame.weights()
        hybrid = np.clip(hybrid_image(filt, frame, kernel_size, detail), 0.0, 1.0) * weights[..., None]
        image = np.clip(np.asarray(frame.image, np.float32), 0.0, 1.0) * weights[..., None]
        values.append(metric(hybrid, image, weights))
    return float(np.mean(values))


def smallest_within(scores: dict[int, float], tolerance: float, higher_is_better: bool = False) -> int:
    """The smallest size whose score is within ``tolerance`` of the score range from the best one
    (``tolerance = 0``: the best score, ties to the smaller size)."""
    values = np.array(list(scores.values()), np.float64)
    loss = -values if higher_is_better else values
    low, high = float(loss.min()), float(loss.max())
    span = high - low
    limit = low + tolerance * span if np.isfinite(span) else low  # an infinite score (PSNR of equal images) wins
    return min(k for k, e in zip(scores, loss) if e <= limit)


def choose_kernel_by_metric(filt: Filter, frames: list[TrainingFrame], metric: Metric, name: str,
                            sizes: list[int] | None = None, tolerance: float = 0.0,
                            detail: str = "additive") -> KernelChoice:
    """The smallest candidate size whose hybrid score under ``metric`` (:func:`hybrid_score`, over ``frames``,
    composed with ``detail``) is within ``tolerance`` of the score range from the best (0: the best score).
    ``name`` labels the criterion. Scores: the metric's value per candidate size."""
    if not frames:
        raise PGCDataError("kernel choice: mode 'metric' needs at least one view")
    for frame in frames:
        _check_far(frame, "metric")
    scores = {k: hybrid_score(filt, frames, k, metric, detail) for k in _sizes(sizes, np.shape(frames[0].image))}
    return KernelChoice(smallest_within(scores, tolerance, metric.higher_is_better), f"metric:{name}", scores)


def choose_kernel_by_error(filt: Filter, frame: TrainingFrame, sizes: list[int] | None = None,
                           tolerance: float = 0.1, detail: str = "additive") -> KernelChoice:
    """The smallest size whose training-frame error ``mean |I - (h(G) + l(S))|`` (:func:`hybrid_error`, composed
    with ``detail``) is within ``tolerance`` of the error range above the minimum. Scores: mean absolute error per
    candidate size."""
    _check_far(frame, "error")
    scores = {k: hybrid_error(filt, frame, k, detail) for k in _sizes(sizes, np.shape(frame.image))}
    return KernelChoice(smallest_within(scores, tolerance), "error", scores)


def gradient_magnitude(image: np.ndarray) -> np.ndarray:
    """Per-pixel gradient magnitude (central differences, summed over channels in quadrature), (H, W)."""
    gy, gx = np.gradient(np.asarray(image, np.float64), axis=(0, 1))
    return np.sqrt((gx ** 2 + gy ** 2).sum(axis=-1))


def choose_kernel_by_gradient(filt: Filter, frame: TrainingFrame, sizes: list[int] | None = None,
                              gradient_ratio: float = 0.15) -> KernelChoice:
    """The first candidate size whose low-pass of the captured image has a mean gradient magnitude on the garment
    interior (the weights eroded by one pixel, so the silhouette does not count) at most ``gradient_ratio`` times
    the unblurred image's; the largest candidate if none gets there. Scores: the ratio per size tried.
    """
    from scipy.ndimage import binary_erosion

    image, alpha = np.asarray(frame.image, np.float32), frame.near_alpha
    interior = binary_erosion(frame.weights() > 0.5).astype(np.float64)
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


def select_kernel(selection: KernelSelection, filt: Filter, frame: TrainingFrame,
                  detail: str = "additive") -> KernelChoice:
    """Apply ``selection`` to one view of the training frame, the hybrid composed with ``detail`` (mode 'metric'
    scores several views at once: :func:`choose_kernel_by_metric`)."""
    height = np.asarray(frame.image).shape[0]
    if selection.mode == "paper":
        return KernelChoice(kernel_size_for_height(height), "paper")
    if selection.mode == "fixed":
        if selection.size is None:
            raise PGCDataError("kernel selection: mode 'fixed' needs 'size' (odd, px)")
        return KernelChoice(check_kernel_size(selection.size), "fixed")
    if selection.mode == "gradient":
        return choose_kernel_by_gradient(filt, frame, selection.sizes, selection.gradient_ratio)
    if selection.mode == "metric":
        raise PGCDataError("kernel selection: mode 'metric' scores several views with a metric plugin; "
                           "use choose_kernel_by_metric")
    return choose_kernel_by_error(filt, frame, selection.sizes, selection.tolerance, detail)
