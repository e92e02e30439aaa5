"""Photometric losses of the splat fit (3DGS conventions): L1, SSIM (11-tap Gaussian window, sigma 1.5,
zero padding as in 3DGS), and sRGB encoding."""

from __future__ import annotations

import torch
import torch.nn.functional as F

_SIGMA, _TAPS = 1.5, 11


def _window(dtype: torch.dtype) -> torch.Tensor:
    x = torch.arange(_TAPS, dtype=torch.float64) - _TAPS // 2
    g = torch.exp(-x * x / (2 * _SIGMA ** 2))
    g = g / g.sum()
    return (g[:, None] * g[None, :]).to(dtype).expand(3, 1, _TAPS, _TAPS).contiguous()


def ssim(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Mean SSIM of two (H, W, 3) images (differentiable)."""
    x, y = x.permute(2, 0, 1)[None], y.permute(2, 0, 1)[None]
    w = _window(x.dtype)

    def blur(a: torch.Tensor) -> torch.Tensor:
        return F.conv2d(a, w, padding=_TAPS // 2, groups=3)

    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    return (((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))).mean()


def linear_to_srgb(x: torch.Tensor) -> torch.Tensor:
    """sRGB encoding of linear values (differentiable, finite gradient at 0; clamped to [0, 1])."""
    x = torch.clamp(x, 0.0, 1.0)
    return torch.where(x <= 0.0031308, 12.92 * x, 1.055 * torch.clamp_min(x, 0.0031308) ** (1 / 2.4) - 0.055)
