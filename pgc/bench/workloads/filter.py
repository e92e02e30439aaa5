"""filter: the alpha-aware low-pass on a textured image with a soft elliptical garment alpha.

Reference (speed base): the O(k^2)-per-pixel direct 2-D sum, :func:`pgc.filtering.reference.lowpass_direct`.
Errors against the float64 separable reference: ``max_abs`` (whole image, plotted) and ``max_abs_garment`` /
``mean_abs_garment`` (alpha > 0).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "max_abs"


def make_image(size: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(size, size, 3) float32 texture in [0, 1] and an elliptical (size, size) alpha with a soft edge."""
    from scipy.ndimage import zoom

    rng = np.random.default_rng(seed)
    coarse = rng.random((max(size // 8, 2), max(size // 8, 2), 3))
    image = zoom(coarse, (size / coarse.shape[0], size / coarse.shape[1], 1), order=1)[:size, :size]
    image = np.clip(image + 0.1 * rng.standard_normal(image.shape), 0, 1).astype(np.float32)
    yy, xx = np.mgrid[:size, :size] / size
    alpha = np.clip(8 * (0.35 - np.hypot((yy - 0.5) / 1.2, xx - 0.5)), 0, 1).astype(np.float32)
    return image, alpha


def errors(out: np.ndarray, truth: np.ndarray, alpha: np.ndarray) -> dict[str, float]:
    d = np.abs(np.asarray(out, np.float64) - truth)
    g = d[alpha > 0]
    return {"max_abs": float(d.max()), "max_abs_garment": float(g.max()), "mean_abs_garment": float(g.mean())}


def bench(ctx: Context) -> list[dict[str, Any]]:
    from pgc.filtering.reference import lowpass_direct, lowpass_separable

    size, repeats = int(ctx.param("size", 96)), int(ctx.param("repeats", 3))
    image, alpha = make_image(size)
    filters = [ctx.build(run) for run in ctx.runs]
    records = []
    for k in ctx.param("kernels", [7, 31]):
        case = f"{size}px k={k}"
        truth = lowpass_separable(image, alpha, k)
        t = timed(lambda: lowpass_direct(image, alpha, k), 1, warmup=False)
        records.append(ctx.record("naive-direct", case, {"size": size, "kernel_size": k}, t.seconds, t.peak_mb,
                                  errors(t.value, truth, alpha), ERROR_KEY, reference=True))
        for i, run in enumerate(ctx.runs):
            settings = {"size": size, "kernel_size": k, "options": run.options}
            try:
                if isinstance(filters[i], Exception):
                    raise filters[i]
                t = timed(lambda: filters[i].lowpass(image, alpha, k), repeats)
            except Exception as exc:  # a failing backend is reported, the others still run
                records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
                continue
            records.append(ctx.record(run.implementation, case, settings | {"seconds_std": t.seconds_std},
                                      t.seconds, t.peak_mb, errors(t.value, truth, alpha), ERROR_KEY))
    return records
