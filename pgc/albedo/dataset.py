"""The albedo network's training data (:class:`AlbedoData`: renders with ground-truth albedo, made by
:func:`pgc.synth.albedo_data.make_albedo_data`) and its error measure (:func:`scale_invariant_error`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class AlbedoData:
    images: np.ndarray
    """(N, H, W, 3) float32 linear RGB renders."""
    albedo: np.ndarray
    """(N, H, W, 3) float32 linear ground-truth albedo."""
    mask: np.ndarray
    """(N, H, W) float32 foreground coverage."""
    garment: np.ndarray
    """(N, H, W) float32 garment coverage."""

    def __len__(self) -> int:
        return len(self.images)


def scale_invariant_error(pred: np.ndarray, target: np.ndarray, weight: np.ndarray) -> float:
    """Weighted mean absolute error after the best per-channel scale of ``pred`` (albedo is defined up to
    scale; colour correction removes it downstream)."""
    w = weight[..., None].astype(np.float64)
    p, t = pred.astype(np.float64), target.astype(np.float64)
    scale = (w * p * t).sum(axis=(0, 1)) / np.maximum((w * p * p).sum(axis=(0, 1)), 1e-12)
    return float((w * np.abs(p * scale - t)).sum() / max(3 * w.sum(), 1e-12))
