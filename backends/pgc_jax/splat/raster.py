"""Front-to-back alpha compositing of projected Gaussians over tile chunks, in JAX, with an analytic VJP.

Formulation (dense, XLA friendly): every chunk of ``B`` depth-sorted Gaussians of one ``tile x tile``
pixel tile is evaluated against all ``P = tile^2`` pixels of that tile as a (K, P, B) block.
- Pass 1: per chunk and pixel, ``S = sum_b log(1 - a_b)``; a segmented exclusive scan over the chunks of a
  tile gives the log-transmittance ``log T_in`` entering every chunk.
- Pass 2: inside a chunk, ``T_b = T_in exp(sum_{b' < b} log(1 - a_b'))``; weights ``w_b = a_b T_b``.
The rules of the contract hold exactly: a Gaussian touches the pixel centres inside its footprint box
(``|dx|, |dy| <= radius``); ``a = min(0.99, o exp(-q/2))``; ``a < 1/255`` (or ``q < 0``) is skipped;
a Gaussian is composited only while ``T_b (1 - a_b) >= 1e-4`` (transmittance is monotone, so this equals
"stop at the first one that would cross it"). The final transmittance is ``1 - sum w``.

Backward (one dense pass, no stored (K, P, B) tensors): with the pixel cotangent ``g`` of the features and
``g_W`` of the accumulated alpha, ``v_i = g . f_i + g_W`` and the suffix ``Q_i = sum_{j > i} w_j v_j`` over
the whole tile list, ``dL/da_i = T_i v_i - Q_i / (1 - a_i)`` and ``dL/df_i = w_i g``. ``Q_i`` is the tile
total (known from the forward outputs) minus the prefix up to ``i`` (chunk prefixes from a segmented scan of
the per-chunk forward outputs, then a cumulative sum inside the chunk).
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from pgc.splats.projection import ALPHA_MAX, ALPHA_MIN, T_MIN

LOG_T_MIN = math.log(T_MIN)


def _screen(px, py, mean, conic, opacity, radius):
    """Offsets, Gaussian falloff and masks of every (chunk, pixel, entry): the shared first step."""
    dx = px[:, :, None] - mean[:, None, :, 0]
    dy = py[:, :, None] - mean[:, None, :, 1]
    a, b, c = (conic[:, None, :, i] for i in range(3))
    power = -0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy
    g = jnp.exp(jnp.minimum(power, 0.0))
    raw = opacity[:, None, :] * g
    r = radius[:, None, :]
    active = (jnp.abs(dx) <= r) & (jnp.abs(dy) <= r) & (raw >= ALPHA_MIN) & (power <= 0.0)
    alpha = jnp.where(active, jnp.minimum(ALPHA_MAX, raw), 0.0)
    return dx, dy, g, raw, active, alpha


def _segmented_exclusive_sum(values: jnp.ndarray, first: jnp.ndarray) -> jnp.ndarray:
    """Exclusive running sum of ``values`` (K, P) along K, restarting where ``first`` (K,) is set.

    A sequential scan: exact (no differences of large prefix sums), cheap to compile and to run."""
    def step(carry, x):
        v, f = x
        out = jnp.where(f, 0.0, carry)
        return out + v, out

    return jax.lax.scan(step, jnp.zeros_like(values[0]), (values, first))[1]


def _prefix_matrix(n: int, dtype, strict: bool) -> jnp.ndarray:
    """(n, n) matrix ``U`` with ``(x @ U)[i] = sum_{j < i} x[j]`` (strict) or ``j <= i``: a prefix sum as
    one small GEMM, much faster on XLA:CPU than ``cumsum`` along a short last axis."""
    return jnp.triu(jnp.ones((n, n), dtype), 1 if strict else 0)


def _weights(alpha, log_t_in):
    """Per-entry log transmittance before each entry, the keep mask and the weights ``w = a T``."""
    log1m = jnp.log1p(-alpha)
    log_t = log_t_in[:, :, None] + log1m @ _prefix_matrix(alpha.shape[-1], alpha.dtype, strict=True)
    keep = log_t + log1m >= LOG_T_MIN
    return log_t, keep, jnp.where(keep, alpha * jnp.exp(log_t), 0.0)


def _forward(px, py, mean, conic, opacity, radius, feats, first):
    alpha = _screen(px, py, mean, conic, opacity, radius)[-1]
    log_t_in = _segmented_exclusive_sum(jnp.sum(jnp.log1p(-alpha), axis=-1), first)
    _, _, w = _weights(alpha, log_t_in)
    return jnp.einsum("kpb,kbf->kpf", w, feats), jnp.sum(w, axis=-1), log_t_in


@partial(jax.custom_vjp, nondiff_argnums=(9,))
def _composite_chunks(px, py, mean, conic, opacity, radius, feats, first, tiles, n_tiles):
    """Per-chunk weighted feature sums (K, P, F) and weight sums (K, P)."""
    out, wsum, _ = _forward(px, py, mean, conic, opacity, radius, feats, first)
    return out, wsum


def _composite_fwd(px, py, mean, conic, opacity, radius, feats, first, tiles, n_tiles):
    out, wsum, log_t_in = _forward(px, py, mean, conic, opacity, radius, feats, first)
    return (out, wsum), (px, py, mean, conic, opacity, radius, feats, first, tiles, out, wsum, log_t_in)


def _composite_bwd(n_tiles, res, cot):
    px, py, mean, conic, opacity, radius, feats, first, tiles, out, wsum, log_t_in = res
    g_out, g_w = cot
    chunk_val = jnp.sum(g_out * out, axis=-1) + g_w * wsum          # sum_b w_b v_b of each chunk
    tile_total = jax.ops.segment_sum(chunk_val, tiles, num_segments=n_tiles + 1)[tiles]
    before = _segmented_exclusive_sum(chunk_val, first)
    _, _, _, raw, active, alpha = _screen(px, py, mean, conic, opacity, radius)
    log_t, keep, w = _weights(alpha, log_t_in)
    v = jnp.einsum("kpf,kbf->kpb", g_out, feats) + g_w[:, :, None]
    suffix = (tile_total - before)[:, :, None] - (w * v) @ _prefix_matrix(w.shape[-1], w.dtype, strict=False)
    d_alpha = jnp.where(keep & active, jnp.exp(log_t) * v - suffix / (1.0 - alpha), 0.0)
    d_power = jnp.where(raw < ALPHA_MAX, d_alpha, 0.0) * raw   # d raw / d power = raw
    # Sums over pixels of d_power times (1, x, y, x^2, xy, y^2) in tile-centred coordinates, as one GEMM;
    # the offsets dx = x - mx expand from these moments (small magnitudes: little cancellation).
    half = 0.5 * round(px.shape[1] ** 0.5)                    # tile centre = pixel-centre origin - 0.5 + half
    ox, oy = px[:, :1] - 0.5 + half, py[:, :1] - 0.5 + half
    x, y = px - ox, py - oy
    moments = jnp.einsum("kpb,kpm->kbm", d_power, jnp.stack([jnp.ones_like(x), x, y, x * x, x * y, y * y], -1))
    e1, ex, ey, exx, exy, eyy = (moments[..., i] for i in range(6))
    mx, my = mean[..., 0] - ox, mean[..., 1] - oy
    sx, sy = ex - mx * e1, ey - my * e1                       # sum d_power dx, sum d_power dy
    a, b, c = conic[..., 0], conic[..., 1], conic[..., 2]
    d_mean = jnp.stack([a * sx + b * sy, c * sy + b * sx], axis=-1)
    sxx = exx - 2.0 * mx * ex + mx * mx * e1
    sxy = exy - mx * ey - my * ex + mx * my * e1
    syy = eyy - 2.0 * my * ey + my * my * e1
    d_conic = jnp.stack([-0.5 * sxx, -sxy, -0.5 * syy], axis=-1)
    d_opacity = jnp.where(opacity > 0, e1 / jnp.where(opacity > 0, opacity, 1.0), 0.0)  # d raw / d o = raw / o
    d_feats = jnp.einsum("kpb,kpf->kbf", w, g_out)
    float0 = lambda x: np.zeros(x.shape, dtype=jax.dtypes.float0)  # noqa: E731
    return (jnp.zeros_like(px), jnp.zeros_like(py), d_mean, d_conic, d_opacity, jnp.zeros_like(radius), d_feats,
            float0(first), float0(tiles))


_composite_chunks.defvjp(_composite_fwd, _composite_bwd)


def composite(mean2d: jnp.ndarray, conic: jnp.ndarray, opacity: jnp.ndarray, radius: jnp.ndarray,
              feats: jnp.ndarray, gauss: jnp.ndarray, tiles: jnp.ndarray, first: jnp.ndarray, width: int,
              height: int, tile: int) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Composite ``feats`` (N, F) of screen-space Gaussians (``radius``: footprint box half-width, px)
    front to back.

    ``gauss`` (K, B), ``tiles`` (K,), ``first`` (K,) come from :func:`binning.bin_gaussians`
    (index ``N`` is a transparent sentinel, tile ``n_tiles`` a discarded padding tile).
    Returns the (H, W, F) weighted feature sums and the (H, W) accumulated alpha ``sum w``.
    """
    f = feats.shape[1]
    pad = lambda x: jnp.concatenate([x, jnp.zeros((1,) + x.shape[1:], x.dtype)], axis=0)  # noqa: E731
    mean, con, opa, fea = pad(mean2d)[gauss], pad(conic)[gauss], pad(opacity)[gauss], pad(feats)[gauss]
    rad = pad(jax.lax.stop_gradient(radius))[gauss]
    tx_n, ty_n = -(-width // tile), -(-height // tile)
    n_tiles = tx_n * ty_n
    local = jnp.arange(tile * tile)
    lx, ly = (local % tile).astype(mean.dtype) + 0.5, (local // tile).astype(mean.dtype) + 0.5
    px = ((tiles % tx_n) * tile).astype(mean.dtype)[:, None] + lx[None, :]
    py = ((tiles // tx_n) * tile).astype(mean.dtype)[:, None] + ly[None, :]
    out, wsum = _composite_chunks(px, py, mean, con, opa, rad, fea, first, tiles, n_tiles)
    out = jax.ops.segment_sum(jnp.concatenate([out, wsum[..., None]], -1), tiles, num_segments=n_tiles + 1)
    img = out[:n_tiles].reshape(ty_n, tx_n, tile, tile, f + 1).transpose(0, 2, 1, 3, 4)
    img = img.reshape(ty_n * tile, tx_n * tile, f + 1)[:height, :width]
    return img[..., :f], img[..., f]
