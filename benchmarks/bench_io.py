#!/usr/bin/env python
"""Speed against error of the file formats: capture directories (PNG 8/16-bit, EXR) and the 3DGS .ply.

Times are reported as ratios to ``numpy.save`` of the same arrays (raw bytes, no compression, no fsync)
measured in the same run, because wall-clock seconds on a shared machine are noisy. Errors: the largest
absolute round-trip difference of the colour images in linear RGB (and in sRGB code units), of the masks,
and of the Gaussian parameters. Peak memory is traced with tracemalloc (numpy buffers included).
Records (JSON) follow docs/bench.md, "Record schema".

    python benchmarks/bench_io.py [--views 32] [--size 256] [--gaussians 200000] [--out bench_io.json]
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any, Callable

import numpy as np


def measure(fn: Callable[[], Any], repeats: int) -> tuple[float, float, Any]:
    """Median seconds over ``repeats`` calls, peak traced memory (MB) and the last result."""
    times, result = [], None
    tracemalloc.start()
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    peak = tracemalloc.get_traced_memory()[1] / 2 ** 20
    tracemalloc.stop()
    return statistics.median(times), peak, result


def folder_mb(path: Path) -> float:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) / 2 ** 20


def synthetic_capture(views: int, size: int, seed: int = 0):
    """Smooth images with noise (compress like photographs, not like white noise) on a ring of cameras."""
    from pgc.types import Camera, Capture, View

    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] / size
    out = []
    for i in range(views):
        a = 2 * np.pi * i / views
        c, s = np.cos(a), np.sin(a)
        R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
        cam = Camera(K=np.array([[size, 0, size / 2], [0, size, size / 2], [0, 0, 1]]), R=R, t=[0, 0, 3.0],
                     width=size, height=size, name=f"cam{i:03d}")
        base = np.stack([0.5 + 0.4 * np.sin(6 * xx + a), 0.4 + 0.3 * np.cos(5 * yy), 0.3 + 0.2 * xx * yy], -1)
        image = np.clip(base + rng.normal(0, 0.01, base.shape), 0, 1).astype(np.float32)
        mask = ((xx - 0.5) ** 2 + (yy - 0.5) ** 2 < 0.1).astype(np.float32)
        out.append(View(cam, image, mask=mask, segmentation=(2 * mask).astype(np.uint8),
                        background=np.full((size, size, 3), 0.2, np.float32),
                        extras={"albedo": base.astype(np.float32), "depth": (2.5 + xx).astype(np.float32)}))
    return Capture(out)


def bench_capture(views: int, size: int, repeats: int, versions: dict[str, str]) -> list[dict[str, Any]]:
    from pgc.io.capture import read_capture, write_capture
    from pgc.io.images import linear_to_srgb

    capture = synthetic_capture(views, size)
    arrays = {f"{k}{i}": v for i, view in enumerate(capture.views)
              for k, v in [("i", view.image), ("m", view.mask), ("s", view.segmentation), ("b", view.background),
                           ("a", view.extras["albedo"]), ("d", view.extras["depth"])]}
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        ref_s, _, _ = measure(lambda: np.savez(Path(tmp) / "ref.npz", **arrays), repeats)
        for fmt in ("png", "png16", "exr"):
            folder = Path(tmp) / fmt

            def write() -> None:
                shutil.rmtree(folder, ignore_errors=True)
                write_capture(folder, capture, image_format=fmt)

            write_s, write_mb, _ = measure(write, repeats)
            read_s, read_mb, back = measure(lambda: read_capture(folder), repeats)
            img = max(float(np.abs(b.image - a.image).max()) for a, b in zip(capture.views, back.views))
            img_srgb = max(float(np.abs(linear_to_srgb(b.image) - linear_to_srgb(a.image)).max())
                           for a, b in zip(capture.views, back.views))
            mask = max(float(np.abs(b.mask - a.mask).max()) for a, b in zip(capture.views, back.views))
            records.append({
                "role": "io", "implementation": f"capture-{fmt}", "preset": f"{views}x{size}px",
                "settings": {"views": views, "size": size, "image_format": fmt},
                "seconds": write_s + read_s, "peak_mb": max(write_mb, read_mb),
                "errors": {"image_linear_max": img, "image_srgb_max": img_srgb, "mask_max": mask},
                "write_s": write_s, "read_s": read_s, "write_ratio": write_s / ref_s, "read_ratio": read_s / ref_s,
                "size_mb": folder_mb(folder), "versions": versions})
    return records


def bench_gaussians(n: int, repeats: int, versions: dict[str, str]) -> list[dict[str, Any]]:
    from pgc.io.gaussians_ply import read_bound_gaussians_ply, read_world_gaussians_ply, write_bound_gaussians_ply
    from pgc.splats.binding import bind
    from pgc.types import GaussianSet

    rng = np.random.default_rng(1)
    vertices = rng.normal(size=(n // 20, 3))
    faces = rng.integers(0, len(vertices), (n // 10, 3))
    g = GaussianSet(parent=rng.integers(0, len(faces), n), means=rng.normal(size=(n, 3)), quats=rng.normal(size=(n, 4)),
                    log_scales=rng.normal(-3, 1, (n, 3)), opacity_logits=rng.normal(size=n),
                    sh=rng.normal(size=(n, 16, 3)))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "g.ply"
        ref_s, _, _ = measure(lambda: np.savez(Path(tmp) / "ref.npz", p=g.parent, m=g.means, q=g.quats,
                                               s=g.log_scales, o=g.opacity_logits, sh=g.sh), repeats)
        write_s, write_mb, _ = measure(lambda: write_bound_gaussians_ply(path, g, vertices, faces), repeats)
        read_s, read_mb, back = measure(lambda: read_bound_gaussians_ply(path), repeats)
        world_s, _, world = measure(lambda: read_world_gaussians_ply(path), repeats)
        exact = all(np.array_equal(getattr(back, k), getattr(g, k))
                    for k in ("parent", "means", "quats", "log_scales", "opacity_logits", "sh"))
        ref = bind(g, vertices, faces)
        size_mb = path.stat().st_size / 2 ** 20
    return [{"role": "io", "implementation": "gaussians-ply-bound", "preset": f"{n} gaussians, SH degree 3",
             "settings": {"gaussians": n, "sh_degree": 3}, "seconds": write_s + read_s,
             "peak_mb": max(write_mb, read_mb),
             "errors": {"binding_exact": float(exact),
                        "world_means_rel_max": float(np.abs(world.means - ref.means).max() / np.abs(ref.means).max()),
                        "world_scales_rel_max": float(np.max(np.abs(world.scales - ref.scales) / ref.scales))},
             "write_s": write_s, "read_s": read_s, "read_world_s": world_s, "write_ratio": write_s / ref_s,
             "read_ratio": read_s / ref_s, "size_mb": size_mb, "versions": versions}]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=int, default=32)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--gaussians", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default="bench_io.json")
    args = parser.parse_args()
    from pgc.io.asset import package_versions

    versions = package_versions(("pgc", "numpy", "pillow", "openexr", "opencv-python-headless"))
    records = bench_capture(args.views, args.size, args.repeats, versions)
    records += bench_gaussians(args.gaussians, args.repeats, versions)
    print(f"{'implementation':<22} {'preset':<28} {'write/np.save':>13} {'read/np.save':>12} {'MB':>6}  errors")
    for r in records:
        errors = ", ".join(f"{k}={v:.2e}" for k, v in r["errors"].items())
        print(f"{r['implementation']:<22} {r['preset']:<28} {r['write_ratio']:>13.1f} {r['read_ratio']:>12.1f} "
              f"{r['size_mb']:>6.1f}  {errors}")
    Path(args.out).write_text(json.dumps(records, indent=1) + "\n")
    print(f"records: {args.out}")


if __name__ == "__main__":
    main()
