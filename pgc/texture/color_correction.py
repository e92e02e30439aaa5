"""Per-view 3x3 colour correction: a robust least-squares fit of ``target ~ M @ source`` per pixel."""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError


def fit_color_matrix(source: np.ndarray, target: np.ndarray, weights: np.ndarray | None = None,
                     iterations: int = 10, huber_k: float = 1.345) -> np.ndarray:
    """The (3, 3) matrix M minimising sum w rho(|M s - t|) over colour pairs (N, 3) -> (N, 3).

    Iteratively reweighted least squares with Huber weights on the residual norm, the scale estimated by
    the median absolute deviation, so a minority of outliers (specular glints, misaligned mask borders)
    does not bend the fit. Fewer than 3 usable pairs (or a rank-deficient source) gives a scalar fit.
    """
    s = np.asarray(source, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(target, dtype=np.float64).reshape(-1, 3)
    if s.shape != t.shape:
        raise PGCDataError(f"colour correction: source {s.shape} and target {t.shape} differ")
    w = np.ones(len(s)) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    ok = (w > 0) & np.all(np.isfinite(s), axis=1) & np.all(np.isfinite(t), axis=1)
    s, t, w = s[ok], t[ok], w[ok]
    if len(s) == 0:
        return np.eye(3)
    m = _scalar_fit(s, t, w)
    if len(s) < 3 or np.linalg.matrix_rank(s * np.sqrt(w)[:, None], tol=1e-8) < 3:
        return m
    robust = w.copy()
    for _ in range(iterations):
        sw = np.sqrt(robust)[:, None]
        sol, *_ = np.linalg.lstsq(s * sw, t * sw, rcond=None)
        m = sol.T
        r = np.linalg.norm(s @ m.T - t, axis=1)
        scale = 1.4826 * np.median(np.abs(r - np.median(r))) + 1e-12
        u = r / (huber_k * scale)
        robust = w * np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-12))
    return m


def _scalar_fit(s: np.ndarray, t: np.ndarray, w: np.ndarray) -> np.ndarray:
    den = float(np.sum(w[:, None] * s * s))
    return np.eye(3) * (float(np.sum(w[:, None] * s * t)) / den if den > 0 else 1.0)


def apply_color_matrix(image: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``image`` (..., 3) with every colour c replaced by M c."""
    return (np.asarray(image, dtype=np.float64) @ np.asarray(m).T).astype(np.float32)
