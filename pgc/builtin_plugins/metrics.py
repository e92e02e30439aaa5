"""The ``metric`` role implementations psnr, psnr-exposure, ssim and fsim (numpy/scipy); lpips lives in the torch
backend."""

from __future__ import annotations

import numpy as np

from pgc.builtin_plugins.specs_metrics import FSIMOptions, PSNRExposureOptions, PSNROptions
from pgc.metrics.fsim import MIN_SIZE as FSIM_MIN_SIZE
from pgc.metrics.fsim import fsim
from pgc.metrics.psnr import psnr
from pgc.metrics.ssim import BORDER, ssim
from pgc.roles.metric import Metric


class PSNRMetric(Metric):
    """PSNR in dB, higher is better; +inf for identical images."""

    name = "psnr"
    Options = PSNROptions

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        return psnr(pred, target, mask, self.options.color_space)


class PSNRExposureMetric(Metric):
    """PSNR in dB after scaling both images so that the target's mean over the mask is ``exposure`` (linear):
    higher is better; +inf for identical images."""

    name = "psnr-exposure"
    Options = PSNRExposureOptions

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        return psnr(pred, target, mask, self.options.color_space, self.options.exposure)


class SSIMMetric(Metric):
    """Mean SSIM on sRGB values, higher is better (1 for identical images)."""

    name = "ssim"

    def min_image_size(self, masked: bool) -> tuple[int, str]:
        return 2 * BORDER + 1, f"the {2 * BORDER + 1} x {2 * BORDER + 1} px Gaussian window"

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        return ssim(pred, target, mask)


class FSIMMetric(Metric):
    """FSIMc (or FSIM) on sRGB values, higher is better (1 for identical images)."""

    name = "fsim"
    Options = FSIMOptions

    def min_image_size(self, masked: bool) -> tuple[int, str]:
        return FSIM_MIN_SIZE, f"one {FSIM_MIN_SIZE} px period of the finest log-Gabor filter"

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        return fsim(pred, target, mask, self.options.chromatic)
