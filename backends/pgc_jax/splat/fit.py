"""The JAX arrays of the splat fit: :class:`JaxFitBackend` for the loop of :mod:`pgc.splats.fit`.

XLA specifics: one jitted training step serves every SH degree (higher coefficients are masked, not sliced),
every view whose size rounds up to the same multiple of the tile (views are zero-padded to it; the loss counts
their own pixels only) and every loss weight and Adam epsilon (traced values, not compile-time constants: settings
that differ in them share one compilation); chunk tables are padded to a capacity that only grows (by >= 25 %),
reserved for every view before the first step, so a whole fit compiles a handful of times. The Adam update is the
shared :func:`pgc.splats.fit.adam_update`, traced into the step.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from typing import Any, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from pgc.io.images import linear_to_srgb
from pgc.metrics.ssim import ssim_map
from pgc.roles.splat_renderer import FitSplatsSettings
from pgc.splats.binding import apply_frames, triangle_frames
from pgc.splats.fused import DEFAULT_TILE
from pgc.splats.sh import SH_C0
from pgc.splats.fit import PARAMETERS, FitBackend, FitView, adam_update
from pgc.types import Camera, GaussianSet, Mesh
from pgc_jax.splat.binning import Bins, bucket
from pgc_jax.splat.fused import camera_bits, fused_render
from pgc_jax.splat.render import CameraArrays, camera_arrays, make_bins, render_bound


@dataclass
class _Arrays:
    """A view's arrays."""

    camera: Camera           # the view's camera, its image size padded to a multiple of the tile
    size: tuple[int, int]    # the view's own (H, W)
    cam: CameraArrays | jnp.ndarray  # the XLA compositor's arrays, or the fused kernel's camera bits
    target: jnp.ndarray      # (H, W, 3) sRGB, zero outside the view
    background: jnp.ndarray  # (H, W, 3) linear
    mask: jnp.ndarray        # (H, W) (zeros when the view has none)
    band: jnp.ndarray        # (H, W) mask-loss weights (zeros without a mask)
    inside: jnp.ndarray      # (H, W) 1 on the view's own pixels, 0 on the padding


def _sh_mask(degree: int, dtype) -> jnp.ndarray:
    """(16,) 1 for the coefficients of degrees <= ``degree``."""
    return jnp.asarray(np.arange(16) < (degree + 1) ** 2, dtype)


@partial(jax.jit, static_argnames=("width", "height", "tile", "near", "threads"))
def _render(params, frames, parent, keep, sh_mask, cam, background, bins, probe, *, width, height, tile, near,
            threads):
    """Colour, alpha of the current model; ``keep`` (N,) scales opacities, ``probe`` (N, 3) adds to colours.

    ``bins`` None: the fused kernel (``cam``: :func:`pgc_jax.splat.fused.camera_bits`; ``probe`` must be None);
    else the XLA compositor on the chunk table ``(gauss, tiles, first)`` (``cam``: :class:`CameraArrays`)."""
    means, rot, scales, opac = apply_frames(*frames, parent, params["means"], params["quats"],
                                            params["log_scales"], params["opacity_logits"])
    sh = params["sh"] * sh_mask[None, : params["sh"].shape[1], None]
    if bins is None:
        color, alpha, _ = fused_render(means, rot, scales, opac * keep, sh, cam, background, height=height,
                                       width=width, count=sh.shape[1], tile=DEFAULT_TILE, threads=threads)
        return color, alpha
    color, alpha, _ = render_bound(means, rot, scales, opac * keep, sh, cam, background, *bins,
                                   width=width, height=height, tile=tile, sh_degree=3, near=near, color_offset=probe)
    return color, alpha


@jax.jit
def _world(params, frames, parent, keep):
    """World means, axes, scales and (``keep``-scaled) opacities of the current model."""
    means, rot, scales, opac = apply_frames(*frames, parent, params["means"], params["quats"],
                                            params["log_scales"], params["opacity_logits"])
    return means, rot, scales, opac * keep


@partial(jax.jit, static_argnames=("width", "height", "tile", "near", "threads"))
def _contributions(params, frames, parent, sh_mask, cam, background, inside, bins, *, width, height, tile, near,
                   threads):
    """(N,) each Gaussian's summed compositing weight over the ``inside`` pixels of one view
    (d colour_r / d offset_r)."""
    n = params["means"].shape[0]
    zero = jnp.zeros((n, 3), background.dtype)
    if bins is None:  # the fused kernel: colour = C0 probe + 0.5 from a DC-only SH, as the torch fit does
        means, rot, scales, opac = apply_frames(*frames, parent, params["means"], params["quats"],
                                                params["log_scales"], params["opacity_logits"])

        def red(probe):
            color, _, _ = fused_render(means, rot, scales, opac, probe[:, None, :], cam, background, height=height,
                                       width=width, count=1, tile=DEFAULT_TILE, threads=threads)
            return (inside * color[..., 0]).sum()

        return jax.grad(red)(zero)[:, 0] / SH_C0
    ones = jnp.ones((n,), background.dtype)

    def red(probe):
        color = _render(params, frames, parent, ones, sh_mask, cam, background, bins, probe, width=width,
                        height=height, tile=tile, near=near, threads=threads)[0][..., 0]
        return (inside * color).sum()

    return jax.grad(red)(zero)[:, 0]


def _weights(s: FitSplatsSettings, dtype) -> dict[str, jnp.ndarray]:
    """The loss weights and Adam epsilon of ``s`` as traced scalars (``ssim``: 1 - lambda_l1, rounded once, as a
    Python float would be)."""
    return {k: jnp.asarray(v, dtype) for k, v in (("l1", s.lambda_l1), ("ssim", 1.0 - s.lambda_l1),
                                                  ("mask", s.lambda_mask), ("surface", s.lambda_surface),
                                                  ("opacity", s.lambda_opacity), ("adam_eps", s.adam_eps))}


@partial(jax.jit, static_argnames=("width", "height", "tile", "near", "threads"))
def _train_step(params, adam, t, lrs, frames, parent, sh_mask, cam, background, target, mask, band, inside, bins,
                weights, *, width, height, tile, near, threads):
    """One Adam step (number ``t`` >= 1) on one view with the :func:`_weights` ``weights``; returns new params, Adam
    state, loss and the sRGB MSE. A zero weight adds an exact zero to the loss and its gradients. Means are over
    the ``inside`` pixels; the SSIM's zero padding at the view's border is the zeroed padding of the image."""
    n = params["means"].shape[0]
    ones = jnp.ones((n,), target.dtype)
    probe = None if bins is None else jnp.zeros((n, 3), target.dtype)
    w = weights
    pixels = inside.sum()

    def loss_fn(p):
        color, alpha = _render(p, frames, parent, ones, sh_mask, cam, background, bins, probe, width=width,
                               height=height, tile=tile, near=near, threads=threads)
        pred = jnp.where(inside[..., None] > 0, linear_to_srgb(color), 0.0)
        ssim = ssim_map(pred, target, "zeros")
        loss = (w["l1"] * jnp.abs(pred - target).sum() / (3 * pixels)
                + w["ssim"] * (1.0 - (inside[..., None] * ssim).sum() / (3 * pixels)))
        surface = w["surface"] * jnp.mean(p["means"][:, 1] ** 2)
        fade = w["opacity"] * jnp.mean(jax.nn.sigmoid(p["opacity_logits"]))
        return loss + w["mask"] * (band * jnp.abs(mask - alpha)).sum() / pixels + surface + fade, pred

    (loss, pred), grads = jax.value_and_grad(loss_fn, has_aux=True)(params)
    new_p, new_m, new_v = {}, {}, {}
    for name in params:
        new_p[name], new_m[name], new_v[name] = adam_update(params[name], grads[name], adam["m"][name],
                                                            adam["v"][name], t, lrs[name], w["adam_eps"])
    return new_p, {"m": new_m, "v": new_v}, loss, ((pred - target) ** 2).sum() / (3 * pixels)


class JaxFitBackend(FitBackend):
    """JAX arrays, jitted steps and chunk tables padded to a growing capacity, for the shared fit loop."""

    name = "jax"

    def __init__(self, renderer: Any) -> None:
        o = renderer.options
        self.dtype, self.tile, self.chunk, self.near = renderer.dtype, o.tile_size, o.chunk_size, o.near
        self.fused, self.threads = renderer.compositor == "fused", renderer.threads
        self.capacity: dict[tuple[int, int], int] = {}
        self.compiles = 0

    def start(self, initial: GaussianSet, mesh: Mesh) -> None:
        # fixed vertices: the frames come from the float64 numpy binding (exact degenerate-face rules)
        self.frames = tuple(jnp.asarray(x, self.dtype) for x in triangle_frames(mesh.vertices, mesh.faces))
        self.parent = jnp.asarray(initial.parent)
        self.params = {n: jnp.asarray(getattr(initial, n), self.dtype) for n in PARAMETERS}
        self.adam = {"m": {n: jnp.zeros_like(t) for n, t in self.params.items()},
                     "v": {n: jnp.zeros_like(t) for n, t in self.params.items()}}

    def prepare(self, view: FitView) -> _Arrays:
        """The view's arrays, zero-padded to the next multiple of the compositor's tile: the tile grid is the
        view's own, and views of nearby sizes share one compilation."""
        h, w = view.camera.height, view.camera.width
        tile = DEFAULT_TILE if self.fused else self.tile
        size = (-(-h // tile) * tile, -(-w // tile) * tile)
        camera = replace(view.camera, height=size[0], width=size[1])

        def padded(x: np.ndarray | None) -> jnp.ndarray:
            x = np.zeros((h, w), np.float32) if x is None else np.asarray(x)
            out = np.zeros(size + x.shape[2:], x.dtype)
            out[:h, :w] = x
            return jnp.asarray(out, self.dtype)

        cam = jnp.asarray(camera_bits(camera, self.near)) if self.fused else camera_arrays(camera, self.dtype)
        return _Arrays(camera, (h, w), cam, padded(view.target), padded(view.background), padded(view.mask),
                       padded(view.band), padded(np.ones((h, w), np.float32)))

    def _keep(self, keep: np.ndarray | None) -> jnp.ndarray:
        return jnp.ones(len(self.parent), self.dtype) if keep is None else jnp.asarray(keep, self.dtype)

    def _bins(self, view: _Arrays, keep: jnp.ndarray | None = None) -> tuple | None:
        """The XLA compositor's chunk table (gauss, tiles, first) of the view; None for the fused kernel."""
        if self.fused:
            return None
        b = self._chunks(view, keep)
        return b.gauss, b.tile, b.first

    def _chunks(self, view: _Arrays, keep: jnp.ndarray | None = None) -> Bins:
        keep = self._keep(None) if keep is None else keep
        means, rot, scales, opac = _world(self.params, self.frames, self.parent, keep)
        size = (view.camera.width, view.camera.height)
        cap = self.capacity.get(size, 0)
        b = make_bins(means, rot, scales, opac, view.camera, view.cam, tile=self.tile, chunk=self.chunk,
                      near=self.near, capacity=cap)
        if b.n_chunks > cap:  # grow with head room: each new capacity is one more compilation
            self.capacity[size] = bucket(int(1.25 * b.n_chunks) + 1)
            self.compiles += 1
            return self._chunks(view, keep)
        return b

    def reserve(self, handles: Sequence[_Arrays]) -> None:
        """Each image size's chunk capacity at 1.25 x the most any view needs now (one compilation, not one per
        growth); the fused kernel needs none."""
        for h in handles if not self.fused else ():
            b = self._chunks(h)
            size = (h.camera.width, h.camera.height)
            self.capacity[size] = max(self.capacity[size], bucket(int(1.25 * b.n_chunks) + 1))

    def _kw(self, view: _Arrays) -> dict[str, Any]:
        return dict(width=view.camera.width, height=view.camera.height, tile=self.tile, near=self.near,
                    threads=self.threads)

    def step(self, handle: _Arrays, degree: int, lrs: dict[str, Any], t: int,
             s: FitSplatsSettings) -> tuple[jax.Array, jax.Array]:
        self.params, self.adam, loss, mse = _train_step(
            self.params, self.adam, float(t), lrs, self.frames, self.parent, _sh_mask(degree, self.dtype),
            handle.cam, handle.background, handle.target, handle.mask, handle.band, handle.inside, self._bins(handle),
            _weights(s, self.dtype), **self._kw(handle))
        return loss, mse

    def render(self, handle: _Arrays, degree: int, keep: np.ndarray | None = None) -> np.ndarray:
        k = self._keep(keep)
        bins = self._bins(handle, k)
        probe = None if bins is None else jnp.zeros((len(self.parent), 3), self.dtype)
        color, _ = _render(self.params, self.frames, self.parent, k, _sh_mask(degree, self.dtype), handle.cam,
                           handle.background, bins, probe, **self._kw(handle))
        h, w = handle.size
        return np.asarray(color)[:h, :w]

    def contributions(self, handles: Sequence[_Arrays], degree: int) -> np.ndarray:
        total = np.zeros(len(self.parent))
        for h in handles:
            total += np.asarray(_contributions(self.params, self.frames, self.parent, _sh_mask(degree, self.dtype),
                                               h.cam, h.background, h.inside, self._bins(h), **self._kw(h)))
        return total

    def state(self) -> dict[str, np.ndarray]:
        out = {"parent": np.asarray(self.parent).copy()} | {f"p_{n}": np.asarray(t) for n, t in self.params.items()}
        out |= {f"m_{n}": np.asarray(t) for n, t in self.adam["m"].items()}
        return out | {f"v_{n}": np.asarray(t) for n, t in self.adam["v"].items()}

    def load_state(self, arrays: dict[str, np.ndarray]) -> None:
        self.parent = jnp.asarray(arrays["parent"])
        self.params = {n: jnp.asarray(arrays[f"p_{n}"], self.dtype) for n in PARAMETERS}
        self.adam = {k: {n: jnp.asarray(arrays[f"{k}_{n}"], self.dtype) for n in PARAMETERS} for k in ("m", "v")}

    def gaussians(self) -> GaussianSet:
        return GaussianSet(parent=np.asarray(self.parent), **{n: np.asarray(t, np.float32)
                                                               for n, t in self.params.items()})

    def figures(self) -> dict[str, Any]:
        return {"compositor": "fused" if self.fused else "xla", "chunk_capacity_changes": self.compiles}
