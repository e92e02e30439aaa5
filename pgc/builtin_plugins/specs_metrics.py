"""Registration of the numpy/scipy metrics psnr, ssim, fsim (light: pgc core and pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import Options
from pgc.registry import ImplementationSpec


class PSNROptions(Options):
    color_space: Literal["srgb", "linear"] = Field(
        "srgb", description="compare sRGB-encoded values (as images are viewed) or the linear values")


class FSIMOptions(Options):
    chromatic: bool = Field(True, description="FSIMc (with the YIQ chroma term, the paper's choice) or grey FSIM")


SPECS = [
    ImplementationSpec(role="metric", name="psnr", factory="pgc.builtin_plugins.metrics:PSNRMetric",
                       description="peak signal-to-noise ratio in dB (sRGB values by default; masked MSE)",
                       options="pgc.builtin_plugins.specs_metrics:PSNROptions", requires=("scipy",)),
    ImplementationSpec(role="metric", name="ssim", factory="pgc.builtin_plugins.metrics:SSIMMetric",
                       description="SSIM, Gaussian window 11 / sigma 1.5, standard constants, on sRGB values",
                       requires=("scipy",)),
    ImplementationSpec(role="metric", name="fsim", factory="pgc.builtin_plugins.metrics:FSIMMetric",
                       description="FSIMc (Zhang et al. 2011): phase congruency + Scharr gradient + YIQ chroma",
                       options="pgc.builtin_plugins.specs_metrics:FSIMOptions", requires=("scipy",)),
]
