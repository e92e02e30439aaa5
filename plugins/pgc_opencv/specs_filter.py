"""Registration of the OpenCV ``filter`` (light: pgc core and pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import Options
from pgc.registry import ImplementationSpec


class OpenCVFilterOptions(Options):
    method: Literal["exact", "box3"] = Field(
        "exact", description="'exact': separable Gaussian, O(k) per pixel; 'box3': three box filters of the same "
                             "sigma, O(1) per pixel, an approximation (its error: benchmarks/bench_filter.py)")


SPECS = [
    ImplementationSpec(
        role="filter", name="opencv", factory="pgc_opencv.filter:OpenCVFilter",
        description="alpha-aware Gaussian low-pass with OpenCV (separable exact, or an O(1) 3-box cascade)",
        options="pgc_opencv.specs_filter:OpenCVFilterOptions", requires=("cv2",), extra="opencv"),
]
