"""Differentiable rasterisation in torch, on two paths.

``"fused"`` runs everything (projection, SH, binning, compositing and their backward) in one compiled kernel
(:mod:`.fused`, the fast CPU path); ``"torch"`` projects with the shared maths (:mod:`pgc.splats.projection`,
float64 inside), bins by footprint box and composites in vectorised torch per tile with autograd: the path that
needs no compiler, and the pure-torch cross-check of the kernel. Both follow the contract of
pgc/splats/projection.py and pgc/splats/reference.py exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from pgc.splats.projection import ALPHA_MAX, ALPHA_MIN, T_MIN, expected_depth, screen_space, view_colors
from pgc.types import Camera

from . import fused


@dataclass
class Screen:
    """Screen-space Gaussians: one row per input Gaussian (culled rows have radius 0)."""

    means2d: torch.Tensor  # (N, 2)
    conics: torch.Tensor   # (N, 3)
    colors: torch.Tensor   # (N, 3)
    opacities: torch.Tensor  # (N,) world opacities times the coverage (pgc.splats.projection)
    depths: torch.Tensor   # (N,)
    radii: torch.Tensor    # (N,) detached, 0 when culled


def project(means: torch.Tensor, rotmats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
            sh: torch.Tensor, camera: Camera, sh_degree: int, near: float = 0.01) -> Screen:
    """EWA projection and SH colour of world Gaussians (computed in float64, returned in the input dtype)."""
    out_dtype, f64 = means.dtype, torch.float64
    means = means.to(f64)
    K, R, t, centre = (torch.as_tensor(x, dtype=f64) for x in (camera.K, camera.R, camera.t, camera.center))
    s = screen_space(means, rotmats.to(f64), scales.to(f64), K, R, t, near)
    colors = view_colors(means, sh.to(f64), centre, sh_degree)
    return Screen(s.mean2d.to(out_dtype), s.conic.to(out_dtype), colors.to(out_dtype),
                  (opacities * s.coverage).to(out_dtype), s.depth.to(out_dtype), s.radius.to(out_dtype))


@dataclass
class Bins:
    """Depth-sorted visible Gaussians and their tile lists."""

    order: torch.Tensor    # (M,) indices of visible Gaussians, increasing depth (ties by index)
    offsets: torch.Tensor  # (tiles + 1,) int64 into ids
    ids: torch.Tensor      # (entries,) int64 positions into ``order`` (ranks), increasing within a tile
    tiles_x: int
    tiles_y: int


@torch.no_grad()
def bin_tiles(screen: Screen, height: int, width: int, tile: int) -> Bins:
    """Assign every visible Gaussian to the tiles its footprint box covers (pixel exact, then by tile)."""
    tiles_x, tiles_y = -(-width // tile), -(-height // tile)
    r = screen.radii.double()
    m = screen.means2d.detach().double()
    # pixel index ranges whose centres lie within the box: x + 0.5 in [u - r, u + r]
    x0, x1 = torch.ceil(m[:, 0] - r - 0.5), torch.floor(m[:, 0] + r - 0.5)
    y0, y1 = torch.ceil(m[:, 1] - r - 0.5), torch.floor(m[:, 1] + r - 0.5)
    visible = (r > 0) & (x0 <= x1) & (y0 <= y1) & (x0 <= width - 1) & (x1 >= 0) & (y0 <= height - 1) & (y1 >= 0)
    x0, x1 = x0.clamp(0, width - 1), x1.clamp(0, width - 1)
    y0, y1 = y0.clamp(0, height - 1), y1.clamp(0, height - 1)
    idx = torch.nonzero(visible).squeeze(1)
    order = idx[torch.sort(screen.depths.detach()[idx], stable=True).indices]
    tx0, tx1 = (x0[order] // tile).long(), (x1[order] // tile).long()
    ty0, ty1 = (y0[order] // tile).long(), (y1[order] // tile).long()
    nx, ny = tx1 - tx0 + 1, ty1 - ty0 + 1
    counts = nx * ny
    rank = torch.repeat_interleave(torch.arange(len(order)), counts)
    start = torch.cumsum(counts, 0) - counts
    local = torch.arange(int(counts.sum())) - start[rank]
    tile_id = (ty0[rank] + local // nx[rank]) * tiles_x + tx0[rank] + local % nx[rank]
    key = tile_id * max(len(order), 1) + rank
    sorted_key = torch.sort(key).values
    ids = sorted_key % max(len(order), 1)
    per_tile = torch.bincount(sorted_key // max(len(order), 1), minlength=tiles_x * tiles_y)
    offsets = torch.zeros(tiles_x * tiles_y + 1, dtype=torch.long)
    offsets[1:] = torch.cumsum(per_tile, 0)
    return Bins(order, offsets, ids, tiles_x, tiles_y)


def composite(screen: Screen, bins: Bins, background: torch.Tensor, height: int, width: int, tile: int
              ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Vectorised per-tile compositing with autograd: colour (H, W, 3), alpha (H, W) and the alpha-weighted
    depth sum (H, W)."""
    o = bins.order
    s = {"means2d": screen.means2d[o], "conics": screen.conics[o], "colors": screen.colors[o],
         "opac": screen.opacities[o], "depths": screen.depths[o], "radii": screen.radii[o]}
    dtype = s["means2d"].dtype
    rows_c, rows_a, rows_d = [], [], []
    for ty in range(bins.tiles_y):
        tiles_c, tiles_a, tiles_d = [], [], []
        for tx in range(bins.tiles_x):
            t = ty * bins.tiles_x + tx
            ids = bins.ids[bins.offsets[t]:bins.offsets[t + 1]]
            ys = torch.arange(ty * tile, min(height, (ty + 1) * tile), dtype=dtype) + 0.5
            xs = torch.arange(tx * tile, min(width, (tx + 1) * tile), dtype=dtype) + 0.5
            cy, cx = torch.meshgrid(ys, xs, indexing="ij")
            m, q, r = s["means2d"][ids], s["conics"][ids], s["radii"][ids]
            dx = cx.reshape(-1, 1) - m[:, 0]
            dy = cy.reshape(-1, 1) - m[:, 1]
            inside = (dx.abs() <= r) & (dy.abs() <= r)
            power = -0.5 * (q[:, 0] * dx * dx + q[:, 2] * dy * dy) - q[:, 1] * dx * dy
            alpha = torch.clamp(s["opac"][ids] * torch.exp(torch.where(inside, power, torch.zeros_like(power))),
                                max=ALPHA_MAX)
            alpha = torch.where(inside & (alpha >= ALPHA_MIN), alpha, torch.zeros_like(alpha))
            with torch.no_grad():
                keep = torch.cumprod(1.0 - alpha, dim=1) >= T_MIN
            alpha = torch.where(keep, alpha, torch.zeros_like(alpha))
            trans = torch.cumprod(torch.cat([alpha.new_ones(alpha.shape[0], 1), 1.0 - alpha], 1), dim=1)
            w = alpha * trans[:, :-1]
            T = trans[:, -1]
            bg = background[ys.long(), :][:, xs.long()].reshape(-1, 3)
            shape = (len(ys), len(xs))
            tiles_c.append((w @ s["colors"][ids] + T[:, None] * bg).reshape(*shape, 3))
            tiles_a.append((1.0 - T).reshape(shape))
            tiles_d.append((w @ s["depths"][ids]).reshape(shape))
        rows_c.append(torch.cat(tiles_c, 1))
        rows_a.append(torch.cat(tiles_a, 1))
        rows_d.append(torch.cat(tiles_d, 1))
    return torch.cat(rows_c, 0), torch.cat(rows_a, 0), torch.cat(rows_d, 0)


def background_tensor(background, height: int, width: int, dtype: torch.dtype) -> torch.Tensor:
    """(H, W, 3) tensor from None (black), a (3,) colour or an (H, W, 3) image (numpy or torch)."""
    if background is None:
        return torch.zeros(height, width, 3, dtype=dtype)
    bg = torch.as_tensor(background, dtype=dtype)
    if bg.shape == (3,):
        return bg.expand(height, width, 3).contiguous()
    if tuple(bg.shape) != (height, width, 3):
        raise ValueError(f"background must be (3,) or (H, W, 3) = {(height, width, 3)}, got {tuple(bg.shape)}")
    return bg


def rasterize(means: torch.Tensor, rotmats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
              sh: torch.Tensor, camera: Camera, background=None, sh_degree: int | None = None, near: float = 0.01,
              tile: int = 16, backend: str = "fused", threads: int = 1
              ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Render world Gaussians (matrices for rotations) differentiably; returns colour, alpha, depth.

    ``backend``: "fused" (one compiled call, forward and backward) or "torch" (shared projection, pure-torch
    compositing); ``threads``: OpenMP threads of the compiled kernel.
    """
    max_degree = int(round(sh.shape[1] ** 0.5)) - 1
    degree = max_degree if sh_degree is None else min(sh_degree, max_degree)
    h, w = camera.height, camera.width
    bg = background_tensor(background, h, w, means.dtype)
    if backend == "fused":
        color, alpha, dsum = fused.FusedRasterize.apply(means, rotmats, scales, opacities, sh, camera, bg,
                                                        (degree + 1) ** 2, near, tile, threads)
    elif backend == "torch":
        screen = project(means, rotmats, scales, opacities, sh, camera, degree, near)
        color, alpha, dsum = composite(screen, bin_tiles(screen, h, w, tile), bg, h, w, tile)
    else:
        raise ValueError(f"unknown rasterisation path '{backend}' (use 'fused' or 'torch')")
    return color, alpha, expected_depth(dsum, alpha)
