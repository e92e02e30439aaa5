"""Material fitting by differentiable path tracing (Mitsuba ``prb``): the BRDF's own parameters and the
RGB radiance of the light, over all views of a capture; the base colour is fixed. The light's shape is the
capture's recorded light (its environment map and rotation) or a constant environment
(:func:`pgc.brdfs.fitdata.fit_light`); only its RGB radiance is fitted, from the recorded radiance.

Adam (lr 0.01 as in the paper) on the BRDF parameters mapped to [0, 1] by their bounds (clamped after each
step; one lr moves every parameter the same fraction of its range: Disney's sheen spans [0, 5], and
unscaled it travelled 5x slower than the roughness it trades off against) and on the log of the light
radiance (a step is a relative change, so lr 0.01 suits any light level). Each step renders at 4 spp one
film of at most ``views_per_step`` views of one image size tiled side by side (the films cycle; Adam's
moment averages span them) and minimises the mean squared error over its interior garment pixels. A film's
views are dealt into ``shards`` sub-films rendered on one Dr.Jit thread each, in parallel processes when the
process has the cores, their gradients summed in a fixed order (:mod:`pgc_mitsuba.shards`): the fit is the
same bytes whatever the thread count.

Stopping: when the mean loss of the last ``patience`` steps is not ``min_improvement`` (relative) below
the mean of the ``patience`` steps before (window means: the 4-spp loss is noisy, and an exponential
average stopped at the same step for every model, driven by the noise of the shared seeds) and no
optimised variable still travels (its net change over the window is below ``max_drift`` x lr x window:
along flat valleys of the loss, such as roughness against sheen, the loss stalls while the parameters are
still on their way), one more window runs at ``final_lr_factor`` x lr and the result is the mean of its
iterates; else the run ends at ``max_iterations`` with the last iterate.

Polish (``settings.polish``): from Adam's result, Levenberg-Marquardt (:func:`pgc.least_squares.levenberg_marquardt`)
on the same variables, clamped to [0, 1] likewise, minimising the squared weighted residuals of every film
rendered at ``polish_spp``, twice, with two fixed seeds (a deterministic problem, where Adam's noisy steps
wander along flat valleys). The cost is the product of the two renders' residuals, whose expectation has no
render variance (one render's squared residuals would favour parameters that render with less noise: on the
knit control that moved the minimum 60 % in roughness); the Jacobians by forward differences of step
:data:`DIFFERENCE_STEP` with each render's seed (its noise cancels in the difference).
"""

from __future__ import annotations

import contextlib
import math
import time
from typing import Any, Callable, Iterator

import numpy as np

from pgc.brdfs.fitdata import FitLight, FitView, fit_light, prepare_views, psnr_from_mse, split_occluders
from pgc.cores import allotted_cores
from pgc.brdfs.parameters import PARAMETERS
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.least_squares import levenberg_marquardt
from pgc.roles.pbr_renderer import MaterialFitSettings
from pgc.roles.pbr_renderer import MaterialFit
from pgc.splats.fit import adam_update
from pgc.types import Capture, Light, Material, Mesh
from pgc_mitsuba.runtime import mitsuba
from pgc_mitsuba.scene import scene_dict
from pgc_mitsuba.shards import SceneSpec, ShardFilm, ShardPool, split_film


DIFFERENCE_STEP = 1e-2
"""Forward-difference step of the polish's Jacobian in the fit's variables (1 % of a parameter's range, 1 %
relative in the radiance); taken downward at a parameter's upper bound."""


def resolve_settings(settings: Any) -> MaterialFitSettings:
    if settings is None or isinstance(settings, dict):
        return MaterialFitSettings.model_validate(settings or {})
    return settings


def fit_material(renderer: Any, capture: Capture, mesh: Mesh, material: Material, settings: Any = None,
                 reporter: Reporter | None = None) -> MaterialFit:
    """Fit ``material``'s BRDF parameters and the light's radiance to all views of ``capture`` (under the
    light of ``settings.light``). With ``settings.select_model`` all models are fitted and the simplest
    adequate one returned."""
    settings = resolve_settings(settings)
    reporter = reporter or Reporter.silent()
    if settings.select_model:
        from pgc.brdfs.select import fit_and_select

        return fit_and_select(renderer, capture, mesh, material, settings, reporter).fit
    if material.brdf not in PARAMETERS:
        raise PGCDataError(f"material.brdf '{material.brdf}' cannot be fitted; use one of {sorted(PARAMETERS)}")
    light = fit_light(capture, settings.light)
    fit_views = prepare_views(capture, settings.max_image_side)
    with one_jit_thread():
        return _optimise(renderer, fit_views, capture, mesh, material, light, settings, reporter)


@contextlib.contextmanager
def one_jit_thread() -> Iterator[None]:
    """Run Dr.Jit's CPU kernels on one thread, restoring its pool afterwards. The gradients of the scene
    parameters are accumulated by atomic adds from every thread in a racy order, so with more than one thread
    a render's gradient differs from run to run (and with the thread count); the fit's cores are used by
    shards in separate processes instead (:mod:`pgc_mitsuba.shards`)."""
    mitsuba()
    import drjit as dr

    previous = dr.thread_count()
    dr.set_thread_count(1)
    try:
        yield
    finally:
        dr.set_thread_count(previous)


def _find(keys: list[str], suffix: str) -> str:
    found = [k for k in keys if k.endswith(suffix)]
    if len(found) != 1:
        raise RuntimeError(f"expected one scene parameter ending in '{suffix}', found {found}")
    return found[0]


def _films(fit_views: list[FitView], settings: MaterialFitSettings) -> list[list[ShardFilm]]:
    """Views of one image size side by side on one film, at most ``views_per_step`` per film, each film dealt
    into ``settings.shards`` shards. Each step renders one film, cycling through them (a bounded cost per step
    whatever the number of views)."""
    groups: dict[tuple[int, int], list[FitView]] = {}
    for v in fit_views:
        if v.weight.any():
            groups.setdefault((v.camera.height, v.camera.width), []).append(v)
    films = [[g[i] for i in part] for g in groups.values()
             for part in np.array_split(np.arange(len(g)), math.ceil(len(g) / settings.views_per_step))]
    return [split_film([v.camera for v in f], [v.target for v in f], [v.weight for v in f], settings.shards)
            for f in films]


def _optimise(renderer: Any, fit_views: list[FitView], capture: Capture, mesh: Mesh, material: Material,
              light: FitLight, settings: MaterialFitSettings, reporter: Reporter) -> MaterialFit:
    mi = mitsuba()

    start_time = time.perf_counter()
    garment, occluder = split_occluders(mesh, tuple(capture.garment_label_ids))
    integrator = {"type": "prb", "max_depth": settings.max_depth, "hide_emitters": True}
    # the BSDF's parameters as the scene holds them (their keys, and the material's values or the defaults)
    params = mi.traverse(mi.load_dict(scene_dict(garment, material, Light(np.ones(3)), integrator)))
    keys = list(params.keys())
    bounds = {_find(keys, f"bsdf.{p.name}"): (p.lower, p.upper, p.name) for p in PARAMETERS[material.brdf]}
    initial = {key: np.asarray(params[key], np.float64).reshape(-1) for key in bounds}
    spec = SceneSpec(garment, occluder, material, integrator, renderer.options.occluder_albedo,
                     renderer.options.smooth_normals, list(bounds), settings.spp, light.shape)
    films = _films(fit_views, settings)
    # the optimised variables as one vector: each parameter mapped to [0, 1] by its bounds, then the log of
    # the light radiance (from the recorded radiance, else 1: the paper's initial value)
    sizes = [initial[key].size for key in bounds]
    lows = np.array([bounds[key][0] for key, n in zip(bounds, sizes) for _ in range(n)], np.float64)
    spans = np.array([bounds[key][1] - bounds[key][0] for key, n in zip(bounds, sizes) for _ in range(n)],
                     np.float64)
    n_unit = int(sum(sizes))
    start = np.array([value for key in bounds for value in initial[key]], np.float64)
    x = np.concatenate([np.clip((start - lows) / spans, 0.0, 1.0), np.log(np.maximum(light.radiance, 1e-6))])
    m, v = np.zeros_like(x), np.zeros_like(x)

    def values(state: np.ndarray) -> list[np.ndarray]:
        """Scene values of the state: each parameter, then the radiance."""
        params = lows + spans * state[:n_unit]
        return [*np.split(params, np.cumsum(sizes)[:-1]), np.exp(state[n_unit:])] if sizes else \
            [np.exp(state[n_unit:])]

    lr = settings.lr
    history: list[float] = []
    states: list[np.ndarray] = []
    stopped = "max_iterations"
    window = settings.patience
    drift: float | None = None  # measured once two windows have run
    polish_from: int | None = None  # the step where the final low-lr window began
    pixels = max(sum(part.weight.size for part in parts) for parts in films)
    processes = min(settings.shards, allotted_cores()) if pixels >= settings.parallel_min_pixels else 1
    with ShardPool(spec, films, processes) as pool, \
            reporter.stage("material", total=settings.max_iterations, brdf=material.brdf) as stage:
        for it in range(settings.max_iterations):
            states.append(x.copy())
            scene_values = values(x)
            loss_value, grads = pool.render(it % len(films), scene_values, settings.seed + settings.shards * it,
                                            settings.seed + 1_000_003 + settings.shards * it)
            # chain rule to the optimised variables: d/dunit = span d/dparam, d/dlog = radiance d/dradiance
            gradient = np.concatenate([*grads[:-1], grads[-1] * scene_values[-1]])
            gradient[:n_unit] *= spans
            x, m, v = adam_update(x, gradient, m, v, it + 1, lr)
            x[:n_unit] = np.clip(x[:n_unit], 0.0, 1.0)
            history.append(loss_value)
            if polish_from is not None:
                if len(history) - polish_from >= window:
                    break
            elif len(history) >= 2 * window:
                recent, before = np.mean(history[-window:]), np.mean(history[-2 * window:-window])
                # net travel over the window, as a fraction of the most Adam can travel (lr per step)
                drift = float(np.abs(states[-1] - states[-1 - window]).max() / (settings.lr * window))
                if recent > before * (1.0 - settings.min_improvement) and drift < settings.max_drift:
                    stopped = "plateau"
                    polish_from = len(history)
                    lr = settings.lr * settings.final_lr_factor
            if it % 10 == 0:
                stage.progress(it + 1, loss=loss_value)
        iterations = len(history)
        final = float(np.mean(history[-window:]))
        stage.record(iterations=iterations, loss=final)
        # after a plateau the result is the mean of the final window's iterates: the 4-spp gradient noise keeps
        # the iterates jittering about the optimum by ~lr (~1 % in the light, ~0.1 dB of held-out PSNR at lr
        # 0.01); the final window at final_lr_factor x lr shrinks the jitter, which is one-sided at a bound
        # (there a mean at full lr stays off the bound: Disney's sheen kept 0.02-0.06 where its optimum is 0).
        # Ended by max_iterations, the variables may still travel and a mean would lag: the last iterate.
        adam_state = x if polish_from is None else np.mean(states[-window:], axis=0)
        polish = None
        if settings.polish:
            mean_state, polish = _polish(pool, adam_state, n_unit, values, settings)
            polish["adam"] = _named(adam_state, bounds, sizes)
        else:
            mean_state = adam_state
    fitted = _named(mean_state, bounds, sizes)
    radiance = np.asarray(fitted.pop("radiance"))
    out_material = Material(material.brdf, fitted, material.base_color)
    if material.base_color is None and "base_color" in material.params:
        out_material.params["base_color"] = material.params["base_color"]
    figures = {"brdf": material.brdf, "iterations": iterations, "stopped": stopped,
               "loss_final": final, "polish_from": polish_from, "psnr_train_4spp": psnr_from_mse(final),
               "seconds": time.perf_counter() - start_time, "views": len([v for v in fit_views if v.weight.any()]),
               "films": len(films), "shards": settings.shards,
               "image_sizes": [list(k) for k in sorted({(v.camera.height, v.camera.width) for v in fit_views
                                                      if v.weight.any()})],
               "drift": drift, "polish": polish,
               "loss_history": [float(h) for h in history[:: max(1, len(history) // 200)]],
               "light": light.record()}
    return MaterialFit(out_material, light.light(radiance), figures)


def _named(state: np.ndarray, bounds: dict[str, tuple[float, float, str]], sizes: list[int]) -> dict[str, Any]:
    """The parameters of a state by name (scalars as floats, colours as lists), then its ``radiance``."""
    named: dict[str, Any] = {}
    offset = 0
    for (lo, hi, name), size in zip(bounds.values(), sizes):
        value = lo + (hi - lo) * state[offset:offset + size]
        offset += size
        named[name] = float(value[0]) if size == 1 else value.tolist()
    named["radiance"] = np.exp(state[offset:offset + 3]).tolist()
    return named


def _polish(pool: ShardPool, state: np.ndarray, n_unit: int, values: Callable[[np.ndarray], list[np.ndarray]],
            settings: MaterialFitSettings) -> tuple[np.ndarray, dict[str, Any]]:
    """Levenberg-Marquardt from ``state`` (see the module docstring): the polished state and its figures."""
    start_time = time.perf_counter()
    seeds = (settings.seed, settings.seed + 1_000_003)  # two independent renders of every point

    def residual(s: np.ndarray) -> np.ndarray:
        return np.stack([pool.residual(values(s), settings.polish_spp, seed) for seed in seeds])

    def jacobian(s: np.ndarray, r: np.ndarray) -> np.ndarray:
        columns = []
        for j in range(s.size):
            step = -DIFFERENCE_STEP if j < n_unit and s[j] + DIFFERENCE_STEP > 1.0 else DIFFERENCE_STEP
            shifted = s.copy()
            shifted[j] += step
            columns.append((residual(shifted) - r) / step)
        return np.stack(columns, 2)

    def project(s: np.ndarray) -> np.ndarray:
        return np.concatenate([np.clip(s[:n_unit], 0.0, 1.0), s[n_unit:]])

    result = levenberg_marquardt(residual, jacobian, state, project, settings.polish_iterations,
                                 settings.polish_tolerance)
    return result.x, {"iterations": result.iterations, "stopped": result.stopped,
                      "loss_before": result.initial_cost, "loss_after": result.cost,
                      "seconds": time.perf_counter() - start_time}
