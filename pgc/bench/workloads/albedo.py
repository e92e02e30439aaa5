"""albedo_estimator: per-view albedo of the synthetic capture against its ground-truth albedo layer.

Input per view: the rendered image, the garment mask from the segmentation and, for estimators that need it,
the white-albedo shading of the ground-truth mesh rendered by the ``pbr_renderer`` named in the workload
(default ``torch``) under the capture's light. Albedo is defined up to scale, so each prediction is scaled
per channel by least squares to the ground truth on the garment before the error. Reference (speed base):
the ``shading_ratio`` baseline. Errors: ``mae_scaled`` (mean over views of the mean absolute error on the
garment, plotted) with ``mae_scaled_std``; per-view values in the detail file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context
from pgc.errors import PGCDataError

ERROR_KEY = "mae_scaled"
REFERENCE = "shading_ratio"


def scaled_mae(pred: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    """Mean absolute error on ``mask`` after the per-channel least-squares scale of ``pred`` to ``truth``."""
    m = mask > 0.5
    p, g = np.asarray(pred, np.float64)[m], np.asarray(truth, np.float64)[m]
    scale = (p * g).sum(0) / np.maximum((p * p).sum(0), 1e-12)
    return float(np.abs(p * scale - g).mean())


def bench(ctx: Context) -> list[dict[str, Any]]:
    from pgc.albedo.base_color import garment_mask
    from pgc.io.capture import read_capture
    from pgc.io.mesh import read_mesh
    from pgc.types import Light, Material

    root = Path(ctx.capture_dir())
    capture = read_capture(root)
    views = [v for v in capture.views if "albedo" in v.extras][: int(ctx.param("views", 6))]
    if not views:
        raise PGCDataError(f"{root}: no view has an extras/albedo layer; generate the capture with 'pgc synth'")
    mesh = read_mesh(root / "ground_truth" / "full.ply")
    shader = ctx.registry.get("pbr_renderer", ctx.param("shading_renderer", "torch")).create()
    white = Material("lambertian", {"base_color": [1.0, 1.0, 1.0]}, None)
    light = Light(capture.light.radiance if capture.light is not None else np.ones(3))
    shading = [shader.render(mesh, white, light, v.camera).color for v in views]
    masks = [garment_mask(v, capture.garment_label_ids) for v in views]
    case = f"{len(views)} views {views[0].camera.width}x{views[0].camera.height}"
    records = []
    for run in ctx.runs:
        settings = {"views": len(views), "options": run.options}
        try:
            est = ctx.create(run)

            def estimate_all() -> list[np.ndarray]:
                return [est.estimate(v.image, m, s if est.needs_shading else None)
                        for v, m, s in zip(views, masks, shading)]

            t = timed(estimate_all, int(ctx.param("repeats", 1)))
        except Exception as exc:  # a failing estimator is reported, the others still run
            records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
            continue
        per_view = [scaled_mae(a, v.extras["albedo"], m) for a, v, m in zip(t.value, views, masks)]
        errors = {"mae_scaled": float(np.mean(per_view)), "mae_scaled_std": float(np.std(per_view))}
        records.append(ctx.record(run.implementation, case, settings, t.seconds, t.peak_mb, errors, ERROR_KEY,
                                  reference=run.implementation == REFERENCE and not run.options,
                                  detail={"views": [v.camera.name for v in views], "mae_scaled": per_view}))
    return records
