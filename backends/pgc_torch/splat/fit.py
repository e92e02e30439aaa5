"""The mesh-embedded splat fit (METHOD.md section 2) with the torch rasteriser.

Initialise by uniform triangle point picking on the full mesh (count from the image footprint), optimise
``0.8 L1 + 0.2 (1 - SSIM)`` on sRGB-encoded whole images blended over the background plus the mask loss outside
the contour band, Adam with the paper's learning rates (exponential position decay), SH degree raised on a
schedule scaled to the step count. Then model only what the scene needs: prune Gaussians that contribute
nothing, keep the smallest top-contribution subset and the lowest SH degree whose held-out PSNR is within a
margin of the full model, optionally drop Gaussians of triangles facing away from every camera, and keep the
garment's Gaussians. Resumable from checkpoints.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pgc.events import Reporter
from pgc.io.atomic import atomic_path
from pgc.metrics.psnr import psnr
from pgc.pipeline.settings_splats import FitSplatsSettings
from pgc.roles.splat_renderer import SplatFit
from pgc.splats.fitplan import (CURVE_POINTS, REST_LR_FACTOR, auto_lr_factor, final_keep, fingerprint, finished,
                                focus_on_garment, half_resolution, heldout_split, initial_gaussians, outside_band,
                                position_lr_at, progress, require_labels, select_model, sh_degree_at, training_view)
from pgc.types import Camera, Capture, GaussianSet, Mesh, View

from .binding import apply_frames, triangle_frames
from .losses import linear_to_srgb, ssim
from .rasterizer import background_tensor

CALIBRATION_STEPS = 8
NAMES = ("means", "quats", "log_scales", "opacity_logits", "sh")
PARAMS = NAMES + ("sh_rest",)


@dataclass
class _View:
    camera: Camera
    image: np.ndarray        # (H, W, 3) linear, for metrics
    target: torch.Tensor     # (H, W, 3) sRGB-encoded
    background: torch.Tensor  # (H, W, 3) linear
    mask: torch.Tensor | None
    band: torch.Tensor | None  # 1 outside the contour band
    coarse: "_View | None" = None  # the same view at half resolution


def _view(v: View, band: float) -> _View:
    bg = background_tensor(v.background, v.camera.height, v.camera.width, torch.float32)
    weight = None if v.mask is None else torch.as_tensor(outside_band(v.mask, band))
    return _View(v.camera, v.image, linear_to_srgb(torch.as_tensor(v.image)), bg,
                 None if v.mask is None else torch.as_tensor(v.mask), weight)


def _prepare(capture: Capture, band: float) -> list[_View]:
    """Training tensors of every view, with a half-resolution copy (area-averaged) for the coarse phase."""
    views = []
    for v in capture.views:
        full = _view(v, band)
        full.coarse = _view(half_resolution(v), band)
        views.append(full)
    return views


class _Model:
    """Trainable local parameters and the fixed face frames of the mesh."""

    def __init__(self, g: GaussianSet, mesh: Mesh) -> None:
        tau, R, k = triangle_frames(torch.as_tensor(mesh.vertices), torch.as_tensor(mesh.faces))
        self.frames = (tau.float(), R.float(), k.float())
        self.parent = torch.as_tensor(g.parent)
        self.params = {n: torch.tensor(getattr(g, n), dtype=torch.float32).requires_grad_(True) for n in NAMES}
        self.params["sh"] = torch.tensor(g.sh[:, :1], dtype=torch.float32).requires_grad_(True)
        self.params["sh_rest"] = torch.tensor(g.sh[:, 1:], dtype=torch.float32).requires_grad_(True)

    def world(self) -> tuple[torch.Tensor, ...]:
        p = self.params
        means, rot, scales = apply_frames(*self.frames, self.parent, p["means"], p["quats"], p["log_scales"])
        return means, rot, scales, torch.sigmoid(p["opacity_logits"]), torch.cat([p["sh"], p["sh_rest"]], 1)

    def gaussians(self, keep: np.ndarray | None = None, sh_degree: int | None = None) -> GaussianSet:
        arrays = {n: self.params[n].detach().numpy() for n in NAMES}
        arrays["sh"] = np.concatenate([arrays["sh"], self.params["sh_rest"].detach().numpy()], 1)
        if sh_degree is not None:
            arrays["sh"] = arrays["sh"][:, :(sh_degree + 1) ** 2]
        g = GaussianSet(parent=self.parent.numpy(), **arrays)
        return g if keep is None else g.select(keep)


def _render(renderer, model: _Model, view: _View, degree: int, keep: torch.Tensor | None = None):
    world = model.world()
    if keep is not None:
        world = tuple(t[keep] for t in world)
    return renderer.rasterize(*world, view.camera, view.background, degree)


def heldout_psnr(renderer, model: _Model, views: list[_View], degree: int, keep: torch.Tensor | None = None) -> float:
    """Mean PSNR (dB, sRGB) of renders over the background against the images of ``views``."""
    if not views:
        return float("nan")
    with torch.no_grad():
        return float(np.mean([psnr(_render(renderer, model, v, degree, keep)[0].numpy(), v.image) for v in views]))


def _contributions(renderer, model: _Model, views: list[_View], degree: int) -> np.ndarray:
    """(N,) sum over ``views`` and pixels of each Gaussian's compositing weight T_i alpha_i."""
    total = torch.zeros(len(model.parent))
    with torch.no_grad():
        means, rot, scales, opac, _ = model.world()
    for v in views:
        probe = torch.zeros(len(total), 1, 3).requires_grad_(True)  # DC colour only: colour = probe*C0 + 0.5
        color, _, _ = renderer.rasterize(means, rot, scales, opac, probe, v.camera, v.background, 0)
        color[..., 0].sum().backward()
        total += probe.grad[:, 0, 0] / 0.28209479177387814
    return total.numpy()


def _save_checkpoint(path: Path, state: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def fit_splats(renderer, capture: Capture, mesh: Mesh, settings: FitSplatsSettings | dict | None = None,
               reporter: Reporter | None = None) -> SplatFit:
    """Fit mesh-embedded Gaussians on ``mesh`` (the full body mesh) to ``capture``; see the module docstring.

    torch runs single-threaded meanwhile (see :func:`.renderer.single_threaded_torch`).
    """
    from .renderer import single_threaded_torch

    with single_threaded_torch():
        return _fit(renderer, capture, mesh, settings, reporter)


def _fit(renderer, capture: Capture, mesh: Mesh, settings: FitSplatsSettings | dict | None,
         reporter: Reporter | None) -> SplatFit:
    s = settings if isinstance(settings, FitSplatsSettings) else FitSplatsSettings.model_validate(settings or {})
    reporter = reporter or Reporter.silent()
    require_labels(mesh, s)
    capture, faces = focus_on_garment(capture, mesh, s)
    views = _prepare(capture, s.mask_band)
    train_ids, held_ids = heldout_split(len(views), s.holdout_every)
    train, held = [views[i] for i in train_ids], [views[i] for i in held_ids]
    rng = np.random.default_rng(s.seed)
    torch.manual_seed(s.seed)
    initial = initial_gaussians(capture, mesh, s, rng, faces, [capture.views[i] for i in train_ids])
    count = len(initial)
    model = _Model(initial, mesh)
    base_lr = {n: s.lr_other for n in NAMES[1:]} | {"sh_rest": s.lr_other * REST_LR_FACTOR}
    groups = [{"params": [model.params[n]], "lr": lr, "name": n} for n, lr in base_lr.items()]
    groups.insert(0, {"params": [model.params["means"]], "lr": s.lr_position, "name": "means"})
    optim = torch.optim.Adam(groups, eps=1e-15)

    ckpt = Path(s.checkpoint_dir) / "fit_splats.pt" if s.checkpoint_dir else None
    key = fingerprint(capture, mesh, s, "torch")
    step, elapsed, curve, order = 0, 0.0, [], []
    lr_factor = s.lr_scale or (auto_lr_factor(s.iterations) if s.iterations else None)
    if ckpt is not None and ckpt.exists():
        state = torch.load(ckpt, weights_only=True)  # tensors and plain values only: no pickle code
        if state.get("fingerprint") == key:
            with torch.no_grad():
                for n in PARAMS:
                    model.params[n].copy_(state["params"][n])
            optim.load_state_dict(state["optim"])
            step, elapsed, curve, order, lr_factor = (state["step"], state["elapsed"], state["curve"], state["order"],
                                                      state["lr_factor"])
            rng.bit_generator.state = state["rng"]

    def degree_at(p: float) -> int:
        return sh_degree_at(p, s)

    def set_lr(p: float) -> None:
        scale = lr_factor or 1.0
        optim.param_groups[0]["lr"] = scale * position_lr_at(p, s)
        for group in optim.param_groups[1:]:
            group["lr"] = scale * base_lr[group["name"]]

    start, cpu_start = time.perf_counter() - elapsed, time.process_time()
    p = progress(step, elapsed, s)
    next_curve = len(curve) / CURVE_POINTS
    with reporter.stage("fit_splats", total=s.iterations or None, gaussians=count, views=len(train),
                        heldout=len(held)) as st:
        while not finished(step, p, s):
            view = training_view(train, order, rng, p, s)
            set_lr(p)
            color, alpha, _ = _render(renderer, model, view, degree_at(p))
            pred = linear_to_srgb(color)
            loss = s.lambda_l1 * (pred - view.target).abs().mean() + (1 - s.lambda_l1) * (1 - ssim(pred, view.target))
            if view.mask is not None and s.lambda_mask > 0:
                loss = loss + s.lambda_mask * (view.band * (view.mask - alpha).abs()).mean()
            optim.zero_grad(set_to_none=True)
            loss.backward()
            optim.step()
            step += 1
            now = time.perf_counter() - start
            p = progress(step, now, s)
            if lr_factor is None and step == CALIBRATION_STEPS:
                lr_factor = auto_lr_factor(step / max(p, 1e-9))  # steps the budget is expected to allow
            done = finished(step, p, s)
            if step % s.log_every == 0 or done:
                train_psnr = -10.0 * math.log10(max(float(((pred.detach() - view.target) ** 2).mean()), 1e-20))
                figures = {"loss": float(loss.detach()), "psnr_train_view": train_psnr, "sh_degree": degree_at(p),
                           "progress": p}
                if p >= next_curve or done:
                    next_curve = math.floor(p * CURVE_POINTS + 1) / CURVE_POINTS
                    figures["psnr_heldout"] = heldout_psnr(renderer, model, held, degree_at(p))
                    curve.append({"seconds": time.perf_counter() - start, "iteration": step,
                                  "cpu_seconds_this_process": time.process_time() - cpu_start,
                                  "psnr_heldout": figures["psnr_heldout"]})
                st.progress(step, s.iterations or None, **figures)
            if ckpt is not None and (step % s.checkpoint_every == 0 or done):
                _save_checkpoint(ckpt, {"fingerprint": key, "step": step, "curve": curve,
                                        "elapsed": time.perf_counter() - start, "order": order,
                                        "lr_factor": lr_factor, "rng": rng.bit_generator.state,
                                        "optim": optim.state_dict(),
                                        "params": {n: t.detach() for n, t in model.params.items()}})
        fit_seconds = time.perf_counter() - start
        final_degree = degree_at(p)
        figures: dict[str, Any] = {"iterations": step, "initial_gaussians": count, "fit_seconds": fit_seconds,
                                   "time_to_psnr": curve, "views_train": len(train), "views_heldout": len(held),
                                   "heldout_views": [v.camera.name for v in held]}
        keep, degree = _model_selection(renderer, model, mesh, train, held, final_degree, s,
                                        capture.garment_label_ids, figures)
        figures["selection_seconds"] = time.perf_counter() - start - fit_seconds
        st.record(**{k: v for k, v in figures.items() if k != "time_to_psnr"})
    return SplatFit(gaussians=model.gaussians(keep, degree), figures=figures)


def _model_selection(renderer, model: _Model, mesh: Mesh, train: list[_View], held: list[_View], degree: int,
                     s: FitSplatsSettings, garment_ids: list[int], figures: dict[str, Any]
                     ) -> tuple[np.ndarray, int]:
    """Prune and choose count and SH degree on held-out views (pgc.splats.fitplan.select_model), then drop
    back-facing and non-garment Gaussians."""
    contrib = _contributions(renderer, model, train, degree)
    keep, degree = select_model(contrib, lambda k, d: heldout_psnr(renderer, model, held, d, torch.as_tensor(k)),
                                degree, bool(held), s, figures)
    return final_keep(keep, model.parent.numpy(), mesh, [v.camera for v in train], s, garment_ids, figures), degree
