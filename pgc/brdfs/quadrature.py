"""Hemispherical integrals of BRDFs by deterministic quadrature (numpy, float64).

Grazing lobes (the Zeltner sheen at low roughness concentrates within ~1e-4 of the horizon) need a grid
that resolves the horizon: cos theta is sampled log-uniformly down to ``min_cos`` (midpoint rule in
``s = ln cos theta``, ``d cos theta = cos theta ds``), azimuth uniformly.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


def hemisphere_grid(n_cos: int = 2048, n_phi: int = 512, min_cos: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (n_cos * n_phi, 3) over the upper hemisphere and their solid-angle weights."""
    s = np.log(min_cos) * (1.0 - (np.arange(n_cos) + 0.5) / n_cos)
    mu = np.exp(s)
    d_mu = mu * (-np.log(min_cos) / n_cos)
    phi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)
    MU, PHI = np.meshgrid(mu, phi, indexing="ij")
    sin_t = np.sqrt(np.maximum(1.0 - MU * MU, 0.0))
    dirs = np.stack([sin_t * np.cos(PHI), sin_t * np.sin(PHI), MU], axis=-1).reshape(-1, 3)
    weights = np.broadcast_to(d_mu[:, None] * (2.0 * np.pi / n_phi), MU.shape).reshape(-1)
    return dirs, weights


def directional_albedo(eval_cos: Callable[[np.ndarray, np.ndarray], np.ndarray], view: np.ndarray,
                       n_cos: int = 2048, n_phi: int = 512) -> np.ndarray:
    """``int eval_cos(L, view) dL`` over the hemisphere for one view direction (3,); returns (..., C)."""
    L, w = hemisphere_grid(n_cos, n_phi)
    V = np.broadcast_to(np.asarray(view, dtype=np.float64), L.shape)
    return np.tensordot(w, eval_cos(L, V), axes=(0, 0))
