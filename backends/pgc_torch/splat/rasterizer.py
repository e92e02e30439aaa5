"""Differentiable rasterisation in torch: EWA projection (float64), tile binning, depth-ordered compositing.

Backends: ``"fused"`` runs everything (projection, SH, binning, compositing and their backward) in one
compiled kernel (:mod:`.fused`); ``"cpp"`` projects and bins in torch and composites in the compiled kernel
(:mod:`.kernel`, forward and backward); ``"torch"`` composites in vectorised torch per tile (fallback and
cross-check). All follow the contract of pgc/splats/projection.py and pgc/splats/reference.py exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from pgc.splats.projection import ALPHA_MAX, ALPHA_MIN, DILATION, MAX_SCALE, T_MIN
from pgc.splats.sh import sh_basis_terms
from pgc.types import Camera

from . import fused, kernel


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
    out_dtype = means.dtype
    f64 = torch.float64
    means, rotmats, scales = means.to(f64), rotmats.to(f64), scales.to(f64)
    Rc = torch.as_tensor(camera.R, dtype=f64)
    tc = torch.as_tensor(camera.t, dtype=f64)
    K = camera.K
    pc = means @ Rc.T + tc
    x, y, z = pc.unbind(-1)
    valid = z >= near
    zs = torch.where(valid, z, torch.ones_like(z))
    u = (K[0, 0] * x + K[0, 1] * y) / zs + K[0, 2]
    v = K[1, 1] * y / zs + K[1, 2]
    zero = torch.zeros_like(zs)
    J = torch.stack([torch.stack([K[0, 0] / zs, K[0, 1] / zs, -(K[0, 0] * x + K[0, 1] * y) / zs ** 2], -1),
                     torch.stack([zero, K[1, 1] / zs, -K[1, 1] * y / zs ** 2], -1)], -2)
    M = (Rc @ rotmats) * torch.clamp(scales, 0.0, MAX_SCALE)[:, None, :]
    T = J @ M
    cov = T @ T.transpose(1, 2)
    a, b, c = cov[:, 0, 0] + DILATION, cov[:, 0, 1], cov[:, 1, 1] + DILATION
    det = a * c - b * b
    raw_det = (torch.linalg.cross(T[:, 0], T[:, 1]) ** 2).sum(-1)  # det(T T^T), exact for needles
    some = raw_det > 0  # sqrt's gradient at 0 is infinite: those Gaussians have no coverage and no gradient
    coverage = torch.where(some, torch.sqrt(torch.where(some, raw_det, torch.ones_like(raw_det)) / det),
                           torch.zeros_like(det))
    conics = torch.stack([c / det, -b / det, a / det], -1)
    with torch.no_grad():
        lam = 0.5 * (a + c) + torch.sqrt((0.5 * (a - c)) ** 2 + b * b)
        radii = torch.where(valid, torch.ceil(3.0 * torch.sqrt(lam)), torch.zeros_like(lam))
    centre = torch.as_tensor(camera.center, dtype=f64)
    d = means - centre
    d = d * torch.rsqrt(torch.clamp_min((d * d).sum(-1, keepdim=True), 1e-60))
    count = (sh_degree + 1) ** 2
    basis = torch.stack(sh_basis_terms(d[:, 0], d[:, 1], d[:, 2], sh_degree), -1).to(sh.dtype)
    colors = torch.clamp_min(torch.einsum("nk,nkc->nc", basis, sh[:, :count]) + 0.5, 0.0)
    return Screen(torch.stack([u, v], -1).to(out_dtype), conics.to(out_dtype), colors.to(out_dtype),
                  (opacities * coverage).to(out_dtype), z.to(out_dtype), radii.to(out_dtype))


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


def _ptr(t: torch.Tensor) -> int:
    return t.data_ptr()


class _CompositeKernel(torch.autograd.Function):
    """Compositing through the compiled kernel. Inputs are in rank order (contiguous)."""

    @staticmethod
    def forward(ctx, means2d, conics, colors, opac, depths, radii, offsets, ids, background, height, width,
                tile, threads):
        lib = kernel.load()
        sfx = "f64" if means2d.dtype == torch.float64 else "f32"
        args = [x.contiguous() for x in (means2d, conics, colors, opac, depths, radii)]
        bg = background.to(means2d.dtype).contiguous()
        color = torch.empty(height, width, 3, dtype=means2d.dtype)
        alpha = torch.empty(height, width, dtype=means2d.dtype)
        depth = torch.empty(height, width, dtype=means2d.dtype)
        last = torch.empty(height, width, dtype=torch.int32)
        getattr(lib, f"pgc_splat_forward_{sfx}")(*map(_ptr, args), _ptr(offsets), _ptr(ids), height, width, tile,
                                                 _ptr(bg), _ptr(color), _ptr(alpha), _ptr(depth), _ptr(last),
                                                 threads)
        ctx.save_for_backward(*args, offsets, ids, bg, alpha, last)
        ctx.config = (height, width, tile, threads, sfx)
        return color, alpha, depth

    @staticmethod
    def backward(ctx, g_color, g_alpha, g_depth):
        *args, offsets, ids, bg, alpha, last = ctx.saved_tensors
        height, width, tile, threads, sfx = ctx.config
        n = args[0].shape[0]
        grad = torch.empty(n, 10, dtype=args[0].dtype)
        dt = args[0].dtype
        gc, ga, gd = (torch.zeros_like(x) if g is None else g.to(dt).contiguous()
                      for g, x in ((g_color, bg), (g_alpha, alpha), (g_depth, alpha)))
        getattr(kernel.load(), f"pgc_splat_backward_{sfx}")(
            *map(_ptr, args), _ptr(offsets), _ptr(ids), height, width, tile, n, _ptr(bg), _ptr(alpha), _ptr(last),
            _ptr(gc), _ptr(ga), _ptr(gd), _ptr(grad), threads)
        return (grad[:, 0:2], grad[:, 2:5], grad[:, 5:8], grad[:, 8], grad[:, 9], None, None, None, None, None,
                None, None, None)


def _composite_torch(s: dict[str, torch.Tensor], bins: Bins, background: torch.Tensor, height: int, width: int,
                     tile: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Vectorised per-tile compositing with autograd (fallback and cross-check of the kernel)."""
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


def composite(screen: Screen, bins: Bins, background: torch.Tensor, height: int, width: int, tile: int,
              backend: str = "cpp", threads: int = 1) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Colour (H, W, 3), alpha (H, W) and expected depth (H, W; 0 where alpha is 0)."""
    o = bins.order
    s = {"means2d": screen.means2d[o], "conics": screen.conics[o], "colors": screen.colors[o],
         "opac": screen.opacities[o], "depths": screen.depths[o], "radii": screen.radii[o]}
    if backend == "cpp":
        color, alpha, dsum = _CompositeKernel.apply(s["means2d"], s["conics"], s["colors"], s["opac"], s["depths"],
                                                    s["radii"], bins.offsets, bins.ids, background, height,
                                                    width, tile, threads)
    elif backend == "torch":
        color, alpha, dsum = _composite_torch(s, bins, background.to(screen.means2d.dtype), height, width, tile)
    else:
        raise ValueError(f"unknown compositing backend '{backend}' (use 'fused', 'cpp' or 'torch')")
    return color, alpha, expected_depth(dsum, alpha)


def expected_depth(dsum: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """Weighted depth sum / alpha, 0 where alpha is 0."""
    positive = alpha > 0
    return torch.where(positive, dsum / torch.where(positive, alpha, torch.ones_like(alpha)), torch.zeros_like(alpha))


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
              tile: int = 16, backend: str = "cpp", threads: int = 1
              ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Render world Gaussians (matrices for rotations) differentiably; returns colour, alpha, depth.

    ``backend``: "fused" (one compiled call, forward and backward), "cpp" or "torch" (compositing path after
    the torch projection); ``threads``: OpenMP threads of the compiled kernels.
    """
    max_degree = int(round(sh.shape[1] ** 0.5)) - 1
    degree = max_degree if sh_degree is None else min(sh_degree, max_degree)
    if backend == "fused":
        h, w = camera.height, camera.width
        bg = background_tensor(background, h, w, means.dtype)
        color, alpha, dsum = fused.FusedRasterize.apply(means, rotmats, scales, opacities, sh, camera, bg,
                                                        (degree + 1) ** 2, near, tile, threads)
        return color, alpha, expected_depth(dsum, alpha)
    screen = project(means, rotmats, scales, opacities, sh, camera, degree, near)
    h, w = camera.height, camera.width
    bins = bin_tiles(screen, h, w, tile)
    bg = background_tensor(background, h, w, means.dtype)
    return composite(screen, bins, bg, h, w, tile, backend, threads)
