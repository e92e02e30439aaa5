"""Photometric losses of the splat fit in JAX (3DGS conventions, as the torch fit): SSIM with an 11-tap
Gaussian window (sigma 1.5, zero padding), sRGB encoding."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

SIGMA, TAPS = 1.5, 11


def _blur(x: jnp.ndarray) -> jnp.ndarray:
    """Separable Gaussian blur of (H, W, C) with zero padding ('same' size)."""
    t = np.arange(TAPS) - TAPS // 2
    g = np.exp(-t * t / (2 * SIGMA ** 2))
    g = jnp.asarray(g / g.sum(), x.dtype)
    c = x.shape[-1]
    y = jnp.transpose(x, (2, 0, 1))[None]                         # (1, C, H, W)
    dn = ("NCHW", "OIHW", "NCHW")
    for kernel in (g.reshape(1, 1, TAPS, 1), g.reshape(1, 1, 1, TAPS)):
        y = jax.lax.conv_general_dilated(y, jnp.tile(kernel, (c, 1, 1, 1)), (1, 1), "SAME",
                                         dimension_numbers=dn, feature_group_count=c)
    return jnp.transpose(y[0], (1, 2, 0))


def ssim(x: jnp.ndarray, y: jnp.ndarray) -> jnp.ndarray:
    """Mean SSIM of two (H, W, C) images (differentiable)."""
    mx, my = _blur(x), _blur(y)
    vx, vy, cxy = _blur(x * x) - mx * mx, _blur(y * y) - my * my, _blur(x * y) - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    return jnp.mean(((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2)))


def linear_to_srgb(x: jnp.ndarray) -> jnp.ndarray:
    """sRGB encoding of linear values clamped to [0, 1] (finite gradient at 0)."""
    x = jnp.clip(x, 0.0, 1.0)
    return jnp.where(x <= 0.0031308, 12.92 * x, 1.055 * jnp.maximum(x, 0.0031308) ** (1 / 2.4) - 0.055)
