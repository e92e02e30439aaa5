"""Per-view 3x3 colour correction: a robust least-squares fit of ``target ~ M @ source`` per pixel."""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError


def fit_color_matrix(source: np.ndarray, target: np.ndarray, weights: np.ndarray | None = None,
                     iterations: int = 10, huber_k: float = 1.345, ridge: float = 1e-3) -> np.ndarray:
    """The (3, 3) matrix M minimising sum w rho(|M s - t|) + lambda |M - D|^2 over colour pairs (N, 3).

    Iteratively reweighted least squares with Huber weights on the residual norm, the scale estimated by
    the median absolute deviation, so a minority of outliers (specular glints, misaligned mask borders)
    does not bend the fit. The ridge term pulls M toward D, the per-channel (diagonal) fit, with lambda =
    ``ridge`` x the mean eigenvalue of the weighted source covariance: a garment of few, nearly collinear
    colours (stripes of grey and navy) leaves cross-channel terms undetermined, and without it they blow up
    (condition numbers of 1e3 seen). Fewer than 3 usable pairs gives the diagonal fit.
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
    diag = _diagonal_fit(s, t, w)
    if len(s) < 3:
        return diag
    m = diag
    robust = w.copy()
    for _ in range(iterations):
        gram = (s * robust[:, None]).T @ s
        lam = ridge * max(np.trace(gram) / 3.0, 1e-12)
        m = np.linalg.solve(gram + lam * np.eye(3), (s * robust[:, None]).T @ t + lam * diag.T).T
        r = np.linalg.norm(s @ m.T - t, axis=1)
        scale = 1.4826 * np.median(np.abs(r - np.median(r))) + 1e-12
        u = r / (huber_k * scale)
        robust = w * np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-12))
    return m


def _diagonal_fit(s: np.ndarray, t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-channel scales: diag(sum w s_c t_c / sum w s_c^2) (1 where a channel is all zero)."""
    den = (w[:, None] * s * s).sum(0)
    num = (w[:, None] * s * t).sum(0)
    return np.diag(np.where(den > 0, num / np.where(den > 0, den, 1.0), 1.0))


def apply_color_matrix(image: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``image`` (..., 3) with every colour c replaced by M c."""
    return (np.asarray(image, dtype=np.float64) @ np.asarray(m).T).astype(np.float32)
