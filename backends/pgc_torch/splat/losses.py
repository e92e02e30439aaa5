"""Photometric losses of the splat fit (3DGS conventions): L1, SSIM (11-tap Gaussian window, sigma 1.5,
zero padding as in 3DGS; the window is separable, so it runs as a row pass and a column pass: 22 taps a pixel
instead of 121), and sRGB encoding."""

from __future__ import annotations

import torch
import torch.nn.functional as F

_SIGMA, _TAPS = 1.5, 11


def _taps(dtype: torch.dtype) -> torch.Tensor:
    """The normalised 1D Gaussian window (``_TAPS``,); the 2D window is its outer product."""
    x = torch.arange(_TAPS, dtype=torch.float64) - _TAPS // 2
    g = torch.exp(-x * x / (2 * _SIGMA ** 2))
    return (g / g.sum()).to(dtype)


def ssim(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Mean SSIM of two (H, W, 3) images (differentiable)."""
    x, y = x.permute(2, 0, 1)[None], y.permute(2, 0, 1)[None]
    g = _taps(x.dtype)
    rows = g.view(1, 1, 1, _TAPS).expand(3, 1, 1, _TAPS).contiguous()
    cols = g.view(1, 1, _TAPS, 1).expand(3, 1, _TAPS, 1).contiguous()

    def blur(a: torch.Tensor) -> torch.Tensor:
        a = F.conv2d(a, rows, padding=(0, _TAPS // 2), groups=3)
        return F.conv2d(a, cols, padding=(_TAPS // 2, 0), groups=3)

    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    return (((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))).mean()


def linear_to_srgb(x: torch.Tensor) -> torch.Tensor:
    """sRGB encoding of linear values (differentiable, finite gradient at 0; clamped to [0, 1])."""
    x = torch.clamp(x, 0.0, 1.0)
    return torch.where(x <= 0.0031308, 12.92 * x, 1.055 * torch.clamp_min(x, 0.0031308) ** (1 / 2.4) - 0.055)
