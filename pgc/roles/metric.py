"""Role ``metric``: image quality of a prediction against ground truth.

Contract
- ``pred``, ``target``: (H, W, 3) float32 linear RGB in [0, 1] of equal size (else ``PGCDataError``).
  Metrics defined on display values (SSIM, FSIM, LPIPS) convert to sRGB themselves, and say so.
- ``mask`` (H, W) in [0, 1], optional: the metric is restricted to the masked region (a masked mean of the
  per-pixel map, or the image cropped to the mask's bounding box for network metrics; documented per metric).
- ``higher_is_better`` tells the direction.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from pgc.errors import PGCDataError
from pgc.roles._base import RoleImplementation


class Metric(RoleImplementation, ABC):
    role = "metric"
    higher_is_better: ClassVar[bool] = True

    def __call__(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None) -> float:
        pred, target = np.asarray(pred, np.float32), np.asarray(target, np.float32)
        if pred.shape != target.shape:
            raise PGCDataError(f"metric: prediction shape {pred.shape} != target shape {target.shape}")
        if mask is not None and np.asarray(mask).shape != pred.shape[:2]:
            raise PGCDataError(f"metric: mask shape {np.asarray(mask).shape} != image size {pred.shape[:2]}")
        return float(self.compute(pred, target, mask))

    @abstractmethod
    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        """The metric value (validated inputs)."""
