"""Bilinear texture lookups with the UV convention of :class:`pgc.types.Mesh` (v up)."""

from __future__ import annotations

import numpy as np


def sample_bilinear(image: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Sample ``image`` (H, W, C) at continuous pixel coordinates ``xy`` (..., 2) (x right, y down, pixel
    centres at +0.5), clamping at the border. Returns (..., C)."""
    h, w = image.shape[:2]
    x = np.clip(np.asarray(xy[..., 0], dtype=np.float64) - 0.5, 0, w - 1)
    y = np.clip(np.asarray(xy[..., 1], dtype=np.float64) - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def sample_uv(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of ``texture`` (H, W, C) at UV coordinates ``uv`` (..., 2), v up."""
    from pgc.texture.atlas import uv_to_pixel

    h, w = texture.shape[:2]
    return sample_bilinear(texture, uv_to_pixel(uv, h, w))
