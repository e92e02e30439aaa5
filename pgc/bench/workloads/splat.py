"""splat_renderer: forward render of random Gaussians (all SH bands) in front of one camera.

Reference (speed base and truth): the float64 per-pixel rasteriser :func:`pgc.splats.reference.render_reference`
(a Python loop over pixels: only small images). Errors: ``max_abs`` (colour, plotted), ``mean_abs`` (colour)
and ``max_abs_alpha``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "max_abs"


def random_scene(count: int, size: int, seed: int = 0) -> tuple[Any, Any]:
    """``count`` random world Gaussians (anisotropic, SH degree 3) 0.8-1.6 m in front of a square
    ``size`` px pinhole camera at the origin looking down +Z (focal length ``size`` px)."""
    from pgc.types import Camera, WorldGaussians

    rng = np.random.default_rng(seed)
    means = np.c_[rng.uniform(-0.35, 0.35, count), rng.uniform(-0.35, 0.35, count), rng.uniform(0.8, 1.6, count)]
    world = WorldGaussians(means, rng.normal(size=(count, 4)), rng.uniform(0.005, 0.05, (count, 3)),
                           rng.uniform(0.1, 1.0, count), rng.normal(0, 0.3, (count, 16, 3)))
    k = np.array([[size, 0, size / 2], [0, size, size / 2], [0, 0, 1]], dtype=np.float64)
    return world, Camera(k, np.eye(3), np.zeros(3), size, size)


def errors(color: np.ndarray, alpha: np.ndarray, ref: Any) -> dict[str, float]:
    d = np.abs(np.asarray(color, np.float64) - ref.color)
    return {"max_abs": float(d.max()), "mean_abs": float(d.mean()),
            "max_abs_alpha": float(np.abs(np.asarray(alpha, np.float64) - ref.alpha).max())}


def bench(ctx: Context) -> list[dict[str, Any]]:
    from pgc.splats.reference import render_reference

    count, size = int(ctx.param("gaussians", 300)), int(ctx.param("size", 32))
    repeats = int(ctx.param("repeats", 3))
    world, camera = random_scene(count, size)
    case = f"{size}px {count} gaussians"
    base = {"size": size, "gaussians": count}
    t = timed(lambda: render_reference(world, camera), 1, warmup=False)
    ref = t.value
    records = [ctx.record("numpy-reference", case, base | {"dtype": "float64"}, t.seconds, t.peak_mb,
                          errors(ref.color, ref.alpha, ref), ERROR_KEY, reference=True)]
    for run in ctx.runs:
        settings = base | {"options": run.options}
        try:
            renderer = ctx.create(run)
            t = timed(lambda: renderer.render(world, camera), repeats)
        except Exception as exc:  # a failing backend is reported, the others still run
            records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
            continue
        records.append(ctx.record(run.implementation, case, settings, t.seconds, t.peak_mb,
                                  errors(t.value.color, t.value.alpha, ref), ERROR_KEY))
    return records
