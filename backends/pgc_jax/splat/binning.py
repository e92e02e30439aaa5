"""Tile binning on the host (numpy): per-tile, depth-sorted, fixed-size chunks of Gaussian indices.

The image is cut into ``tile x tile`` pixel tiles. A Gaussian is listed in every tile that holds a pixel
centre where it can count: inside its footprint box (half-width ``ceil(3 sqrt(lambda_max))``, the
contract) and inside the ellipse where its alpha can reach 1/255, ``d^T Sigma^-1 d <= 2 ln(255 o)``,
which lies in the circle of radius ``sqrt(2 ln(255 o) lambda_max)`` (tighter than the box for faint
Gaussians; empty for ``o < 1/255``). Nothing the compositor would count is ever dropped, so the result
does not depend on the tile size.

Each tile's list, in increasing depth, is cut into chunks of ``chunk`` entries; the chunk table has a
static, bucketed length so that the jitted compositor recompiles only when the bucket changes.
Binning decides which (Gaussian, pixel) pairs are evaluated, never their values: it carries no gradient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pgc.splats.projection import ALPHA_MIN


@dataclass(frozen=True)
class Bins:
    """Chunk table of one view. ``K`` chunks (bucketed), ``B`` entries each."""

    gauss: np.ndarray
    """(K, B) int32 Gaussian indices; ``N`` (a transparent sentinel) pads."""
    tile: np.ndarray
    """(K,) int32 tile index (row-major over the tile grid); ``n_tiles`` marks padding chunks."""
    first: np.ndarray
    """(K,) bool: the chunk opens its tile's list."""
    n_pairs: int
    """Number of (Gaussian, tile) pairs before padding."""
    n_chunks: int
    """Number of chunks before padding."""


def bucket(n: int, minimum: int = 8) -> int:
    """Round ``n`` up to the next of {1, 1.25, 1.5, 1.75} x 2^k (at most 25 % padding, few sizes)."""
    n = max(int(n), minimum)
    step = 2 ** max(0, math.floor(math.log2(n)) - 2)
    return int(math.ceil(n / step) * step)


def binning_radius(box_radius: np.ndarray, lambda_max: np.ndarray, opacity: np.ndarray) -> np.ndarray:
    """Half-width (px) of a box that holds every pixel centre where a Gaussian counts; 0 if none can."""
    q = 2.0 * np.log(np.maximum(opacity, 1e-30) / ALPHA_MIN)
    r = np.sqrt(np.maximum(q, 0.0) * np.maximum(lambda_max, 0.0)) * (1.0 + 1e-4) + 1e-3
    return np.where(q > 0, np.minimum(r, box_radius), 0.0)


def bin_gaussians(mean2d: np.ndarray, radius: np.ndarray, depth: np.ndarray, valid: np.ndarray,
                  width: int, height: int, tile: int, chunk: int, capacity: int = 0) -> Bins:
    """Build the chunk table for Gaussians at ``mean2d`` (N, 2) px with footprint ``radius`` (N,) px,
    camera ``depth`` (N,) and ``valid`` (N,) flags, on a ``width`` x ``height`` image.

    The table has ``capacity`` chunks when they suffice, else the bucket above the number needed."""
    n = len(depth)
    tx_n, ty_n = -(-width // tile), -(-height // tile)
    n_tiles = tx_n * ty_n
    ok = valid & (radius > 0) & np.all(np.isfinite(mean2d), axis=1)
    mx, my = mean2d[:, 0], mean2d[:, 1]
    x0 = np.clip(np.floor((mx - radius) / tile), 0, tx_n).astype(np.int64)
    x1 = np.clip(np.floor((mx + radius) / tile) + 1, 0, tx_n).astype(np.int64)
    y0 = np.clip(np.floor((my - radius) / tile), 0, ty_n).astype(np.int64)
    y1 = np.clip(np.floor((my + radius) / tile) + 1, 0, ty_n).astype(np.int64)
    w, h = np.where(ok, x1 - x0, 0), np.where(ok, y1 - y0, 0)
    order = np.argsort(np.where(ok, depth, np.inf), kind="stable")
    counts = (w * h)[order]
    n_pairs = int(counts.sum())
    gid = np.repeat(order, counts)
    local = np.arange(n_pairs) - np.repeat(np.cumsum(counts) - counts, counts)
    tid = (y0[gid] + local // w[gid]) * tx_n + x0[gid] + local % w[gid]
    sort = np.argsort(tid.astype(np.int32 if n_tiles < 2**31 else np.int64), kind="stable")
    gid_sorted = gid[sort]
    per_tile = np.bincount(tid, minlength=n_tiles)
    tile_start = np.cumsum(per_tile) - per_tile
    chunks = -(-per_tile // chunk)
    n_chunks = int(chunks.sum())
    k = capacity if 0 < capacity and n_chunks <= capacity else bucket(n_chunks)
    chunk_tile = np.repeat(np.arange(n_tiles), chunks)
    j = np.arange(n_chunks) - np.repeat(np.cumsum(chunks) - chunks, chunks)
    slot = j[:, None] * chunk + np.arange(chunk)[None, :]
    idx = tile_start[chunk_tile][:, None] + slot
    inside = slot < per_tile[chunk_tile][:, None]
    gauss = np.full((k, chunk), n, dtype=np.int32)
    gauss[:n_chunks] = np.where(inside, gid_sorted[np.minimum(idx, max(n_pairs - 1, 0))] if n_pairs else n, n)
    tiles = np.full(k, n_tiles, dtype=np.int32)
    tiles[:n_chunks] = chunk_tile
    first = np.zeros(k, dtype=bool)
    first[:n_chunks] = j == 0
    first[n_chunks:] = True
    return Bins(gauss, tiles, first, n_pairs, n_chunks)
