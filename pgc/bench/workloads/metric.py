"""metric: one image pair (a textured image and its blurred, noisy copy), optionally masked.

Reference (speed base): PSNR written out in numpy on the sRGB values (the cheapest full-reference metric).
Error ``abs_diff_reference`` (plotted): the distance of the metric's value to an independent value of the
same quantity, named in ``settings["reference"]``: scikit-image for psnr and ssim, the published LPIPS
distances of the example pair in tests/data/lpips (0.722 / 0.138, AlexNet) for lpips, and for metrics
without an independent implementation here their value on identical images (1 for similarity indices).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "abs_diff_reference"
LPIPS_DATA = Path(__file__).resolve().parents[3] / "tests" / "data" / "lpips"
LPIPS_PUBLISHED = {"p0": 0.722, "p1": 0.138}


def image_pair(size: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(prediction, target): linear RGB (size, size, 3) float32; the target is the filter workload's texture
    (as sRGB values), the prediction its blurred copy with noise."""
    from scipy.ndimage import gaussian_filter

    from pgc.bench.workloads.filter import make_image
    from pgc.io.images import srgb_to_linear

    srgb = 0.1 + 0.8 * make_image(size, seed)[0].astype(np.float64)
    noise = 0.03 * np.random.default_rng(seed + 1).standard_normal(srgb.shape)
    noisy = np.clip(gaussian_filter(srgb, (1, 1, 0)) + noise, 0, 1)
    return srgb_to_linear(noisy).astype(np.float32), srgb_to_linear(srgb).astype(np.float32)


def numpy_psnr(pred: np.ndarray, target: np.ndarray) -> float:
    from pgc.io.images import linear_to_srgb

    mse = float(np.mean((linear_to_srgb(pred).astype(np.float64) - linear_to_srgb(target)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def independent(name: str, metric: Callable[..., float], pred: np.ndarray,
                target: np.ndarray) -> tuple[str, float] | None:
    """(reference name, |value - reference value|) of metric ``name``, or None without a reference."""
    from pgc.io.images import linear_to_srgb

    if name == "psnr":
        return "numpy psnr on srgb", abs(metric(pred, target) - numpy_psnr(pred, target))
    if name == "ssim":
        try:
            from skimage.metrics import structural_similarity
        except ImportError:
            return None
        ref = structural_similarity(linear_to_srgb(pred).astype(np.float64), linear_to_srgb(target).astype(np.float64),
                                    gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1.0,
                                    channel_axis=-1)
        return "scikit-image structural_similarity", abs(metric(pred, target) - ref)
    if name == "lpips" and LPIPS_DATA.is_dir():
        from pgc.io.images import read_image

        ref = read_image(LPIPS_DATA / "ex_ref.png")
        diff = max(abs(metric(read_image(LPIPS_DATA / f"ex_{k}.png"), ref) - v) for k, v in LPIPS_PUBLISHED.items())
        return "published lpips distances (tests/data/lpips)", diff
    if getattr(metric, "higher_is_better", True):
        return "value on identical images (1)", abs(metric(target, target) - 1.0)
    return "value on identical images (0)", abs(metric(target, target))


def bench(ctx: Context) -> list[dict[str, Any]]:
    size, repeats = int(ctx.param("size", 64)), int(ctx.param("repeats", 3))
    pred, target = image_pair(size)
    mask = np.zeros((size, size), np.float32)
    mask[size // 8: -size // 8, size // 4: -size // 4] = 1.0
    case = f"{size}px"
    t = timed(lambda: numpy_psnr(pred, target), repeats)
    records = [ctx.record("numpy-psnr", case, {"size": size}, t.seconds, t.peak_mb, {ERROR_KEY: 0.0}, ERROR_KEY,
                          reference=True)]
    for run in ctx.runs:
        settings: dict[str, Any] = {"size": size, "options": run.options}
        try:
            metric = ctx.create(run)
            t = timed(lambda: metric(pred, target), repeats)
            masked = timed(lambda: metric(pred, target, mask), 1, warmup=False)
            check = independent(run.implementation, metric, pred, target)
        except Exception as exc:  # a failing metric is reported, the others still run
            records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
            continue
        errors = {} if check is None else {ERROR_KEY: check[1]}
        settings |= {"value": t.value, "masked_value": masked.value, "masked_seconds": masked.seconds,
                     "reference": False, "independent": None if check is None else check[0]}
        records.append(ctx.record(run.implementation, case, settings, t.seconds, t.peak_mb, errors, ERROR_KEY))
    return records
