"""Role ``metric``: image quality of a prediction against ground truth.

Contract
- ``pred``, ``target``: (H, W, 3) float32 linear RGB in [0, 1] of equal size (else ``PGCDataError``).
  Metrics defined on display values (SSIM, FSIM, LPIPS) convert to sRGB themselves, and say so.
- ``mask`` (H, W) in [0, 1], optional: the metric is restricted to the masked region (a masked mean of the
  per-pixel map, or the image cropped to the mask's bounding box for network metrics; documented per metric).
- ``higher_is_better`` tells the direction.
- Inputs are checked before any implementation runs (:meth:`Metric.__call__` with
  :func:`pgc.metrics.common.check_images`): NaN/Inf in ``pred``, ``target`` or ``mask``, mismatched shapes and
  images smaller than :meth:`Metric.min_image_size` raise :class:`pgc.errors.PGCDataError`; no metric returns
  NaN for them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from pgc.roles._base import RoleImplementation


class Metric(RoleImplementation, ABC):
    role = "metric"
    higher_is_better: ClassVar[bool] = True
    name: ClassVar[str] = ""
    """The metric's name in error messages (default: ``metric CLASSNAME``)."""

    def __call__(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None) -> float:
        """The metric of ``pred`` against ``target`` (optionally within ``mask``), after the role's checks."""
        from pgc.metrics.common import check_images

        minimum, why = self.min_image_size(mask is not None)
        pred, target = check_images(self.name or f"metric {type(self).__name__}", pred, target, mask, minimum, why)
        pred, target = np.asarray(pred, np.float32), np.asarray(target, np.float32)
        return float(self.compute(pred, target, mask))

    def min_image_size(self, masked: bool) -> tuple[int, str]:
        """The smallest image side (px) this metric measures (with a mask when ``masked``), and why."""
        return 1, "one pixel"

    @abstractmethod
    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        """The metric value (validated inputs)."""
