"""Differentiable JAX rendering of world Gaussians: projection -> host binning -> jitted compositing.

:func:`render_bound` is the pure, differentiable function (``jax.grad`` flows to every Gaussian parameter,
and to mesh vertices when the inputs come from :func:`pgc.splats.binding.bind_arrays`). It takes the chunk
table of :func:`make_bins`, which is piecewise constant in the parameters and built once per view and
parameter state (the standard 3DGS treatment of culling and sorting).
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from pgc.splats.projection import expected_depth, screen_space, view_colors
from pgc.splats.quaternion import quat_to_rotmat
from pgc.types import Camera
from pgc_jax.splat.binning import Bins, bin_gaussians, binning_radius
from pgc_jax.splat.raster import composite


class CameraArrays(NamedTuple):
    K: jnp.ndarray
    R: jnp.ndarray
    t: jnp.ndarray
    center: jnp.ndarray


def camera_arrays(camera: Camera, dtype=jnp.float32) -> CameraArrays:
    """The camera's matrices as JAX arrays of ``dtype``."""
    return CameraArrays(*(jnp.asarray(x, dtype) for x in (camera.K, camera.R, camera.t, camera.center)))


rotmats_of = jax.jit(quat_to_rotmat)
"""Jitted :func:`quat_to_rotmat` (one compilation instead of one per primitive)."""


@partial(jax.jit, static_argnames=("near",))
def _footprints(means, rotmats, scales, opacities, cam: CameraArrays, near: float):
    p = screen_space(means, rotmats, scales, cam.K, cam.R, cam.t, near)
    return p.mean2d, p.depth, p.valid, p.radius, p.lambda_max, jnp.where(p.valid, opacities * p.coverage, 0.0)


def make_bins(means, rotmats, scales, opacities, camera: Camera, cam: CameraArrays, *, tile: int,
              chunk: int, near: float, capacity: int = 0, sort_depth: np.ndarray | None = None) -> Bins:
    """Chunk table of the Gaussians seen by ``camera`` (no gradient; see :mod:`binning`).

    ``sort_depth`` (N,), optional: camera depths to order by (e.g. float64 ones from the caller's inputs, so
    that near-ties are ordered as the float64 reference orders them); default the rendered float32 depths.
    """
    mean2d, depth, valid, radius, lam, opac = jax.device_get(
        _footprints(means, rotmats, scales, opacities, cam, near))
    if sort_depth is not None:
        depth = sort_depth
    rb = binning_radius(np.asarray(radius, np.float64), np.asarray(lam, np.float64), np.asarray(opac, np.float64))
    return bin_gaussians(np.asarray(mean2d, np.float64), rb, np.asarray(depth), np.asarray(valid),
                         camera.width, camera.height, tile, chunk, capacity)


@partial(jax.jit, static_argnames=("width", "height", "tile", "sh_degree", "near"))
def render_bound(means, rotmats, scales, opacities, sh, cam: CameraArrays, background, gauss, tiles, first, *,
                 width: int, height: int, tile: int, sh_degree: int, near: float, color_offset=None):
    """Render Gaussians (means (N, 3), rotmats (N, 3, 3), scales (N, 3), opacities (N,), sh (N, K, 3)).

    ``background``: (H, W, 3) or (3,). ``color_offset`` (N, 3), optional, is added to the SH colours (its
    gradient is each Gaussian's weighted pixel count: the contribution measure of pruning).
    Returns colour (H, W, 3) composited over the background, alpha (H, W) and expected depth (H, W)
    (0 where alpha is 0).
    """
    p = screen_space(means, rotmats, scales, cam.K, cam.R, cam.t, near)
    colors = view_colors(means, sh, cam.center, sh_degree)
    if color_offset is not None:
        colors = colors + color_offset
    feats = jnp.concatenate([colors, p.depth[:, None]], axis=1)
    opac = jnp.where(p.valid, opacities * p.coverage, 0.0)
    img, alpha = composite(p.mean2d, p.conic, opac, p.radius, feats, gauss, tiles, first, width, height, tile)
    color = img[..., :3] + (1.0 - alpha)[..., None] * background
    return color, alpha, expected_depth(img[..., 3], alpha)


def render_view(means, rotmats, scales, opacities, sh, camera: Camera, background, *, sh_degree: int,
                tile: int, chunk: int, near: float, sort_depth: np.ndarray | None = None):
    """Bin and render in one call (culling and ordering carry no gradient, as in every 3DGS rasteriser)."""
    cam = camera_arrays(camera, means.dtype)
    bins = make_bins(means, rotmats, scales, opacities, camera, cam, tile=tile, chunk=chunk, near=near,
                     sort_depth=sort_depth)
    return render_bound(means, rotmats, scales, opacities, sh, cam, background, bins.gauss, bins.tile, bins.first,
                        width=camera.width, height=camera.height, tile=tile, sh_degree=sh_degree, near=near)
