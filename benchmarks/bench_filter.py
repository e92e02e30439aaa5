#!/usr/bin/env python
"""Speed against error of the ``filter`` backends: the alpha-aware low-pass per image size and kernel size.

Each backend's time per image is reported as a ratio to a naive O(k^2) 2-D convolution (torch ``conv2d`` with
the full k x k kernel, the same alpha renormalisation) measured in the same run. The naive cost per pixel
does not depend on the image size, so for images above ``--naive-max`` px it is timed on a central crop of
that size and scaled by the pixel count (marked ``naive_extrapolated``). Error: the largest absolute
difference to the float64 separable reference, everywhere and on the garment (alpha > 0; the O(1) 3-box
approximation differs most where the blurred alpha is tiny, far outside the garment). Records (JSON) follow docs/bench.md, "Record schema".

    python benchmarks/bench_filter.py [--sizes 256 1024 2048] [--kernels 7 31 71 151] [--out bench_filter.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import threading
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np


class PeakRSS:
    """Peak resident memory above the starting level while the block runs (sampled every 2 ms), in MB."""

    def __enter__(self) -> "PeakRSS":
        self._page = 4096 / 2 ** 20
        self.start = self.peak = self._rss()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def _rss(self) -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * self._page

    def _sample(self) -> None:
        while not self._stop.wait(0.002):
            self.peak = max(self.peak, self._rss())

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, self._rss())

    @property
    def mb(self) -> float:
        return self.peak - self.start


def timed(fn: Callable[[], Any], repeats: int) -> tuple[float, float]:
    """Median seconds of ``repeats`` calls after one warm-up call, and the peak extra memory (MB)."""
    fn()
    times = []
    with PeakRSS() as mem:
        for _ in range(repeats):
            start = time.perf_counter()
            fn()
            times.append(time.perf_counter() - start)
    return statistics.median(times), mem.mb


def print_table(rows: list[dict[str, Any]], columns: list[str]) -> None:
    widths = [max([len(c)] + [len(str(r.get(c, ""))) for r in rows]) for c in columns]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    for r in rows:
        print("  ".join(str(r.get(c, "")).ljust(w) for c, w in zip(columns, widths)))


def naive_lowpass(image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
    """The O(k^2) reference: torch conv2d with the full 2-D Gaussian, then the role's renormalisation."""
    import torch

    from pgc.filtering.kernel import gaussian_kernel_1d, renormalise

    taps = torch.as_tensor(gaussian_kernel_1d(kernel_size), dtype=torch.float32)
    c = image.shape[2] + 1
    stack = np.concatenate([image * alpha[..., None], alpha[..., None]], axis=-1)
    x = torch.from_numpy(stack).permute(2, 0, 1)[None]
    with torch.no_grad():
        out = torch.nn.functional.conv2d(x, torch.outer(taps, taps).expand(c, 1, -1, -1), padding=kernel_size // 2,
                                         groups=c)[0].permute(1, 2, 0).numpy()
    return renormalise(out[..., :-1], out[..., -1:], image)


def make_image(size: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A textured (H, W, 3) image with an elliptical garment alpha (soft edge)."""
    from scipy.ndimage import zoom

    rng = np.random.default_rng(seed)
    image = np.clip(zoom(rng.random((size // 8, size // 8, 3)), (8, 8, 1), order=1)
                    + 0.1 * rng.standard_normal((size, size, 3)), 0, 1).astype(np.float32)
    yy, xx = np.mgrid[:size, :size] / size
    alpha = np.clip(8 * (0.35 - np.hypot((yy - 0.5) / 1.2, xx - 0.5)), 0, 1).astype(np.float32)
    return image, alpha


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 1024, 2048])
    parser.add_argument("--kernels", type=int, nargs="+", default=[7, 31, 71, 151])
    parser.add_argument("--backends", nargs="+", default=["torch", "jax", "opencv", "opencv:box3"],
                        help="implementation names, optionally NAME:METHOD for the OpenCV 'method' option")
    parser.add_argument("--naive-max", type=int, default=256, help="largest side the naive reference runs on")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default="bench_filter.json")
    args = parser.parse_args(argv)

    from pgc.filtering.reference import lowpass_separable
    from pgc.io.asset import package_versions
    from pgc.registry import default_registry

    reg = default_registry()
    filters = {}
    for entry in args.backends:
        name, _, method = entry.partition(":")
        if reg.get("filter", name).available:
            filters[entry] = reg.create("filter", name, {"method": method} if method else None)
    env = package_versions(("pgc", "numpy", "torch", "jax", "jaxlib", "opencv-python-headless"))
    records, rows = [], []
    for size in args.sizes:
        image, alpha = make_image(size)
        crop = slice((size - min(size, args.naive_max)) // 2, (size + min(size, args.naive_max)) // 2)
        for k in args.kernels:
            reference = lowpass_separable(image, alpha, k)
            naive_s, _ = timed(lambda: naive_lowpass(image[crop, crop], alpha[crop, crop], k), 1)
            naive_s *= (size / min(size, args.naive_max)) ** 2
            for name, filt in filters.items():
                seconds, peak = timed(lambda: filt.lowpass(image, alpha, k), args.repeats)
                diff = np.abs(filt.lowpass(image, alpha, k) - reference)
                err, garment = float(diff.max()), diff[alpha > 0]
                records.append({"role": "filter", "implementation": name.partition(":")[0], "preset": f"{size}px",
                                "settings": {"size": size, "kernel_size": k, "naive_extrapolated": size > args.naive_max,
                                             **dict(filt.options or {})},
                                "seconds": seconds, "peak_mb": round(peak, 1),
                                "errors": {"max_abs": err, "max_abs_garment": float(garment.max()),
                                           "mean_abs_garment": float(garment.mean()), "naive_seconds": naive_s,
                                           "speedup_vs_naive": naive_s / seconds},
                                "versions": env})
                rows.append({"size": size, "k": k, "backend": name, "ms": f"{1e3 * seconds:.1f}",
                             "x naive": f"{naive_s / seconds:.1f}", "max err": f"{err:.1e}",
                             "garment max/mean err": f"{garment.max():.1e}/{garment.mean():.1e}",
                             "peak MB": f"{peak:.0f}"})
                print(" ".join(f"{key}={value}" for key, value in rows[-1].items()), flush=True)  # progress
    print_table(rows, ["size", "k", "backend", "ms", "x naive", "max err", "garment max/mean err", "peak MB"])
    Path(args.out).write_text(json.dumps(records, indent=1) + "\n")
    print(f"wrote {len(records)} records to {args.out}")
    return records


if __name__ == "__main__":
    main()
