"""The mesh-embedded splat fit (METHOD.md section 2) on the JAX rasteriser; same loss, schedules, settings and
model selection as the torch fit (``pgc.pipeline.settings_splats.FitSplatsSettings``), all backend-neutral
parts from :mod:`pgc.splats.fitplan`.

Initialise by uniform triangle point picking on the full mesh, optimise ``0.8 L1 + 0.2 (1 - SSIM)`` on
sRGB-encoded whole images blended over the background plus the mask loss outside the contour band, with Adam
(paper learning rates times ``lr_scale``, exponential position decay, higher SH bands 20x slower), half-resolution
images for the first ``coarse_fraction`` of the fit and the SH degree raised on a schedule; the schedules follow
the fraction of the fit done (steps, or time in auto mode). Then prune Gaussians that contribute nothing, keep
the smallest top-contribution subset and the lowest SH degree whose held-out PSNR is within a margin, optionally
drop back-facing faces' Gaussians, keep the garment's.

XLA specifics: one jitted training step serves every SH degree (higher coefficients are masked, not sliced)
and every view of one image size; chunk tables are padded to a capacity that only grows (by >= 25 %), so a
whole fit compiles a handful of times. Checkpoints are ``.npz`` files (no pickle), written atomically.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from pgc.events import Reporter
from pgc.io.atomic import atomic_path
from pgc.metrics.psnr import psnr
from pgc.pipeline.settings_splats import FitSplatsSettings
from pgc.roles.splat_renderer import SplatFit
from pgc.splats.binding import triangle_frames as np_triangle_frames
from pgc.splats.fitplan import (CURVE_POINTS, REST_LR_FACTOR, auto_lr_factor, final_keep, fingerprint, finished,
                                focus_on_garment, half_resolution, heldout_split, initial_gaussians, outside_band,
                                position_lr_at, progress, require_labels, select_model, sh_degree_at, training_view)
from pgc.splats.reference import background_image
from pgc.types import Capture, GaussianSet, Mesh, View
from pgc_jax.splat.binding import apply_frames
from pgc_jax.splat.binning import Bins, bucket
from pgc_jax.splat.losses import linear_to_srgb, ssim
from pgc_jax.splat.render import CameraArrays, camera_arrays, make_bins, render_bound

CALIBRATION_STEPS = 8
NAMES = ("means", "quats", "log_scales", "opacity_logits", "sh")
ADAM_B1, ADAM_B2, ADAM_EPS = 0.9, 0.999, 1e-15


@dataclass
class _View:
    camera: Any
    cam: CameraArrays
    image: np.ndarray          # (H, W, 3) linear, for metrics
    target: jnp.ndarray        # (H, W, 3) sRGB-encoded
    background: jnp.ndarray    # (H, W, 3) linear
    mask: jnp.ndarray          # (H, W) (zeros when the view has none)
    band: jnp.ndarray          # (H, W) mask-loss weights: 1 outside the contour band (zeros without a mask)
    coarse: "_View | None" = None  # the same view at half resolution


def _view(v: View, band: float, dtype) -> _View:
    h, w = v.camera.height, v.camera.width
    bg = jnp.asarray(background_image(v.background, h, w), dtype)
    mask = np.zeros((h, w), np.float32) if v.mask is None else v.mask
    weight = np.zeros((h, w), np.float32) if v.mask is None else outside_band(v.mask, band)
    return _View(v.camera, camera_arrays(v.camera, dtype), v.image, linear_to_srgb(jnp.asarray(v.image, dtype)), bg,
                 jnp.asarray(mask, dtype), jnp.asarray(weight, dtype))


def _prepare(capture: Capture, band: float, dtype) -> list[_View]:
    """Training arrays of every view, with a half-resolution copy for the coarse phase."""
    views = []
    for v in capture.views:
        full = _view(v, band, dtype)
        full.coarse = _view(half_resolution(v), band, dtype)
        views.append(full)
    return views


def _learning_rates(p: float, factor: float, n_sh: int, s: FitSplatsSettings) -> dict[str, Any]:
    """Adam learning rates at progress ``p``, all times ``factor``; the SH one is (n_sh, 1): the DC term at
    ``lr_other``, higher bands ``REST_LR_FACTOR`` times that."""
    lrs: dict[str, Any] = {n: factor * s.lr_other for n in NAMES}
    lrs["means"] = factor * position_lr_at(p, s)
    lrs["sh"] = np.where(np.arange(n_sh)[:, None] == 0, 1.0, REST_LR_FACTOR) * (factor * s.lr_other)
    return lrs


def _sh_mask(degree: int, dtype) -> jnp.ndarray:
    """(16,) 1 for the coefficients of degrees <= ``degree``."""
    return jnp.asarray(np.arange(16) < (degree + 1) ** 2, dtype)


@partial(jax.jit, static_argnames=("width", "height", "tile", "near"))
def _render(params, frames, parent, keep, sh_mask, cam, background, gauss, tiles, first, probe, *,
            width, height, tile, near):
    """Colour, alpha of the current model; ``keep`` (N,) scales opacities, ``probe`` (N, 3) adds to colours."""
    means, rot, scales, opac = apply_frames(*frames, parent, params["means"], params["quats"],
                                            params["log_scales"], params["opacity_logits"])
    sh = params["sh"] * sh_mask[None, : params["sh"].shape[1], None]
    color, alpha, _ = render_bound(means, rot, scales, opac * keep, sh, cam, background, gauss, tiles, first,
                                   width=width, height=height, tile=tile, sh_degree=3, near=near, color_offset=probe)
    return color, alpha


@jax.jit
def _world(params, frames, parent, keep):
    """World means, axes, scales and (``keep``-scaled) opacities of the current model."""
    means, rot, scales, opac = apply_frames(*frames, parent, params["means"], params["quats"],
                                            params["log_scales"], params["opacity_logits"])
    return means, rot, scales, opac * keep


@partial(jax.jit, static_argnames=("width", "height", "tile", "near"))
def _contributions(params, frames, parent, sh_mask, cam, background, gauss, tiles, first, *, width, height, tile,
                   near):
    """(N,) each Gaussian's summed compositing weight over the pixels of one view (d colour_r / d offset_r)."""
    n = params["means"].shape[0]
    ones = jnp.ones((n,), background.dtype)

    def red(probe):
        return _render(params, frames, parent, ones, sh_mask, cam, background, gauss, tiles, first, probe,
                       width=width, height=height, tile=tile, near=near)[0][..., 0].sum()

    return jax.grad(red)(jnp.zeros((n, 3), background.dtype))[:, 0]


@partial(jax.jit, static_argnames=("width", "height", "tile", "near", "lambda_l1", "lambda_mask"))
def _train_step(params, adam, step, lrs, frames, parent, sh_mask, cam, background, target, mask, band, gauss, tiles,
                first, *, width, height, tile, near, lambda_l1, lambda_mask):
    """One Adam step on one view; returns new params, Adam state, loss and the sRGB prediction."""
    n = params["means"].shape[0]
    ones, zero = jnp.ones((n,), target.dtype), jnp.zeros((n, 3), target.dtype)

    def loss_fn(p):
        color, alpha = _render(p, frames, parent, ones, sh_mask, cam, background, gauss, tiles, first, zero,
                               width=width, height=height, tile=tile, near=near)
        pred = linear_to_srgb(color)
        loss = lambda_l1 * jnp.mean(jnp.abs(pred - target)) + (1.0 - lambda_l1) * (1.0 - ssim(pred, target))
        return loss + lambda_mask * jnp.mean(band * jnp.abs(mask - alpha)), pred

    (loss, pred), grads = jax.value_and_grad(loss_fn, has_aux=True)(params)
    t = step + 1
    new_p, new_m, new_v = {}, {}, {}
    for name in params:
        g = grads[name]
        m = ADAM_B1 * adam["m"][name] + (1 - ADAM_B1) * g
        v = ADAM_B2 * adam["v"][name] + (1 - ADAM_B2) * g * g
        mhat, vhat = m / (1 - ADAM_B1 ** t), v / (1 - ADAM_B2 ** t)
        new_p[name] = params[name] - lrs[name] * mhat / (jnp.sqrt(vhat) + ADAM_EPS)
        new_m[name], new_v[name] = m, v
    return new_p, {"m": new_m, "v": new_v}, loss, pred


class _Model:
    """Trainable local parameters, the fixed face frames, and chunk tables padded to a growing capacity."""

    def __init__(self, renderer, g: GaussianSet, mesh: Mesh) -> None:
        o = renderer.options
        self.dtype, self.tile, self.chunk, self.near = renderer.dtype, o.tile_size, o.chunk_size, o.near
        # fixed vertices: the frames come from the float64 numpy binding (exact degenerate-face rules)
        self.frames = tuple(jnp.asarray(x, self.dtype) for x in np_triangle_frames(mesh.vertices, mesh.faces))
        self.parent = jnp.asarray(g.parent)
        self.params = {n: jnp.asarray(getattr(g, n), self.dtype) for n in NAMES}
        self.capacity: dict[tuple[int, int], int] = {}
        self.compiles = 0

    def bins(self, view: _View, keep: jnp.ndarray | None = None) -> Bins:
        keep = jnp.ones(len(self.parent), self.dtype) if keep is None else keep
        means, rot, scales, opac = _world(self.params, self.frames, self.parent, keep)
        size = (view.camera.width, view.camera.height)
        cap = self.capacity.get(size, 0)
        b = make_bins(means, rot, scales, opac, view.camera, view.cam, tile=self.tile, chunk=self.chunk,
                      near=self.near, capacity=cap)
        if b.n_chunks > cap:  # grow with head room: each new capacity is one more compilation
            self.capacity[size] = bucket(int(1.25 * b.n_chunks) + 1)
            self.compiles += 1
            return self.bins(view, keep)
        return b

    def reserve(self, views: list[_View], headroom: float = 1.25) -> None:
        """Set each image size's chunk capacity to ``headroom`` x the most any of ``views`` needs now, so that
        the training loop starts with the capacity it will mostly keep (one compilation, not one per growth)."""
        for v in views:
            b = self.bins(v)
            size = (v.camera.width, v.camera.height)
            self.capacity[size] = max(self.capacity[size], bucket(int(headroom * b.n_chunks) + 1))

    def kw(self, view: _View) -> dict[str, Any]:
        return dict(width=view.camera.width, height=view.camera.height, tile=self.tile, near=self.near)

    def render(self, view: _View, degree: int, keep: jnp.ndarray) -> tuple[np.ndarray, np.ndarray]:
        b = self.bins(view, keep)
        n = len(self.parent)
        color, alpha = _render(self.params, self.frames, self.parent, keep, _sh_mask(degree, self.dtype), view.cam,
                               view.background, b.gauss, b.tile, b.first, jnp.zeros((n, 3), self.dtype),
                               **self.kw(view))
        return np.asarray(color), np.asarray(alpha)

    def contributions(self, views: list[_View], degree: int) -> np.ndarray:
        """(N,) sum over ``views`` and pixels of each Gaussian's compositing weight ``T_i alpha_i``."""
        total = np.zeros(len(self.parent))
        for v in views:
            b = self.bins(v)
            total += np.asarray(_contributions(self.params, self.frames, self.parent, _sh_mask(degree, self.dtype),
                                               v.cam, v.background, b.gauss, b.tile, b.first, **self.kw(v)))
        return total

    def gaussians(self, keep: np.ndarray | None = None, sh_degree: int | None = None) -> GaussianSet:
        arrays = {n: np.asarray(t, np.float32) for n, t in self.params.items()}
        if sh_degree is not None:
            arrays["sh"] = arrays["sh"][:, :(sh_degree + 1) ** 2]
        g = GaussianSet(parent=np.asarray(self.parent), **arrays)
        return g if keep is None else g.select(keep)


def heldout_psnr(model: _Model, views: list[_View], degree: int, keep: np.ndarray | None = None) -> float:
    """Mean PSNR (dB, sRGB) of renders over the background against the images of ``views``."""
    if not views:
        return float("nan")
    k = jnp.ones(len(model.parent), model.dtype) if keep is None else jnp.asarray(keep, model.dtype)
    return float(np.mean([psnr(model.render(v, degree, k)[0], v.image) for v in views]))


def _save_checkpoint(path: Path, model: _Model, adam: dict, meta: dict[str, Any]) -> None:
    arrays = {f"p_{n}": np.asarray(t) for n, t in model.params.items()}
    arrays |= {f"m_{n}": np.asarray(t) for n, t in adam["m"].items()}
    arrays |= {f"v_{n}": np.asarray(t) for n, t in adam["v"].items()}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **arrays)


def _load_checkpoint(path: Path, fingerprint: str) -> tuple[dict, dict, dict] | None:
    if not path.exists():
        return None
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(z["meta"].tobytes().decode())
        if meta.get("fingerprint") != fingerprint:
            return None
        params = {n: z[f"p_{n}"] for n in NAMES}
        adam = {"m": {n: z[f"m_{n}"] for n in NAMES}, "v": {n: z[f"v_{n}"] for n in NAMES}}
    return params, adam, meta


def fit_splats(renderer, capture: Capture, mesh: Mesh, settings: FitSplatsSettings | dict | None = None,
               reporter: Reporter | None = None) -> SplatFit:
    """Fit mesh-embedded Gaussians on ``mesh`` (the full body mesh) to ``capture``; see the module docstring."""
    s = settings if isinstance(settings, FitSplatsSettings) else FitSplatsSettings.model_validate(settings or {})
    reporter = reporter or Reporter.silent()
    require_labels(mesh, s)
    capture, faces = focus_on_garment(capture, mesh, s)
    dtype = renderer.dtype
    views = _prepare(capture, s.mask_band, dtype)
    train_idx, held_idx = heldout_split(len(views), s.holdout_every)
    train, held = [views[i] for i in train_idx], [views[i] for i in held_idx]
    rng = np.random.default_rng(s.seed)
    initial = initial_gaussians(capture, mesh, s, rng, faces, [capture.views[i] for i in train_idx])
    count = len(initial)
    model = _Model(renderer, initial, mesh)
    adam = {"m": {n: jnp.zeros_like(t) for n, t in model.params.items()},
            "v": {n: jnp.zeros_like(t) for n, t in model.params.items()}}

    ckpt = Path(s.checkpoint_dir) / "fit_splats_jax.npz" if s.checkpoint_dir else None
    fp = fingerprint(capture, mesh, s, "jax")
    step, elapsed, curve, order = 0, 0.0, [], []
    lr_factor = s.lr_scale or (auto_lr_factor(s.iterations) if s.iterations else None)
    loaded = _load_checkpoint(ckpt, fp) if ckpt is not None else None
    if loaded is not None:
        params, state, meta = loaded
        model.params = {n: jnp.asarray(a, dtype) for n, a in params.items()}
        adam = {k: {n: jnp.asarray(a, dtype) for n, a in d.items()} for k, d in state.items()}
        step, elapsed, curve, order, lr_factor = (meta["step"], meta["elapsed"], meta["curve"], meta["order"],
                                                  meta["lr_factor"])
        rng.bit_generator.state = meta["rng"]

    lambdas = dict(lambda_l1=float(s.lambda_l1), lambda_mask=float(s.lambda_mask))
    n_sh = model.params["sh"].shape[1]
    model.reserve(views + [v.coarse for v in views])
    start = time.perf_counter() - elapsed
    p = progress(step, elapsed, s)
    next_curve = len(curve) / CURVE_POINTS
    calib_from = None
    with reporter.stage("fit_splats", total=s.iterations or None, gaussians=count, views=len(train),
                        heldout=len(held)) as st:
        while not finished(step, p, s):
            view = training_view(train, order, rng, p, s)
            degree = sh_degree_at(p, s)
            b = model.bins(view)
            model.params, adam, loss, pred = _train_step(
                model.params, adam, float(step), _learning_rates(p, lr_factor or 1.0, n_sh, s), model.frames,
                model.parent, _sh_mask(degree, dtype), view.cam, view.background, view.target, view.mask, view.band,
                b.gauss, b.tile, b.first, **model.kw(view), **lambdas)
            step += 1
            if not s.iterations:
                loss.block_until_ready()      # time drives the schedules: count the step's real duration
            now = time.perf_counter() - start
            p = progress(step, now, s)
            if lr_factor is None:             # auto: lr factor from the step count the budget allows
                if calib_from is None:        # the first step compiles: time the following ones
                    calib_from = (step, now)
                elif step - calib_from[0] == CALIBRATION_STEPS:
                    per_step = (now - calib_from[1]) / CALIBRATION_STEPS
                    expected = step + max(0.0, s.time_budget_s - now) / max(per_step, 1e-9)
                    lr_factor = auto_lr_factor(min(expected, s.max_iterations))
            done = finished(step, p, s)
            if step % s.log_every == 0 or done:
                train_psnr = -10.0 * math.log10(max(float(jnp.mean((pred - view.target) ** 2)), 1e-20))
                figures = {"loss": float(loss), "psnr_train_view": train_psnr, "sh_degree": sh_degree_at(p, s),
                           "progress": p}
                if p >= next_curve or done:
                    next_curve = math.floor(p * CURVE_POINTS + 1) / CURVE_POINTS
                    figures["psnr_heldout"] = heldout_psnr(model, held, figures["sh_degree"])
                    curve.append({"seconds": time.perf_counter() - start, "iteration": step,
                                  "psnr_heldout": figures["psnr_heldout"]})
                st.progress(step, s.iterations or None, **figures)
            if ckpt is not None and (step % s.checkpoint_every == 0 or done):
                _save_checkpoint(ckpt, model, adam, {
                    "fingerprint": fp, "step": step, "curve": curve, "order": order, "lr_factor": lr_factor,
                    "elapsed": time.perf_counter() - start, "rng": rng.bit_generator.state})
        fit_seconds = time.perf_counter() - start
        final_degree = sh_degree_at(p, s)
        figures: dict[str, Any] = {"iterations": step, "initial_gaussians": count, "fit_seconds": fit_seconds,
                                   "time_to_psnr": curve, "views_train": len(train), "views_heldout": len(held),
                                   "heldout_views": [v.camera.name for v in held],
                                   "lr_factor": lr_factor or 1.0, "chunk_capacity_changes": model.compiles}
        contrib = model.contributions(train, final_degree)
        keep, degree = select_model(contrib, lambda k, d: heldout_psnr(model, held, d, k), final_degree, bool(held),
                                    s, figures)
        keep = final_keep(keep, np.asarray(model.parent), mesh, [v.camera for v in train], s,
                          capture.garment_label_ids, figures)
        figures["selection_seconds"] = time.perf_counter() - start - fit_seconds
        st.record(**{k: v for k, v in figures.items() if k != "time_to_psnr"})
    return SplatFit(gaussians=model.gaussians(keep, degree), figures=figures)
