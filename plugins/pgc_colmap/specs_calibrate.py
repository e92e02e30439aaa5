"""Registration of the colmap calibrator (light: no pycolmap import)."""

from __future__ import annotations

from pydantic import Field

from pgc.options import Options, count
from pgc.registry import ImplementationSpec


class ColmapCalibratorOptions(Options):
    """COLMAP on the CPU: SIFT features, exhaustive matching, incremental mapping with the intrinsics fixed,
    aligned back to the capture's frame by a similarity."""

    max_features: int = count(4096, 64, 1_000_000, "SIFT features per image")
    sift_peak_threshold: float = Field(0.002, gt=0.0, description="SIFT peak threshold (COLMAP's default 0.0067 "
                                                                  "finds few features on small cloth images)")
    min_inliers: int = count(12, 6, 1_000_000, "verified matches a view pair needs")


SPECS = [
    ImplementationSpec(
        role="calibrator", name="colmap", factory="pgc_colmap.calibrate:ColmapCalibrator",
        description="pycolmap on CPU: SIFT + exhaustive matching + incremental mapping (intrinsics fixed), "
                    "aligned to the capture's frame by a similarity",
        options="pgc_colmap.specs_calibrate:ColmapCalibratorOptions", requires=("pycolmap",), extra="colmap"),
]
