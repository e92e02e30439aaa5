"""Material fitting by differentiable path tracing (Mitsuba ``prb``): the BRDF's own parameters and the
RGB radiance of the constant environment light, over all views of a capture; the base colour is fixed.

Adam (lr 0.01 as in the paper) on the BRDF parameters directly (clamped to their bounds after each step)
and on the log of the light radiance (a step is a relative change, so lr 0.01 suits any light level). Each
step renders every view at 4 spp (all views of one image size tiled on one film: one traced kernel) and
minimises the mean squared error over interior garment pixels. The run stops when the mean loss of the
last ``patience`` steps is not ``min_improvement`` (relative) below the mean of the ``patience`` steps
before (window means: the 4-spp loss is noisy, and an exponential average stopped at the same step for
every model, driven by the noise of the shared seeds), or at ``max_iterations``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from pgc.brdfs.fitdata import FitView, prepare_views, psnr_from_mse, split_occluders
from pgc.brdfs.parameters import PARAMETERS
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.pipeline.settings_material import MaterialFitSettings
from pgc.roles.pbr_renderer import MaterialFit
from pgc.types import Capture, Light, Material, Mesh
from pgc_mitsuba.runtime import mitsuba
from pgc_mitsuba.scene import scene_dict
from pgc_mitsuba.sensors import pinhole_sensor


def resolve_settings(settings: Any) -> MaterialFitSettings:
    if settings is None or isinstance(settings, dict):
        return MaterialFitSettings.model_validate(settings or {})
    return settings


def fit_material(renderer: Any, capture: Capture, mesh: Mesh, material: Material, settings: Any = None,
                 reporter: Reporter | None = None) -> MaterialFit:
    """Fit ``material``'s BRDF parameters and the constant light to all views of ``capture``. With
    ``settings.select_model`` all models are fitted and the simplest adequate one returned."""
    settings = resolve_settings(settings)
    reporter = reporter or Reporter.silent()
    if settings.select_model:
        from pgc.brdfs.select import fit_and_select

        return fit_and_select(renderer, capture, mesh, material, settings, reporter).fit
    if material.brdf not in PARAMETERS:
        raise PGCDataError(f"material.brdf '{material.brdf}' cannot be fitted; use one of {sorted(PARAMETERS)}")
    fit_views = prepare_views(capture, settings.max_image_side)
    return _optimise(renderer, fit_views, capture, mesh, material, settings, reporter)


def _find(params: Any, suffix: str) -> str:
    keys = [k for k in params.keys() if k.endswith(suffix)]
    if len(keys) != 1:
        raise RuntimeError(f"expected one scene parameter ending in '{suffix}', found {keys}")
    return keys[0]


def _optimise(renderer: Any, fit_views: list[FitView], capture: Capture, mesh: Mesh, material: Material,
              settings: MaterialFitSettings, reporter: Reporter) -> MaterialFit:
    mi = mitsuba()
    import drjit as dr

    start_time = time.perf_counter()
    garment, occluder = split_occluders(mesh, tuple(capture.garment_label_ids))
    init_light = Light(np.ones(3))
    integrator = {"type": "prb", "max_depth": settings.max_depth, "hide_emitters": True}
    scene = mi.load_dict(scene_dict(garment, material, init_light, integrator, occluder,
                                    renderer.options.occluder_albedo, renderer.options.smooth_normals))
    params = mi.traverse(scene)
    bounds = {}
    opt = mi.ad.Adam(lr=settings.lr)
    for p in PARAMETERS[material.brdf]:
        key = _find(params, f"bsdf.{p.name}")
        bounds[key] = (p.lower, p.upper, p.name)
        opt[key] = params[key]
    light_key = _find(params, "light.radiance.value")
    opt["log_radiance"] = mi.Color3f(0.0, 0.0, 0.0)  # radiance 1: the paper's initial value

    def apply() -> None:
        for key, (lo, hi, _) in bounds.items():
            opt[key] = dr.clip(opt[key], lo, hi)
            params[key] = opt[key]
        params[light_key] = dr.exp(opt["log_radiance"])
        params.update()

    # one film per image size holding all its views side by side: every step renders every view
    groups: dict[tuple[int, int], list[FitView]] = {}
    for v in fit_views:
        if v.weight.any():
            groups.setdefault((v.camera.height, v.camera.width), []).append(v)
    count = 3.0 * sum(float(v.weight.sum()) for g in groups.values() for v in g)
    batches = [(pinhole_sensor([v.camera for v in g], settings.spp),
                mi.TensorXf(np.concatenate([v.target for v in g], axis=1)),
                mi.TensorXf(np.concatenate([v.weight for v in g], axis=1)[..., None])) for g in groups.values()]
    history: list[float] = []
    stopped = "max_iterations"
    window = settings.patience
    with reporter.stage("material_fit", total=settings.max_iterations, brdf=material.brdf) as stage:
        for it in range(settings.max_iterations):
            apply()
            loss_value = 0.0
            for b, (sensor, target, weight) in enumerate(batches):
                seed = it * len(batches) + b
                img = mi.render(scene, params, sensor=sensor, spp=settings.spp, seed=settings.seed + seed,
                                seed_grad=settings.seed + 1_000_003 + seed)
                loss = dr.sum(weight * dr.square(img[:, :, :3] - target), axis=None) / count
                dr.backward(loss)
                loss_value += float(loss.array[0])
            opt.step()
            history.append(loss_value)
            if len(history) >= 2 * window:
                recent, before = np.mean(history[-window:]), np.mean(history[-2 * window:-window])
                if recent > before * (1.0 - settings.min_improvement):
                    stopped = "plateau"
                    break
            if it % 10 == 0:
                stage.progress(it + 1, loss=loss_value)
        apply()
        iterations = len(history)
        final = float(np.mean(history[-window:]))
        stage.record(iterations=iterations, loss=final)
    fitted = {}
    for key, (_, _, name) in bounds.items():
        value = np.asarray(params[key], dtype=np.float64).reshape(-1)
        fitted[name] = float(value[0]) if value.size == 1 else value.tolist()
    radiance = np.asarray(dr.exp(opt["log_radiance"]), dtype=np.float64).reshape(3)
    out_material = Material(material.brdf, fitted, material.base_color)
    if material.base_color is None and "base_color" in material.params:
        out_material.params["base_color"] = material.params["base_color"]
    figures = {"brdf": material.brdf, "iterations": iterations, "stopped": stopped,
               "loss_final": final, "psnr_train_4spp": psnr_from_mse(final),
               "seconds": time.perf_counter() - start_time, "views": sum(len(g) for g in groups.values()),
               "image_sizes": [list(k) for k in groups],
               "loss_history": [float(x) for x in history[:: max(1, len(history) // 200)]]}
    return MaterialFit(out_material, Light(radiance=radiance), figures)
