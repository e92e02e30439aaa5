"""Image-quality metrics: PSNR, SSIM and FSIM here (numpy/scipy; registered for the ``metric`` role by
:mod:`pgc.builtin_plugins.metrics`); LPIPS in the torch backend (``pgc_torch.lpips``).
All take linear RGB and compare sRGB-encoded values; see docs/metrics.md."""

from pgc.metrics.fsim import fsim
from pgc.metrics.psnr import psnr
from pgc.metrics.ssim import ssim

__all__ = ["fsim", "psnr", "ssim"]
