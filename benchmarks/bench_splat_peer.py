#!/usr/bin/env python
"""The fused torch splat path against a peer: Mitsuba 3's ray-traced Gaussians, same world Gaussians, same camera.

Peer: the ``ellipsoids`` shape (centres, standard deviations, quaternions, opacities, SH) rendered by the
``volprim_rf_basic`` integrator (linear colours: ``srgb_primitives = False``) in the ``llvm_ad_rgb`` variant at
1 sample per pixel, through PGC's exact OpenCV pinhole sensor (pgc_mitsuba.sensors). Forward = one render;
forward+backward = the render and the gradient of the image sum w.r.t. every parameter the shape exposes
(``data``: centres, scales, quaternions; ``opacities``; ``sh_coeffs``). Ours: ``rasterize(backend="fused")``,
the gradient of colour + alpha sums w.r.t. means, rotation matrices, scales, opacities and SH. Both run on
the same number of threads (each of ``--threads``, default 1 and 2; Dr.Jit's pool set to the same count).
The image difference is the mean absolute difference of the colours (the peer traces one jittered ray per
pixel and composites along the ray in its own order, so the images agree in content, not to rounding).
Seconds after a warm-up call (Mitsuba's kernels are compiled in the warm-up; every call waits for its
asynchronous kernels): the fastest CPU time of ``--repeats`` calls (process, all threads: the machine is
shared) and the median wall time; ratios are of CPU times at equal threads.

    python benchmarks/bench_splat_peer.py [--sizes 256 512] [--counts 10000 50000] [--threads 1 2] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_filter import print_table  # noqa: E402
from bench_splat import surface_scene  # noqa: E402


def times(fn: Callable[[], Any], repeats: int) -> tuple[float, float]:
    """(median wall, min CPU) seconds of ``repeats`` calls after one warm-up call; CPU = this process, all
    threads (on a shared machine the wall clock also counts time other processes hold the cores)."""
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return statistics.median(wall), min(cpu)


def ours(world, camera, threads: int):
    """(forward, forward+backward, colour) callables of the fused torch path."""
    import torch

    from pgc.splats.quaternion import quat_to_rotmat
    from pgc_torch.splat.rasterizer import rasterize

    rot = quat_to_rotmat(torch.tensor(np.asarray(world.quats), dtype=torch.float64)).float()
    base = [torch.tensor(np.asarray(x), dtype=torch.float32) for x in (world.means, world.scales, world.opacities,
                                                                     world.sh)]

    def forward():
        with torch.no_grad():
            return rasterize(base[0], rot, base[1], base[2], base[3], camera, backend="fused", threads=threads)[0]

    def backward():
        p = [x.clone().requires_grad_() for x in (base[0], rot, *base[1:])]
        color, alpha, _ = rasterize(*p, camera, backend="fused", threads=threads)
        (color.sum() + alpha.sum()).backward()

    return forward, backward, lambda: forward().numpy()


def peer(world, camera, threads: int):
    """(forward, forward+backward, colour) callables of Mitsuba's ray-traced Gaussians."""
    import drjit as dr

    from pgc_mitsuba.runtime import mitsuba
    from pgc_mitsuba.sensors import pinhole_sensor

    mi = mitsuba()
    dr.set_thread_count(threads)
    q = np.asarray(world.quats, np.float64)
    q = q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-30)
    n = len(q)
    shape = {"type": "ellipsoids", "centers": mi.TensorXf(np.asarray(world.means, np.float32)),
             "scales": mi.TensorXf(np.asarray(world.scales, np.float32)),
             "quaternions": mi.TensorXf(q[:, [1, 2, 3, 0]].astype(np.float32)),  # (x, y, z, w)
             "opacities": mi.TensorXf(np.asarray(world.opacities, np.float32).reshape(n, 1)),
             "sh_coeffs": mi.TensorXf(np.asarray(world.sh, np.float32).reshape(n, -1))}
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "volprim_rf_basic", "srgb_primitives": False},
                          "gaussians": shape})
    sensor = pinhole_sensor(camera, spp=1)
    params = mi.traverse(scene)
    keys = ["gaussians.data", "gaussians.opacities", "gaussians.sh_coeffs"]

    def forward():
        img = mi.render(scene, sensor=sensor, spp=1, seed=0)
        dr.eval(img)
        dr.sync_thread()  # the LLVM kernels run asynchronously in Dr.Jit's pool: wait for them
        return img

    def backward():
        for k in keys:
            dr.enable_grad(params[k])
        params.update()
        img = mi.render(scene, params, sensor=sensor, spp=1, seed=0)
        dr.backward(dr.sum(img, axis=None))
        grads = [dr.grad(params[k]) for k in keys]
        dr.eval(*grads)
        dr.sync_thread()
        for k in keys:
            dr.disable_grad(params[k])

    return forward, backward, lambda: np.asarray(forward())[..., :3]


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    parser.add_argument("--counts", type=int, nargs="+", default=[10000, 50000])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default="bench_splat_peer.json")
    args = parser.parse_args(argv)

    import torch

    from pgc.io.asset import package_versions

    torch.set_num_threads(1)  # the fused kernel uses its own OpenMP threads
    env = package_versions(("pgc", "numpy", "torch", "mitsuba", "drjit"))
    records, rows = [], []
    for threads, size, count in ((t, s, c) for t in args.threads for s in args.sizes for c in args.counts):
        world, camera = surface_scene(count, size)
        label = f"{size}px/{count // 1000}k"
        runs = {"ours (fused)": ours(world, camera, threads), "mitsuba": peer(world, camera, threads)}
        measured = {}
        for name, (fwd, bwd, image) in runs.items():
            measured[name] = (*times(fwd, args.repeats), *times(bwd, args.repeats), image())
        ref = measured["ours (fused)"]
        for name, (f_wall, f_cpu, b_wall, b_cpu, img) in measured.items():
            diff = float(np.abs(img - ref[4]).mean())
            records.append({"role": "splat_renderer", "implementation": name, "preset": label,
                            "settings": {"size": size, "gaussians": count, "threads": threads, "spp": 1},
                            "seconds": f_wall, "seconds_cpu": f_cpu, "seconds_forward_backward": b_wall,
                            "seconds_forward_backward_cpu": b_cpu,
                            "errors": {"mean_abs_color_vs_ours": diff}, "versions": env})
            rows.append({"scene": label, "threads": threads, "renderer": name, "fwd cpu ms": f"{1e3 * f_cpu:.1f}",
                         "fwd+bwd cpu ms": f"{1e3 * b_cpu:.1f}", "fwd / ours": f"{f_cpu / ref[1]:.2f}",
                         "fwd+bwd / ours": f"{b_cpu / ref[3]:.2f}",
                         "wall fwd / fwd+bwd ms": f"{1e3 * f_wall:.0f} / {1e3 * b_wall:.0f}",
                         "mean |diff|": f"{diff:.3f}"})
            print(f"  {label} {threads} threads {name}: forward {1e3 * f_cpu:.1f} ms, forward+backward "
                  f"{1e3 * b_cpu:.1f} ms (CPU)", flush=True)
    print_table(rows, ["scene", "threads", "renderer", "fwd cpu ms", "fwd+bwd cpu ms", "fwd / ours", "fwd+bwd / ours",
                       "wall fwd / fwd+bwd ms", "mean |diff|"])
    Path(args.out).write_text(json.dumps(records, indent=1, default=float) + "\n")
    print(f"wrote {len(records)} records to {args.out}")
    return records


if __name__ == "__main__":
    main()
