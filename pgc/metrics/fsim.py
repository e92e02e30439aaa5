"""FSIM / FSIMc (Zhang, Zhang, Mou and Zhang, IEEE TIP 2011), following the authors' reference code.

On sRGB-encoded values scaled to [0, 255] (the constants assume that range): luminance Y and chrominance
I, Q of YIQ; all channels averaged over F x F blocks (zero border, 'same' alignment) and subsampled by
F = max(1, round(min(H, W) / 256)); phase congruency of Y with log-Gabor filters (4 scales from a 6 px
wavelength, factor 2, sigma_f 0.55; 4 orientations, dTheta/sigma 1.2; noise threshold k = 2, as in
Kovesi's phasecong2 used by the reference); gradient magnitude with the Scharr operator;
T1 = 0.85, T2 = 160, T3 = T4 = 200, lambda = 0.03. FSIMc = sum(S_PC S_G (S_I S_Q)^lambda PC_m) / sum(PC_m)
with PC_m = max(PC_1, PC_2). A mask (resampled like the images) weights both sums.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from pgc.metrics.common import check_images, display_255, require_nonempty

T1, T2, T3, T4, LAMBDA = 0.85, 160.0, 200.0, 200.0, 0.03
SCALES, ORIENTATIONS, MIN_WAVELENGTH, MULT, SIGMA_ON_F, D_THETA_ON_SIGMA, NOISE_K = 4, 4, 6.0, 2.0, 0.55, 1.2, 2.0
EPSILON = 1e-4
MIN_SIZE = int(MIN_WAVELENGTH)
"""Smallest image side (px): one period of the finest log-Gabor filter (a 1 px image gives 0 / 0)."""
_YIQ = np.array([[0.299, 0.587, 0.114], [0.596, -0.274, -0.322], [0.211, -0.523, 0.312]])
_SCHARR_X = np.array([[3.0, 0.0, -3.0], [10.0, 0.0, -10.0], [3.0, 0.0, -3.0]]) / 16.0


def downsample_factor(height: int, width: int) -> int:
    """The reference's F = max(1, round(min(H, W) / 256)), rounding halves up."""
    return max(1, int(np.floor(min(height, width) / 256.0 + 0.5)))


def _block_average(x: np.ndarray, f: int) -> np.ndarray:
    """MATLAB ``conv2(x, ones(f)/f^2, 'same')`` sampled at ``(1:f:end, 1:f:end)``, over the first two axes."""
    if f == 1:
        return x
    centre = (f - 1 + 1) // 2  # ceil((f - 1) / 2): where 'same' starts in the full convolution
    for axis in (0, 1):
        pad = [(0, 0)] * x.ndim
        pad[axis] = (f - 1 - centre, centre)
        c = np.cumsum(np.pad(x, pad), axis=axis)
        c = np.concatenate([np.zeros_like(c.take([0], axis=axis)), c], axis=axis)
        n = x.shape[axis]
        x = (c.take(np.arange(f, n + f), axis=axis) - c.take(np.arange(n), axis=axis)) / f
    return x[::f, ::f]


def _centred_grid(n: int) -> np.ndarray:
    """Frequencies in [-0.5, 0.5] as the reference lays them out (odd and even sizes differ)."""
    if n % 2:
        return np.arange(-(n - 1) / 2, (n - 1) / 2 + 1) / max(n - 1, 1)
    return np.arange(-n / 2, n / 2) / n


@dataclass(frozen=True)
class _Bank:
    """The log-Gabor filters of one image size and the noise model's constants that depend on them only."""

    filters: list[list[np.ndarray]]
    """[orientation][scale], in the (unshifted) FFT layout."""
    smallest_energy: list[float]
    """Per orientation: sum of the smallest-scale filter's squared values."""
    sum_an2: list[float]
    """Per orientation: sum over scales of the squared spatial filters."""
    sum_aiaj: list[float]
    """Per orientation: sum over pairs of scales of the products of the spatial filters."""


@lru_cache(maxsize=8)
def _bank(rows: int, cols: int) -> _Bank:
    """The filter bank of a ``rows`` x ``cols`` image (built once per size; the arrays are read-only)."""
    x, y = np.meshgrid(_centred_grid(cols), _centred_grid(rows))
    radius = np.fft.ifftshift(np.sqrt(x ** 2 + y ** 2))
    theta = np.fft.ifftshift(np.arctan2(-y, x))
    lowpass = 1.0 / (1.0 + (radius / 0.45) ** 30)  # Butterworth: cut-off 0.45, order 15
    radius[0, 0] = 1.0
    radial = []
    for s in range(SCALES):
        f0 = 1.0 / (MIN_WAVELENGTH * MULT ** s)
        log_gabor = np.exp(-np.log(radius / f0) ** 2 / (2 * np.log(SIGMA_ON_F) ** 2)) * lowpass
        log_gabor[0, 0] = 0.0
        radial.append(log_gabor)
    theta_sigma = np.pi / ORIENTATIONS / D_THETA_ON_SIGMA
    sin_t, cos_t = np.sin(theta), np.cos(theta)
    filters, smallest, an2, aiaj = [], [], [], []
    for o in range(ORIENTATIONS):
        angle = o * np.pi / ORIENTATIONS
        d_theta = np.abs(np.arctan2(sin_t * np.cos(angle) - cos_t * np.sin(angle),
                                    cos_t * np.cos(angle) + sin_t * np.sin(angle)))
        spread = np.exp(-d_theta ** 2 / (2 * theta_sigma ** 2))
        bank = [r * spread for r in radial]
        spatial = [np.real(np.fft.ifft2(filt)) * np.sqrt(rows * cols) for filt in bank]
        for filt in bank:
            filt.flags.writeable = False
        filters.append(bank)
        smallest.append(float(np.sum(bank[0] ** 2)))
        an2.append(sum(np.sum(s ** 2) for s in spatial))
        aiaj.append(sum(np.sum(spatial[i] * spatial[j]) for i in range(SCALES) for j in range(i + 1, SCALES)))
    return _Bank(filters, smallest, an2, aiaj)


def phase_congruency(image: np.ndarray) -> np.ndarray:
    """Phase congruency (Kovesi's phasecong2 as used by the FSIM reference) of a grey image, in [0, 1]."""
    rows, cols = image.shape
    spectrum = np.fft.fft2(image)
    energy_all = np.zeros((rows, cols))
    amplitude_all = np.zeros((rows, cols))
    bank = _bank(rows, cols)
    for o, filters in enumerate(bank.filters):
        responses = [np.fft.ifft2(spectrum * filt) for filt in filters]
        sum_e = sum(r.real for r in responses)
        sum_o = sum(r.imag for r in responses)
        amplitude = sum(np.abs(r) for r in responses)
        norm = np.sqrt(sum_e ** 2 + sum_o ** 2) + EPSILON
        mean_e, mean_o = sum_e / norm, sum_o / norm
        energy = sum(r.real * mean_e + r.imag * mean_o - np.abs(r.real * mean_o - r.imag * mean_e)
                     for r in responses)
        # noise: the median squared response at the smallest scale, a Rayleigh model, rescaled by 1 / 1.7
        noise_power = -np.median(np.abs(responses[0]) ** 2) / np.log(0.5) / bank.smallest_energy[o]
        tau = np.sqrt((2 * noise_power * bank.sum_an2[o] + 4 * noise_power * bank.sum_aiaj[o]) / 2)
        threshold = (tau * np.sqrt(np.pi / 2) + NOISE_K * np.sqrt((2 - np.pi / 2) * tau ** 2)) / 1.7
        energy_all += np.maximum(energy - threshold, 0.0)
        amplitude_all += amplitude
    return energy_all / np.maximum(amplitude_all, 1e-300)


def _gradient(y: np.ndarray) -> np.ndarray:
    from scipy.ndimage import correlate

    return np.hypot(correlate(y, _SCHARR_X, mode="constant"), correlate(y, _SCHARR_X.T, mode="constant"))


def _similarity(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    return (2 * a * b + t) / (a ** 2 + b ** 2 + t)


def fsim(pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None,
         chromatic: bool = True) -> float:
    """FSIMc (``chromatic``, default) or FSIM of two (H, W, 3) linear images, compared as sRGB.

    1 for identical images, lower for worse; with ``mask`` (H, W) both sums are weighted by the mask
    averaged and subsampled like the images. Images without any phase congruency (flat) give the plain mean
    of the similarity map (the reference's 0 / 0). An all-zero mask is an error, as in every metric; so are
    NaN/Inf inputs and images under :data:`MIN_SIZE` px a side.
    """
    pred, target = check_images("fsim", pred, target, mask, MIN_SIZE,
                                f"one {MIN_SIZE} px period of the finest log-Gabor filter")
    if mask is not None:
        require_nonempty(mask, "fsim")
    f = downsample_factor(*pred.shape[:2])
    yiq = [_block_average(display_255(im) @ _YIQ.T, f) for im in (pred, target)]
    pc1, pc2 = (phase_congruency(c[..., 0]) for c in yiq)
    s = _similarity(pc1, pc2, T1) * _similarity(_gradient(yiq[0][..., 0]), _gradient(yiq[1][..., 0]), T2)
    if chromatic:
        s_iq = _similarity(yiq[0][..., 1], yiq[1][..., 1], T3) * _similarity(yiq[0][..., 2], yiq[1][..., 2], T4)
        # the reference takes real(x ^ lambda): for x < 0 (chroma of opposite signs) that is |x|^lambda cos(pi lambda)
        s = s * np.abs(s_iq) ** LAMBDA * np.where(s_iq < 0, np.cos(np.pi * LAMBDA), 1.0)
    weight = np.maximum(pc1, pc2)
    if mask is not None:
        weight = weight * _block_average(np.asarray(mask, np.float64), f)
    total = weight.sum()
    if total <= 0:  # no structure anywhere (flat images): the reference divides 0 by 0; use the plain mean
        return float(np.mean(s))
    return float((s * weight).sum() / total)
