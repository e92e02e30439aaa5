"""Registration of the numpy/scipy metrics psnr, psnr-exposure, ssim, fsim (light: pgc core and pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import Options
from pgc.registry import ImplementationSpec


class PSNROptions(Options):
    color_space: Literal["srgb", "linear"] = Field(
        "srgb", description="compare sRGB-encoded values (as images are viewed) or the linear values")


class PSNRExposureOptions(PSNROptions):
    exposure: float = Field(0.18, gt=0.0, le=1.0, description=(
        "linear grey the target's mean over the garment is scaled to, with the prediction by the same factor, "
        "before the PSNR (0.18: mid-grey); makes PSNR comparable across lights"))


class FSIMOptions(Options):
    chromatic: bool = Field(True, description="FSIMc (with the YIQ chroma term, the paper's choice) or grey FSIM")


SPECS = [
    ImplementationSpec(role="metric", name="psnr", factory="pgc.builtin_plugins.metrics:PSNRMetric",
                       description="peak signal-to-noise ratio in dB (sRGB values by default; masked MSE)",
                       options="pgc.builtin_plugins.specs_metrics:PSNROptions", requires=("scipy",)),
    ImplementationSpec(role="metric", name="psnr-exposure", factory="pgc.builtin_plugins.metrics:PSNRExposureMetric",
                       description="PSNR in dB at a fixed exposure: both images scaled so that the target's masked "
                                   "mean is mid-grey (relit frames comparable with the capture light's)",
                       options="pgc.builtin_plugins.specs_metrics:PSNRExposureOptions", requires=("scipy",)),
    ImplementationSpec(role="metric", name="ssim", factory="pgc.builtin_plugins.metrics:SSIMMetric",
                       description="SSIM, Gaussian window 11 / sigma 1.5, standard constants, on sRGB values",
                       requires=("scipy",)),
    ImplementationSpec(role="metric", name="fsim", factory="pgc.builtin_plugins.metrics:FSIMMetric",
                       description="FSIMc (Zhang et al. 2011): phase congruency + Scharr gradient + YIQ chroma",
                       options="pgc.builtin_plugins.specs_metrics:FSIMOptions", requires=("scipy",)),
]
