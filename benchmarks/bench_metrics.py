#!/usr/bin/env python
"""Speed and agreement of the ``metric`` implementations (psnr, ssim, fsim, lpips) per image size.

Time per image pair, as a ratio to PSNR measured in the same run (the cheapest metric), and the difference to
an independent implementation where one is installed: scikit-image for PSNR and SSIM, piq for FSIM (imported
with an inert torchvision stand-in; test-only, not a dependency). LPIPS is checked against the published
reference distances 0.722 / 0.138 (AlexNet) on the example pair in tests/data/lpips.

    python benchmarks/bench_metrics.py [--sizes 256 512 1024] [--out bench_metrics.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import types
from pathlib import Path
from typing import Any, Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_filter import print_table, timed  # noqa: E402  (shared benchmark helpers)

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "lpips"
LPIPS_REFERENCE = {"p0": 0.722, "p1": 0.138}


def pair(size: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A textured linear image and a blurred, noisy copy."""
    from scipy.ndimage import gaussian_filter

    from pgc.io.images import srgb_to_linear

    rng = np.random.default_rng(seed)
    srgb = sum(gaussian_filter(rng.standard_normal((size, size, 3)), (s, s, 0)) * s for s in (0.7, 3, 12))
    srgb = 0.1 + 0.8 * (srgb - srgb.min()) / np.ptp(srgb)
    noisy = np.clip(gaussian_filter(srgb, (1, 1, 0)) + 0.03 * rng.standard_normal(srgb.shape), 0, 1)
    return srgb_to_linear(noisy), srgb_to_linear(srgb)


def import_piq() -> Any:
    """Import piq (FSIM reference; test-only) without torchvision: piq imports it at import time for models
    that FSIM does not use, and PyPI's torchvision breaks the CPU torch. An inert stand-in is placed in
    ``sys.modules`` for the import only and removed afterwards. ImportError if piq is not installed."""

    class _Shim(types.ModuleType):
        def __getattr__(self, name: str) -> Any:
            if name.startswith("__"):
                raise AttributeError(name)
            return type(name, (), {}) if name[0].isupper() else _Shim(f"{self.__name__}.{name}")

    names = ("torchvision", "torchvision.models", "torchvision.models.utils")
    saved = {name: sys.modules.get(name) for name in names}
    for name in names:
        sys.modules[name] = saved[name] or _Shim(name)
    try:
        import piq
    finally:
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
    return piq


def independent(names: set[str]) -> dict[str, Callable[[np.ndarray, np.ndarray], float]]:
    """Independent implementations of ``names`` on sRGB values, where installed."""
    from pgc.io.images import linear_to_srgb

    out: dict[str, Callable[[np.ndarray, np.ndarray], float]] = {}
    try:
        from skimage.metrics import peak_signal_noise_ratio, structural_similarity

        out["psnr"] = lambda p, t: peak_signal_noise_ratio(linear_to_srgb(t).astype(np.float64),
                                                           linear_to_srgb(p).astype(np.float64), data_range=1.0)
        out["ssim"] = lambda p, t: structural_similarity(
            linear_to_srgb(p).astype(np.float64), linear_to_srgb(t).astype(np.float64), gaussian_weights=True,
            sigma=1.5, use_sample_covariance=False, data_range=1.0, channel_axis=-1)
    except ImportError:
        pass
    if "fsim" not in names:
        return out
    try:
        piq = import_piq()
        import torch

        def tensor(x: np.ndarray) -> Any:
            return torch.from_numpy(linear_to_srgb(x).astype(np.float64)).permute(2, 0, 1)[None]

        out["fsim"] = lambda p, t: float(piq.fsim(tensor(p), tensor(t), data_range=1.0))
    except ImportError:
        pass
    return out


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    parser.add_argument("--metrics", nargs="+", default=["psnr", "ssim", "fsim", "lpips"], help="psnr first: time base")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default="bench_metrics.json")
    args = parser.parse_args(argv)

    from pgc.io.asset import package_versions
    from pgc.io.images import read_image
    from pgc.registry import default_registry

    reg = default_registry()
    metrics = {n: reg.create("metric", n) for n in args.metrics if reg.get("metric", n).available}
    others = independent(set(metrics))
    env = package_versions(("pgc", "numpy", "scipy", "torch", "scikit-image", "piq"))
    records, rows = [], []
    for size in args.sizes:
        pred, target = pair(size)
        mask = np.zeros((size, size), np.float32)
        mask[size // 8: -size // 8, size // 4: -size // 4] = 1.0
        base = None
        for name, metric in metrics.items():  # psnr first: the time base
            seconds, peak = timed(lambda: metric(pred, target), args.repeats)
            base = base or seconds
            masked_s, _ = timed(lambda: metric(pred, target, mask), 1)
            value = metric(pred, target)
            errors: dict[str, float] = {"value": value, "masked_seconds": masked_s, "x_psnr_time": seconds / base}
            if name in others:
                errors["abs_diff_independent"] = abs(value - others[name](pred, target))
            if name == "lpips":
                ref, p0, p1 = (read_image(DATA / f"ex_{n}.png") for n in ("ref", "p0", "p1"))
                errors["abs_diff_published"] = max(abs(metric(p, ref) - LPIPS_REFERENCE[k])
                                                   for k, p in (("p0", p0), ("p1", p1)))
            records.append({"role": "metric", "implementation": name, "preset": f"{size}px",
                            "settings": {"size": size, **dict(metric.options or {})}, "seconds": seconds,
                            "peak_mb": round(peak, 1), "errors": errors, "versions": env})
            check = errors.get("abs_diff_independent", errors.get("abs_diff_published"))
            rows.append({"size": size, "metric": name, "ms": f"{1e3 * seconds:.1f}", "x psnr": f"{seconds / base:.1f}",
                         "masked ms": f"{1e3 * masked_s:.1f}", "value": f"{value:.4f}",
                         "|diff| to independent": "-" if check is None else f"{check:.1e}", "peak MB": f"{peak:.0f}"})
    print_table(rows, ["size", "metric", "ms", "x psnr", "masked ms", "value", "|diff| to independent", "peak MB"])
    Path(args.out).write_text(json.dumps(records, indent=1) + "\n")
    print(f"wrote {len(records)} records to {args.out}")
    return records


if __name__ == "__main__":
    main()
