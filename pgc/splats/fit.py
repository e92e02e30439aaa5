"""The mesh-embedded splat fit, written once: every splat renderer runs this loop and supplies its array steps.

The loop (the paper's optimisation, with the choices this project adds):
- initial Gaussians by uniform point picking on the (garment-focused) faces of the full mesh, count from the
  image footprint, DC colour from the training views (:func:`pgc.splats.fitplan.initial_gaussians`);
- every ``holdout_every``-th view held out; the training views come in random epochs, at half resolution
  during the first ``coarse_fraction`` of the schedule;
- one Adam step per view on ``lambda_l1 L1 + (1 - lambda_l1)(1 - SSIM)`` of sRGB images over the background
  plus ``lambda_mask`` x the alpha-vs-mask L1 outside the contour band (the backend's :meth:`FitBackend.step`);
  learning rates of the paper times ``sqrt(30000 / iterations)`` (clamped to [1, 10]), the position lr decayed
  exponentially, SH bands above the DC term 20x slower, the SH degree raised on the paper's schedule scaled to
  ``iterations``;
- every ``converge_every`` steps the held-out PSNR is measured (the time-to-PSNR curve); once past
  ``converge_after`` of the schedule, the fit stops when ``converge_patience`` evaluations in a row raised the
  best held-out PSNR by less than ``converge_db``, else after ``iterations`` steps. A capture too small to hold a
  view out (fewer than twice ``holdout_every`` views) is tested the same way on the training views' PSNR (a
  plateau of the fit itself; the curve's points then carry ``psnr_train``). Nothing depends on the clock: the
  same inputs give the same fit;
- then the model only the scene needs: prune Gaussians that contribute nothing, keep the smallest
  top-contribution subset and the lowest SH degree within ``margin_db`` of the full model on the held-out views,
  optionally drop Gaussians of back-facing faces, keep the garment's (:mod:`pgc.splats.fitplan`);
- resumable: a checkpoint (``.npz``: parameters, Adam moments, schedule state; no pickle) every
  ``checkpoint_every`` steps, reused when its fingerprint matches.

Figures (every backend records the same keys): ``iterations``, ``stopped`` ("converged" or "iterations"),
``initial_gaussians``, ``fit_seconds``, ``selection_seconds``, ``time_to_psnr`` (list of {iteration, seconds,
psnr_heldout}), ``views_train``, ``views_heldout``, ``lr_factor``, the selection's figures
(:func:`pgc.splats.fitplan.select_model`, :func:`~pgc.splats.fitplan.final_keep`) and ``backend`` (a dict of
the backend's own figures).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ContextManager, Sequence

import numpy as np

from pgc.events import Reporter
from pgc.io.atomic import atomic_path
from pgc.io.images import linear_to_srgb
from pgc.metrics.psnr import psnr
from pgc.roles.splat_renderer import FitSplatsSettings, SplatFit
from pgc.splats.fitplan import (REST_LR_FACTOR, auto_lr_factor, final_keep, fingerprint, focus_on_garment,
                                half_resolution, heldout_split, initial_gaussians, outside_band, position_lr_at,
                                require_labels, select_model, sh_degree_at)
from pgc.splats.reference import background_image
from pgc.types import Camera, Capture, GaussianSet, Mesh, View

PARAMETERS = ("means", "quats", "log_scales", "opacity_logits", "sh")
"""The optimised arrays, named as the fields of :class:`pgc.types.GaussianSet` (``sh`` holds every band)."""
RELOCATION_JITTER = 0.5
"""A relocated copy's local position moves by a normal sample of this many of its own local scales, so copies
of one Gaussian do not coincide (coincident copies get equal gradients and never separate)."""
ADAM_B1, ADAM_B2, ADAM_EPS = 0.9, 0.999, 1e-15


@dataclass
class FitView:
    """One view as the fit uses it (numpy; a backend converts it once in :meth:`FitBackend.prepare`)."""

    camera: Camera
    image: np.ndarray            # (H, W, 3) linear RGB, for metrics
    target: np.ndarray           # (H, W, 3) sRGB-encoded image, the loss's target
    background: np.ndarray       # (H, W, 3) linear RGB the renders are composited over
    mask: np.ndarray | None      # (H, W) foreground coverage in [0, 1]
    band: np.ndarray | None      # (H, W) mask-loss weights: 1 outside the contour band, 0 inside it

    @classmethod
    def of(cls, view: View, band: float) -> "FitView":
        h, w = view.camera.height, view.camera.width
        image = np.asarray(view.image, np.float32)
        return cls(view.camera, image, linear_to_srgb(image), background_image(view.background, h, w).astype(np.float32),
                   None if view.mask is None else np.asarray(view.mask, np.float32),
                   None if view.mask is None else outside_band(view.mask, band))


@dataclass
class _Prepared:
    """A view with its backend handle, and its half-resolution twin for the coarse phase."""

    view: FitView
    handle: Any
    coarse: "_Prepared | None" = None


class FitBackend(ABC):
    """What a splat renderer supplies to :func:`fit_splats`: its arrays, one optimiser step and renders.

    The backend holds the current parameters (:data:`PARAMETERS`) and their Adam moments; the loop holds
    everything else (schedule, views, selection, checkpoints, figures).
    """

    name: str = "backend"

    def session(self) -> ContextManager[None]:
        """A context the whole fit runs in (e.g. the backend's thread settings)."""
        return contextlib.nullcontext()

    @abstractmethod
    def start(self, initial: GaussianSet, mesh: Mesh) -> None:
        """Take the initial parameters (zero Adam moments) and the fixed face frames of ``mesh``."""

    @abstractmethod
    def prepare(self, view: FitView) -> Any:
        """The backend's arrays of ``view`` (converted once, reused by every step and render)."""

    def reserve(self, handles: Sequence[Any]) -> None:
        """Called once with every prepared view before the first step (e.g. to size buffers)."""

    @abstractmethod
    def step(self, handle: Any, degree: int, lrs: dict[str, Any], t: int, s: FitSplatsSettings) -> tuple[Any, Any]:
        """One Adam step (:func:`adam_update`, step number ``t`` >= 1) on the loss of one view rendered at SH
        ``degree``; ``lrs`` per parameter (``sh``: (K, 1), one per coefficient). Returns (loss, MSE of the sRGB
        prediction) as scalars that ``float()`` accepts (read only when logged)."""

    @abstractmethod
    def render(self, handle: Any, degree: int, keep: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 3) linear colour of the current model over the view's background; ``keep`` (N,) bool selects."""

    @abstractmethod
    def contributions(self, handles: Sequence[Any], degree: int) -> np.ndarray:
        """(N,) each Gaussian's compositing weight ``T_i alpha_i`` summed over the pixels of ``handles``."""

    @abstractmethod
    def state(self) -> dict[str, np.ndarray]:
        """Parameters and Adam moments as numpy: ``p_NAME``, ``m_NAME``, ``v_NAME`` for NAME in PARAMETERS, and
        ``parent`` (N,) the parent faces."""

    @abstractmethod
    def load_state(self, arrays: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`state` returned."""

    @abstractmethod
    def gaussians(self) -> GaussianSet:
        """The current model (every SH band)."""

    def figures(self) -> dict[str, Any]:
        """The backend's own figures (recorded under ``backend``)."""
        return {}


def adam_update(p: Any, g: Any, m: Any, v: Any, t: int, lr: Any, eps: float = ADAM_EPS) -> tuple[Any, Any, Any]:
    """One bias-corrected Adam update (b1 0.9, b2 0.999, ``eps`` added to the root of the second moment) of
    arrays of any library with arithmetic operators (numpy, torch, JAX); returns new (p, m, v)."""
    m = ADAM_B1 * m + (1.0 - ADAM_B1) * g
    v = ADAM_B2 * v + (1.0 - ADAM_B2) * g * g
    m_hat, v_hat = m / (1.0 - ADAM_B1 ** t), v / (1.0 - ADAM_B2 ** t)
    return p - lr * m_hat / (v_hat ** 0.5 + eps), m, v


def learning_rates(p: float, factor: float, n_sh: int, s: FitSplatsSettings) -> dict[str, Any]:
    """Adam learning rates at schedule fraction ``p``, all times ``factor``: the decayed position lr,
    ``lr_other`` for the rest, and for ``sh`` a (n_sh, 1) array: the DC term at ``lr_other``, higher bands
    ``REST_LR_FACTOR`` times that."""
    lrs: dict[str, Any] = {n: factor * s.lr_other for n in PARAMETERS}
    lrs["means"] = factor * position_lr_at(p, s)
    lrs["sh"] = (np.where(np.arange(n_sh)[:, None] == 0, 1.0, REST_LR_FACTOR) * (factor * s.lr_other)).astype(
        np.float32)
    return lrs


def relocate(state: dict[str, np.ndarray], rng: np.random.Generator, threshold: float) -> int:
    """Move every dead Gaussian (opacity below ``threshold``) onto a live one sampled with probability
    proportional to opacity (3DGS-MCMC relocation), in place on a :meth:`FitBackend.state` dict; returns how
    many moved. A source drawn ``c - 1`` times and its copies all get the opacity ``1 - (1 - o)^(1 / c)``, so
    their stack composites to the source's ``o``; copies take the source's parent, rotation, scale and colour,
    and its local position jittered by :data:`RELOCATION_JITTER` local scales; every changed Gaussian restarts
    with zero Adam moments. The count never changes."""
    logits = state["p_opacity_logits"].astype(np.float64)
    opacity = 0.5 * (1.0 + np.tanh(0.5 * logits))
    dead = np.flatnonzero(opacity < threshold)
    live = np.flatnonzero(opacity >= threshold)
    if dead.size == 0 or live.size == 0:
        return 0
    sources = rng.choice(live, size=dead.size, p=opacity[live] / opacity[live].sum())
    drawn = np.unique(sources)
    copies = np.bincount(sources, minlength=len(opacity))[drawn] + 1
    logits = state["p_opacity_logits"].copy()
    logits[drawn] = _logit(1.0 - (1.0 - opacity[drawn]) ** (1.0 / copies))
    state["p_opacity_logits"] = logits
    state["parent"] = state["parent"].copy()
    state["parent"][dead] = state["parent"][sources]
    for name in PARAMETERS:
        values = state[f"p_{name}"].copy()
        values[dead] = values[sources]
        state[f"p_{name}"] = values
    jitter = rng.standard_normal(state["p_means"][dead].shape) * np.exp(state["p_log_scales"][dead])
    state["p_means"][dead] += (RELOCATION_JITTER * jitter).astype(state["p_means"].dtype)
    touched = np.concatenate([dead, drawn])
    for name in PARAMETERS:
        for moment in ("m", "v"):
            values = state[f"{moment}_{name}"].copy()
            values[touched] = 0
            state[f"{moment}_{name}"] = values
    return int(dead.size)


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(p, 1e-7, 1.0 - 1e-7)
    return (np.log(p) - np.log1p(-p)).astype(np.float32)


def converged(evaluations: list[float], s: FitSplatsSettings) -> bool:
    """Whether the last ``converge_patience`` held-out PSNRs raised the best one by less than ``converge_db``."""
    n = s.converge_patience
    if s.converge_db <= 0 or len(evaluations) <= n:
        return False
    return max(evaluations[-n:]) - max(evaluations[:-n]) < s.converge_db


def training_view(train: Sequence[Any], order: list[int], rng: np.random.Generator, coarse: bool) -> Any:
    """The next training view: random permutations (epochs); ``order`` (the rest of the current epoch, consumed
    from the end, refilled from ``rng``) lives in checkpoints. With ``coarse``, the view's half-resolution twin
    (its ``coarse``) when it has one."""
    if not order:
        order.extend(int(i) for i in rng.permutation(len(train)))
    view = train[order.pop()]
    return view.coarse if coarse and view.coarse is not None else view


def views_psnr(backend: FitBackend, views: Sequence[_Prepared], degree: int,
               keep: np.ndarray | None = None) -> float:
    """Mean PSNR (dB, sRGB) of renders over the background against the images of ``views``."""
    if not views:
        return float("nan")
    return float(np.mean([psnr(backend.render(v.handle, degree, keep), v.view.image) for v in views]))


def _save_checkpoint(path: Path, backend: FitBackend, meta: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **backend.state())


def _load_checkpoint(path: Path, key: str) -> tuple[dict[str, np.ndarray], dict[str, Any]] | None:
    if not path.is_file():
        return None
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(z["meta"].tobytes().decode())
        if meta.get("fingerprint") != key:
            return None
        return {k: z[k] for k in z.files if k != "meta"}, meta


def fit_splats(backend: FitBackend, capture: Capture, mesh: Mesh, settings: FitSplatsSettings | dict | None = None,
               reporter: Reporter | None = None) -> SplatFit:
    """Fit mesh-embedded Gaussians on ``mesh`` (the full labelled body mesh) to ``capture`` with ``backend``;
    see the module docstring."""
    s = settings if isinstance(settings, FitSplatsSettings) else FitSplatsSettings.model_validate(settings or {})
    reporter = reporter or Reporter.silent()
    require_labels(mesh, s)
    with backend.session():
        return _fit(backend, capture, mesh, s, reporter)


def _fit(backend: FitBackend, capture: Capture, mesh: Mesh, s: FitSplatsSettings, reporter: Reporter) -> SplatFit:
    capture, faces = focus_on_garment(capture, mesh, s)
    train_ids, held_ids = heldout_split(len(capture.views), s.holdout_every)
    rng = np.random.default_rng(s.seed)
    initial = initial_gaussians(capture, mesh, s, rng, faces, [capture.views[i] for i in train_ids])
    backend.start(initial, mesh)
    views = []
    for v in capture.views:
        full = FitView.of(v, s.mask_band)
        coarse = FitView.of(half_resolution(v), s.mask_band) if s.coarse_fraction > 0 else None
        views.append(_Prepared(full, backend.prepare(full),
                               None if coarse is None else _Prepared(coarse, backend.prepare(coarse))))
    train, held = [views[i] for i in train_ids], [views[i] for i in held_ids]
    probe, probe_key = (held, "psnr_heldout") if held else (train, "psnr_train")  # the convergence test's views
    backend.reserve([v.handle for v in views] + [v.coarse.handle for v in views if v.coarse is not None])

    ckpt = Path(s.checkpoint_dir) / f"fit_splats_{backend.name}.npz" if s.checkpoint_dir else None
    key = fingerprint(capture, mesh, s, backend.name)
    step, elapsed, curve, order, evaluations = 0, 0.0, [], [], []
    loaded = _load_checkpoint(ckpt, key) if ckpt is not None else None
    if loaded is not None:
        arrays, meta = loaded
        backend.load_state(arrays)
        step, elapsed, curve, order, evaluations = (meta["step"], meta["elapsed"], meta["curve"], meta["order"],
                                                    meta["evaluations"])
        rng.bit_generator.state = meta["rng"]
    lr_factor = s.lr_scale or auto_lr_factor(s.iterations)
    n_sh = initial.sh.shape[1]
    stopped = "converged" if curve and curve[-1].get("converged") else "iterations"
    relocated = loaded[1].get("relocated", 0) if loaded is not None else 0
    start = time.perf_counter() - elapsed
    with reporter.stage("fit_splats", total=s.iterations, gaussians=len(initial), views=len(train),
                        heldout=len(held)) as st:
        while step < s.iterations and stopped != "converged":
            p = step / s.iterations
            degree = sh_degree_at(p, s)
            view = training_view(train, order, rng, p < s.coarse_fraction)
            loss, mse = backend.step(view.handle, degree, learning_rates(p, lr_factor, n_sh, s), step + 1, s)
            step += 1
            if s.relocate_every and step % s.relocate_every == 0 and step < s.relocate_until * s.iterations:
                state = backend.state()
                moved = relocate(state, rng, s.relocate_opacity)
                if moved:
                    backend.load_state(state)
                relocated += moved
            done = step >= s.iterations
            evaluate = step % s.converge_every == 0 or done
            if step % s.log_every == 0 or evaluate or done:
                figures = {"loss": float(loss), "psnr_train_view": -10.0 * math.log10(max(float(mse), 1e-20)),
                           "sh_degree": degree, "progress": step / s.iterations}
                if evaluate:
                    figures[probe_key] = views_psnr(backend, probe, degree)
                    evaluations.append(figures[probe_key])
                    point = {"iteration": step, "seconds": time.perf_counter() - start,
                             probe_key: figures[probe_key]}
                    if step / s.iterations >= s.converge_after and converged(evaluations, s):
                        point["converged"] = True
                        stopped = "converged"
                    curve.append(point)
                st.progress(step, s.iterations, **figures)
            if ckpt is not None and (step % s.checkpoint_every == 0 or done or stopped == "converged"):
                _save_checkpoint(ckpt, backend, {
                    "fingerprint": key, "step": step, "curve": curve, "order": order, "evaluations": evaluations,
                    "relocated": relocated,
                    "elapsed": time.perf_counter() - start, "rng": rng.bit_generator.state})
        fit_seconds = time.perf_counter() - start
        degree = sh_degree_at(step / s.iterations, s)
        figures: dict[str, Any] = {"iterations": step, "stopped": stopped, "initial_gaussians": len(initial),
                                   "fit_seconds": fit_seconds, "time_to_psnr": curve, "views_train": len(train),
                                   "views_heldout": len(held), "lr_factor": lr_factor, "relocated": relocated}
        contrib = backend.contributions([v.handle for v in train], degree)
        keep, degree = select_model(contrib, lambda k, d: views_psnr(backend, held, d, k), degree, bool(held),
                                    s, figures)
        current = backend.gaussians()
        keep = final_keep(keep, current.parent, mesh, [v.view.camera for v in train], s, capture.garment_label_ids,
                          figures)
        figures["selection_seconds"] = time.perf_counter() - start - fit_seconds
        figures["backend"] = backend.figures()
        st.record(**{k: v for k, v in figures.items() if k not in ("time_to_psnr", "backend")})
    fitted = current.select(keep)
    fitted = dataclasses.replace(fitted, sh=fitted.sh[:, :(degree + 1) ** 2])
    return SplatFit(gaussians=fitted, heldout_views=[v.view.camera.name for v in held], figures=figures)
