"""The ``metric`` role implementations psnr, ssim and fsim (numpy/scipy); lpips lives in the torch backend."""

from __future__ import annotations

import numpy as np

from pgc.builtin_plugins.specs_metrics import FSIMOptions, PSNROptions
from pgc.metrics.fsim import fsim
from pgc.metrics.psnr import psnr
from pgc.metrics.ssim import ssim
from pgc.roles.metric import Metric


class PSNRMetric(Metric):
    """PSNR in dB, higher is better; +inf for identical images."""

    Options = PSNROptions

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        return psnr(pred, target, mask, self.options.color_space)


class SSIMMetric(Metric):
    """Mean SSIM on sRGB values, higher is better (1 for identical images)."""

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        return ssim(pred, target, mask)


class FSIMMetric(Metric):
    """FSIMc (or FSIM) on sRGB values, higher is better (1 for identical images)."""

    Options = FSIMOptions

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        return fsim(pred, target, mask, self.options.chromatic)
