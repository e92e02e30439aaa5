"""Role ``albedo_estimator``: per-view albedo (base colour) prediction.

Contract
- Input: ``image`` (H, W, 3) float32 linear RGB; optional ``mask`` (H, W) in [0, 1] of the region of
  interest; optional ``shading`` (H, W, 3), the irradiance-like shading a white-albedo surface receives
  (estimators that need it raise ``PGCDataError`` when it is missing).
- Output: (H, W, 3) float32 linear albedo in [0, 1], finite everywhere; values outside ``mask`` unspecified.
- Albedo is defined up to a global scale; consumers fit it (colour correction).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from pgc.roles._base import RoleImplementation


class AlbedoEstimator(RoleImplementation, ABC):
    role = "albedo_estimator"
    needs_shading: bool = False
    """True when :meth:`estimate` requires the ``shading`` image (the pipeline then renders it)."""
    fingerprint: str | None = None
    """A content hash of external state the results depend on (e.g. a model file), for cache keys."""

    @abstractmethod
    def estimate(self, image: np.ndarray, mask: np.ndarray | None = None,
                 shading: np.ndarray | None = None) -> np.ndarray:
        """Albedo of ``image``."""
