"""The model-free baseline albedo estimator: image / shading, safe where the shading vanishes."""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError
from pgc.options import Options
from pgc.roles.albedo_estimator import AlbedoEstimator


class ShadingRatioOptions(Options):
    min_shading: float = 0.02
    """Shading below this (relative to the 99th percentile of the shading) is unreliable: such pixels
    take the image divided by the clamped shading and are marked by a reduced confidence downstream."""
    max_albedo: float = 1.0
    """Albedo is physically at most 1 per channel; results are clipped to [0, max_albedo]."""


class ShadingRatioEstimator(AlbedoEstimator):
    """albedo = image / shading, where ``shading`` is the render of the mesh with white albedo under the
    fitted light (so it holds irradiance, shadowing and interreflection that the mesh can explain)."""

    Options = ShadingRatioOptions
    needs_shading = True

    def estimate(self, image: np.ndarray, mask: np.ndarray | None = None,
                 shading: np.ndarray | None = None) -> np.ndarray:
        if shading is None:
            raise PGCDataError("albedo_estimator 'shading_ratio' needs the shading image (a white-albedo render "
                               "of the mesh under the fitted light); pass shading=...")
        image = np.asarray(image, dtype=np.float64)
        shading = np.asarray(shading, dtype=np.float64)
        if shading.shape != image.shape:
            raise PGCDataError(f"shading shape {shading.shape} != image shape {image.shape}")
        region = shading if mask is None else shading[np.asarray(mask) > 0.5]
        scale = float(np.percentile(region, 99)) if region.size else 0.0
        floor = max(self.options.min_shading * scale, 1e-6)
        albedo = image / np.maximum(shading, floor)
        return np.clip(np.nan_to_num(albedo, nan=0.0, posinf=self.options.max_albedo),
                       0.0, self.options.max_albedo).astype(np.float32)
