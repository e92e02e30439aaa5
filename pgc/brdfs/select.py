"""Model only what the scene needs: fit every BRDF and keep the simplest whose held-out error is close to
the best.

Every ``holdout_every``-th view is held out. Each model (simplest first: lambertian, disney, pgc-sheen) is
fitted on the other views from the paper's initial values; its held-out PSNR (interior garment pixels,
renders at ``eval_spp``) is measured; the simplest model within ``margin_db`` of the best PSNR is chosen.
The fit of the chosen model is returned with a table of all models and the reason for the choice.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pgc.brdfs.fitdata import masked_mse, prepare_views, psnr_from_mse, split_occluders
from pgc.brdfs.parameters import PARAMETERS, SIMPLICITY
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.roles.pbr_renderer import MaterialFit
from pgc.types import Capture, Material, Mesh


@dataclass
class Selection:
    fit: MaterialFit
    """The chosen model's fit (its figures include ``selection``)."""
    table: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Per model: psnr_holdout, iterations, stopped, drift, seconds, params, radiance."""
    reason: str = ""


def holdout_split(n_views: int, every: int) -> tuple[list[int], list[int]]:
    """(training, held-out) view indices: every ``every``-th view (from index every - 1) is held out."""
    held = list(range(every - 1, n_views, every))
    if not held or len(held) == n_views:
        raise PGCDataError(f"capture has {n_views} views: too few to hold out every {every}th view "
                           "(need at least 2; lower material.holdout_every)")
    return [i for i in range(n_views) if i not in held], held


def fit_and_select(renderer: Any, capture: Capture, mesh: Mesh, material: Material, settings: Any,
                   reporter: Reporter | None = None, models: tuple[str, ...] = SIMPLICITY) -> Selection:
    """Fit ``models`` with ``renderer`` and choose the simplest adequate one (see module docstring).

    ``renderer`` must fit materials and its ``render`` accept ``spp``, ``occluder`` and ``max_depth`` (the
    ``mitsuba`` pbr_renderer); held-out views are rendered with the fit's path length. The base colour of
    ``material`` is kept fixed."""
    reporter = reporter or Reporter.silent()
    settings = settings.model_copy(update={"select_model": False})
    train, held = holdout_split(len(capture.views), settings.holdout_every)
    eval_views = prepare_views(capture, settings.max_image_side, held)
    train_capture = replace(capture, views=[capture.views[i] for i in train])
    garment, occluder = split_occluders(mesh, tuple(capture.garment_label_ids))
    table: dict[str, dict[str, Any]] = {}
    fits: dict[str, MaterialFit] = {}
    for name in sorted(models, key=SIMPLICITY.index):
        init = Material(name, {p.name: (p.init[0] if p.size == 1 else list(p.init)) for p in PARAMETERS[name]},
                        material.base_color)
        if material.base_color is None:
            init.params["base_color"] = material.params["base_color"]
        fit = renderer.fit(train_capture, mesh, init, settings, reporter)
        sq, n = 0.0, 0.0
        for v in eval_views:
            out = renderer.render(garment, fit.material, fit.light, v.camera, spp=settings.eval_spp,
                                  occluder=occluder, max_depth=settings.max_depth)
            w = float(v.weight.sum())
            sq += masked_mse(out.color, v.target, v.weight) * w
            n += w
        psnr = psnr_from_mse(sq / max(n, 1.0))
        fits[name] = fit
        table[name] = {"psnr_holdout": psnr, "iterations": fit.figures.get("iterations"),
                       "stopped": fit.figures.get("stopped"), "drift": fit.figures.get("drift"),
                       "seconds": fit.figures.get("seconds"), "params": fit.material.params,
                       "radiance": np.asarray(fit.light.radiance).tolist()}
    best = max(t["psnr_holdout"] for t in table.values())
    chosen = next(m for m in sorted(table, key=SIMPLICITY.index)
                  if table[m]["psnr_holdout"] >= best - settings.margin_db)
    best_name = max(table, key=lambda m: table[m]["psnr_holdout"])
    if chosen == best_name:
        reason = (f"'{chosen}' has the best held-out PSNR ({best:.2f} dB) and no simpler model is within "
                  f"{settings.margin_db} dB of it")
    else:
        reason = (f"'{chosen}' ({table[chosen]['psnr_holdout']:.2f} dB) is within {settings.margin_db} dB of the "
                  f"best, '{best_name}' ({best:.2f} dB), with fewer parameters")
    fit = fits[chosen]
    fit.figures["selection"] = {"chosen": chosen, "reason": reason, "margin_db": settings.margin_db,
                                "held_out_views": [capture.views[i].camera.name for i in held], "models": table}
    return Selection(fit, table, reason)
