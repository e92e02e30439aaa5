"""The compiled splat kernel as a differentiable JAX function (``compositor = "fused"``).

XLA on the CPU compiles the dense tile-chunk compositor of :mod:`pgc_jax.splat.raster` into separate loops over
large intermediates; the per-pixel front-to-back loop with early termination, which a rasteriser needs, is not
expressible as one fused XLA kernel. :func:`fused_render` instead calls the project's compiled kernel
(:mod:`pgc.splats.fused`: projection, SH, binning, sort, compositing, and their backward) from inside the traced
program through ``jax.pure_callback``, wrapped in a ``jax.custom_vjp``: ``jit``, ``grad`` and the binding's
gradient to mesh vertices work unchanged, and the image is the torch fused path's to the byte.

The forward's workspace (depth order, tile lists) is kept for the backward in a small table keyed by a token
that travels as the residual; a backward whose token has been evicted (more than :data:`KEEP` forwards in
flight, or a backward run twice) re-runs the forward, which gives the same workspace.
"""

from __future__ import annotations

import itertools
import threading
from collections import OrderedDict
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from pgc.splats import fused as kernel
from pgc.splats.projection import expected_depth
from pgc.types import Camera

KEEP = 8
"""Forward workspaces held for their backward (each holds the tile lists of one view)."""

_workspaces: OrderedDict[int, kernel.Workspace] = OrderedDict()
_tokens = itertools.count(1)
_lock = threading.Lock()


def camera_bits(camera: Camera, near: float) -> np.ndarray:
    """The kernel's 21 float64 camera values as 42 uint32 words: a JAX array that keeps float64 precision when
    JAX's x64 mode is off."""
    return kernel.camera_vector(camera, near).view(np.uint32)


def _keep(workspace: kernel.Workspace) -> np.int32:
    with _lock:
        token = next(_tokens) % (2**31 - 1)
        _workspaces[token] = workspace
        while len(_workspaces) > KEEP:
            _workspaces.popitem(last=False)
    return np.int32(token)


def _take(token: int) -> kernel.Workspace | None:
    with _lock:
        return _workspaces.pop(int(token), None)


def _host_forward(means, rotmats, scales, opacities, sh, cam, background, *, height, width, count, tile, threads,
                  keep):
    inputs = [np.asarray(x) for x in (means, rotmats, scales, opacities, sh)]
    # inputs were checked at the role's entry (SplatRenderer.render) or made by the fit itself: no second pass
    out = kernel.forward(inputs, np.asarray(cam).view(np.float64), np.asarray(background), height, width, count,
                         tile, threads, check_finite=False)
    images = (out.color, out.alpha, out.depth_sum)
    return (*images, _keep(out.workspace)) if keep else images


def _host_backward(token, means, rotmats, scales, opacities, sh, cam, background, g_color, g_alpha, g_dsum, *,
                   height, width, count, tile, threads):
    inputs = [np.asarray(x) for x in (means, rotmats, scales, opacities, sh)]
    cam64, bg = np.asarray(cam).view(np.float64), np.asarray(background)
    workspace = _take(token)
    if workspace is None:
        workspace = kernel.forward(inputs, cam64, bg, height, width, count, tile, threads, check_finite=False).workspace
    grads = kernel.backward(workspace, inputs, cam64, bg, np.asarray(g_color), np.asarray(g_alpha),
                            np.asarray(g_dsum), count, threads)
    return tuple(grads)


def _image_shapes(dtype, height: int, width: int):
    return (jax.ShapeDtypeStruct((height, width, 3), dtype), jax.ShapeDtypeStruct((height, width), dtype),
            jax.ShapeDtypeStruct((height, width), dtype))


@partial(jax.custom_vjp, nondiff_argnums=(7, 8, 9, 10, 11))
def _render(means, rotmats, scales, opacities, sh, cam, background, height, width, count, tile, threads):
    kw = dict(height=height, width=width, count=count, tile=tile, threads=threads, keep=False)
    return jax.pure_callback(partial(_host_forward, **kw), _image_shapes(means.dtype, height, width),
                             means, rotmats, scales, opacities, sh, cam, background)


def _render_fwd(means, rotmats, scales, opacities, sh, cam, background, height, width, count, tile, threads):
    kw = dict(height=height, width=width, count=count, tile=tile, threads=threads, keep=True)
    shapes = (*_image_shapes(means.dtype, height, width), jax.ShapeDtypeStruct((), jnp.int32))
    *images, token = jax.pure_callback(partial(_host_forward, **kw), shapes, means, rotmats, scales, opacities, sh,
                                       cam, background)
    return tuple(images), (token, means, rotmats, scales, opacities, sh, cam, background)


def _render_bwd(height, width, count, tile, threads, residuals, cotangents):
    token, means, rotmats, scales, opacities, sh, cam, background = residuals
    kw = dict(height=height, width=width, count=count, tile=tile, threads=threads)
    shapes = tuple(jax.ShapeDtypeStruct(x.shape, x.dtype) for x in (means, rotmats, scales, opacities, sh))
    grads = jax.pure_callback(partial(_host_backward, **kw), shapes, token, means, rotmats, scales, opacities, sh,
                              cam, background, *cotangents)
    return (*grads, np.zeros(cam.shape, jax.dtypes.float0), jnp.zeros_like(background))


_render.defvjp(_render_fwd, _render_bwd)


def fused_render(means, rotmats, scales, opacities, sh, cam, background, *, height: int, width: int, count: int,
                 tile: int = 16, threads: int = 1):
    """Colour (H, W, 3) over ``background`` (H, W, 3), alpha (H, W) and expected depth (H, W; 0 where alpha is 0)
    of world Gaussians (means (N, 3), rotmats (N, 3, 3), scales (N, 3), opacities (N,), sh (N, K, 3), one float
    dtype); ``cam``: :func:`camera_bits`; the first ``count`` SH coefficients are used. Differentiable in the five
    Gaussian arrays."""
    color, alpha, dsum = _render(means, rotmats, scales, opacities, sh, cam, background, height, width, count, tile,
                                 threads)
    return color, alpha, expected_depth(dsum, alpha)
