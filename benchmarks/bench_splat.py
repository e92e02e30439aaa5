#!/usr/bin/env python
"""Speed against error of the ``splat_renderer`` backends, and the time-to-PSNR curve of the splat fit.

Forward and forward+backward seconds per view for every installed splat renderer (built through the
registry) at each image size and Gaussian count, on Gaussians covering the surface of the test body
(pgc.testing.capture_scenes) with a fitted-like density; ratios to the torch renderer of the same run. The float64
per-pixel reference (pgc.splats.reference) runs only on a tiny scene (it loops over pixels in Python); there
each backend's time is also a ratio to it and its error is the largest absolute difference to it. At the
larger sizes the error is the largest difference to the torch image. ``--fit`` also fits splats on a capture
(``--capture DIR``, e.g. the output of ``pgc synth OUT --preset default``, or the test body at 256 px) and
records the held-out PSNR against time. Records (JSON): role, implementation, preset, settings, seconds,
errors, versions.

The kernel table (``--kernel-sizes``, ``--kernel-counts``; default 256 px, 50k Gaussians) times one view on
every render path side by side: the torch renderer's "fused" (one compiled call each way) and "torch" (the
shared projection, pure-torch compositing; at the first thread count only) and the JAX renderer's
forward+backward on the fused kernel and on XLA's compositor; it reports Gaussian-pixel pairs per
second (pairs inside the footprint boxes, counted by the fused kernel) and, from the same run, this machine's
float FMA peak and exp throughput (compiled loops with the kernel's flags) and torch's sgemm GFLOP/s, so the
kernel's FLOP rate (FORWARD_FLOPS / BACKWARD_FLOPS per pair) shows as a fraction of them. Times there are CPU
seconds of all threads (the machine is shared; wall seconds are recorded too), measured at each of ``--threads``
(default 1 and 2 kernel threads); throughputs are per second of one core's time (CPU seconds / threads).

    python benchmarks/bench_splat.py [--sizes 128 256 512] [--counts 10000 50000 200000] [--fit] [--out FILE]
    python benchmarks/bench_splat.py --sizes --kernel-sizes 256 --kernel-counts 10000 50000 --threads 1 2
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_filter import PeakRSS, print_table, timed  # noqa: E402


def surface_scene(count: int, size: int, seed: int = 0):
    """World Gaussians on the test body (flat discs of the sampling spacing, opacity 0.8) and a dome camera."""
    from pgc.testing.capture_scenes import body_mesh, dome_cameras
    from pgc.splats.binding import bind
    from pgc.splats.init import sample_on_mesh

    mesh = body_mesh(0.03)
    g = sample_on_mesh(mesh, count, np.random.default_rng(seed), sh_degree=3)
    g.sh[:, 1:] = np.random.default_rng(seed + 1).normal(0, 0.05, g.sh[:, 1:].shape)
    world = bind(g, mesh.vertices, mesh.faces)
    spacing = np.sqrt(mesh.face_areas().sum() / count)
    world.scales = np.tile([spacing, spacing * 0.2, spacing], (count, 1))
    world.opacities = np.full(count, 0.8)
    return world, dome_cameras(4, size)[1]


def tiny_scene(count: int = 300, size: int = 32, seed: int = 0):
    from pgc.types import Camera, WorldGaussians

    rng = np.random.default_rng(seed)
    means = np.c_[rng.uniform(-0.35, 0.35, count), rng.uniform(-0.35, 0.35, count), rng.uniform(0.8, 1.6, count)]
    world = WorldGaussians(means, rng.normal(size=(count, 4)), rng.uniform(0.005, 0.05, (count, 3)),
                           rng.uniform(0.1, 1.0, count), rng.normal(0, 0.3, (count, 16, 3)))
    return world, Camera(np.array([[size, 0, size / 2], [0, size, size / 2], [0, 0, 1]]), np.eye(3), np.zeros(3),
                         size, size)


def torch_backward(renderer, world, camera):
    """Forward+backward of the torch renderer (sum of colour and alpha) w.r.t. every world parameter; the
    closure returns the gradients (numpy)."""
    import torch

    from pgc.splats.quaternion import quat_to_rotmat
    from pgc_torch.threads import torch_threads

    @torch_threads(1)
    def run() -> list[np.ndarray]:
        p = [torch.tensor(np.asarray(x), dtype=torch.float32, requires_grad=True)
             for x in (world.means, world.quats, world.scales, world.opacities, world.sh)]
        color, alpha, _ = renderer.rasterize(p[0], quat_to_rotmat(p[1]), p[2], p[3], p[4], camera)
        (color.sum() + alpha.sum()).backward()
        return [t.grad.numpy() for t in p]
    return run


def jax_backward(renderer, world, camera):
    """Forward+backward of the JAX renderer (sum of colour and alpha) w.r.t. every world parameter, jitted, on
    its compositor: the fused kernel as a custom VJP, or the XLA compositor on bins built once per call; the
    closure returns the gradients (numpy)."""
    import jax
    import jax.numpy as jnp

    from pgc.splats.quaternion import quat_to_rotmat
    from pgc_jax.splat.fused import camera_bits, fused_render
    from pgc_jax.splat.render import camera_arrays, make_bins, render_bound

    o = renderer.options
    arrays = [jnp.asarray(np.asarray(x), jnp.float32) for x in
              (world.means, world.quats, world.scales, world.opacities, world.sh)]
    h, w = camera.height, camera.width
    bg = jnp.zeros((h, w, 3), jnp.float32)
    if renderer.compositor == "fused":
        bits, threads = jnp.asarray(camera_bits(camera, o.near)), renderer.threads

        @jax.jit
        def grads(m, q, s, a, c):
            def loss(m, q, s, a, c):
                color, alpha, _ = fused_render(m, quat_to_rotmat(q), s, a, c, bits, bg, height=h, width=w,
                                               count=c.shape[1], threads=threads)
                return color.sum() + alpha.sum()
            return jax.grad(loss, argnums=(0, 1, 2, 3, 4))(m, q, s, a, c)

        return lambda: [np.asarray(g) for g in jax.block_until_ready(grads(*arrays))]
    cam = camera_arrays(camera, jnp.float32)

    def run() -> list[np.ndarray]:
        means, quats, scales, opac, sh = arrays
        bins = make_bins(means, quat_to_rotmat(quats), scales, opac, camera, cam, tile=o.tile_size,
                         chunk=o.chunk_size, near=o.near)

        def loss(m, q, s, a, c):
            color, alpha, _ = render_bound(m, quat_to_rotmat(q), s, a, c, cam, bg, bins.gauss, bins.tile, bins.first,
                                           width=w, height=h, tile=o.tile_size, sh_degree=3, near=o.near)
            return color.sum() + alpha.sum()

        grads = jax.block_until_ready(jax.grad(loss, argnums=(0, 1, 2, 3, 4))(means, quats, scales, opac, sh))
        return [np.asarray(g) for g in grads]
    return run


BACKWARD = {"torch": torch_backward, "jax": jax_backward}

FORWARD_FLOPS = 50
"""Floating-point operations per pixel-Gaussian pair of the fused forward (power 10, exp 26, compositing 14)."""
BACKWARD_FLOPS = 110
"""Per pair of the fused backward (the forward's alpha again, transmittance restore, 10 gradient sums)."""


def sgemm_flops(threads: int, n: int = 1024, repeats: int = 5) -> float:
    """torch float32 matrix-multiply FLOP per CPU-second on ``threads`` threads (best of ``repeats``)."""
    import torch

    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        a, b = torch.randn(n, n), torch.randn(n, n)
        a @ b
        best = float("inf")
        for _ in range(repeats):
            start = time.process_time()
            a @ b
            best = min(best, time.process_time() - start)
    finally:
        torch.set_num_threads(old)
    return 2.0 * n ** 3 / best * threads


def kernel_benchmarks(args, reg, env) -> list[dict[str, Any]]:
    """Every render path on one view, pair throughput and its fraction of the measured machine peaks."""
    import torch

    from pgc.splats import fused
    from pgc.splats.quaternion import quat_to_rotmat
    from pgc_torch.splat.rasterizer import rasterize
    from pgc_torch.threads import torch_threads

    known = {i.name: i for i in reg.list("splat_renderer")}
    jax_ok = "jax" in known and known["jax"].available
    records, rows = [], []
    for threads, size, count in ((t, s, c) for t in args.threads for s in args.kernel_sizes
                                 for c in args.kernel_counts):
        peaks = fused.machine_peaks(threads)
        peaks["sgemm_flops"] = sgemm_flops(threads)
        print(f"  machine ({threads} threads, per second of CPU time of each): FMA peak "
              f"{peaks['fma_flops'] / 1e9:.1f} GFLOP/s, exp {peaks['exp_per_s'] / 1e9:.2f} G/s, torch sgemm "
              f"{peaks['sgemm_flops'] / 1e9:.1f} GFLOP/s")
        world, camera = surface_scene(count, size)
        label = f"{size}px/{count // 1000}k"
        rot = quat_to_rotmat(torch.tensor(np.asarray(world.quats), dtype=torch.float64)).float()
        base = [torch.tensor(np.asarray(x), dtype=torch.float32) for x in
                (world.means, world.scales, world.opacities, world.sh)]
        stats = fused.render_stats([x.numpy() for x in (base[0], rot, *base[1:])], camera, count=world.sh.shape[1],
                                   threads=threads)

        def forward(backend: str):
            @torch_threads(1)
            def run() -> None:
                with torch.no_grad():
                    rasterize(base[0], rot, *base[1:], camera, backend=backend, threads=threads)
            return run

        def backward(backend: str):
            @torch_threads(1)
            def run() -> None:
                p = [x.clone().requires_grad_() for x in (base[0], rot, *base[1:])]
                color, alpha, _ = rasterize(*p, camera, backend=backend, threads=threads)
                (color.sum() + alpha.sum()).backward()
            return run

        measured = {}
        for backend in ("fused", "torch") if threads == args.threads[0] else ("fused",):  # torch: one thread
            measured[backend] = (min_time(forward(backend), args.repeats),
                                 min_time(backward(backend), args.repeats))
        if jax_ok:  # forward+backward only (the JAX forward is the same kernel call, or XLA's)
            measured["jax/fused"] = ((float("nan"), float("nan")), min_time(BACKWARD["jax"](
                known["jax"].create({"compositor": "fused", "threads": threads}), world, camera), args.repeats))
            if threads == args.threads[0]:  # XLA runs its own thread pool: once
                measured["jax/xla"] = ((float("nan"), float("nan")), min_time(BACKWARD["jax"](
                    known["jax"].create({"compositor": "xla"}), world, camera), args.repeats))
        (f_fused, fc_fused), (b_fused, bc_fused) = measured["fused"]
        for name, ((fwd, fwd_cpu), (fwdbwd, fwdbwd_cpu)) in measured.items():
            # throughput per second of the cores' time: CPU seconds of all threads / threads
            fwd_rate = stats["pairs"] / (fwd_cpu / threads)
            bwd_cpu = fwdbwd_cpu - fwd_cpu
            bwd_rate = stats["pairs"] / (bwd_cpu / threads) if bwd_cpu > 0 else float("nan")
            figures = {"pairs": stats["pairs"], "pairs_per_s_forward": fwd_rate, "pairs_per_s_backward": bwd_rate,
                       "forward_fraction_of_sgemm": fwd_rate * FORWARD_FLOPS / peaks["sgemm_flops"],
                       "forward_fraction_of_fma_peak": fwd_rate * FORWARD_FLOPS / peaks["fma_flops"],
                       "backward_fraction_of_fma_peak": bwd_rate * BACKWARD_FLOPS / peaks["fma_flops"],
                       "exp_fraction_forward": fwd_rate / peaks["exp_per_s"],
                       "fwdbwd_cpu_ratio_to_fused": fwdbwd_cpu / bc_fused, "fwdbwd_wall_ratio_to_fused":
                       fwdbwd / b_fused, "seconds_cpu": fwd_cpu, "seconds_forward_backward_cpu": fwdbwd_cpu}
            records.append({"role": "splat_renderer", "implementation": name if name.startswith("jax") else f"torch/{name}",
                            "preset": label, "settings": {"size": size, "gaussians": count,
                                                          "threads": threads},
                            "seconds": fwd, "seconds_forward_backward": fwdbwd, "errors": figures,
                            "machine": peaks, "versions": env})
            rows.append({"scene": label, "threads": threads, "path": name, "fwd cpu ms": f"{1e3 * fwd_cpu:.1f}",
                         "fwd+bwd cpu ms": f"{1e3 * fwdbwd_cpu:.1f}",
                         "fwd+bwd / fused": f"{fwdbwd_cpu / bc_fused:.2f}",
                         "wall fwd / fwd+bwd ms": f"{1e3 * fwd:.0f} / {1e3 * fwdbwd:.0f}",
                         "fwd Mpair/s": f"{fwd_rate / 1e6:.0f}", "bwd Mpair/s": f"{bwd_rate / 1e6:.0f}",
                         "fwd % sgemm": f"{100 * figures['forward_fraction_of_sgemm']:.1f}",
                         "fwd % FMA peak": f"{100 * figures['forward_fraction_of_fma_peak']:.1f}"})
    print_table(rows, ["scene", "threads", "path", "fwd cpu ms", "fwd+bwd cpu ms", "fwd+bwd / fused",
                       "wall fwd / fwd+bwd ms", "fwd Mpair/s", "bwd Mpair/s", "fwd % sgemm", "fwd % FMA peak"])
    return records


def min_time(fn, repeats: int) -> tuple[float, float]:
    """Fastest wall and fastest CPU seconds (this process, all threads) of ``repeats`` calls after a warm-up.

    On a shared machine the wall clock counts time other processes hold the cores; CPU seconds do not.
    """
    fn()
    wall, cpu = float("inf"), float("inf")
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        wall, cpu = min(wall, time.perf_counter() - start), min(cpu, time.process_time() - start_cpu)
    return wall, cpu


def renderer_benchmarks(args, reg, env) -> list[dict[str, Any]]:
    from pgc.splats.reference import render_reference

    known = {i.name: i for i in reg.list("splat_renderer")}
    renderers = {n: known[n].create() for n in args.backends if n in known and known[n].available}
    records, rows = [], []
    scenes = [("tiny", *tiny_scene())] + [(f"{s}px/{n // 1000}k", *surface_scene(n, s))
                                           for s in args.sizes for n in args.counts]
    for label, world, camera in scenes:
        reference = None
        if label == "tiny":
            start = time.perf_counter()
            reference = render_reference(world, camera)
            ref_s = time.perf_counter() - start
        base: dict[str, float] = {}
        images = {}
        for name, r in renderers.items():
            fwd, peak = timed(lambda: r.render(world, camera), args.repeats)
            images[name] = r.render(world, camera).color
            try:
                bwd, peak_b = timed(BACKWARD[name](r, world, camera), args.repeats)
            except Exception as exc:  # a backend without a differentiable entry point here: report, go on
                bwd, peak_b = float("nan"), float("nan")
                print(f"  {name}: forward+backward not measured ({type(exc).__name__}: {exc})", file=sys.stderr)
            base.setdefault("fwd", fwd)
            base.setdefault("bwd", bwd)
            errors = {"fwd_ratio_to_first": fwd / base["fwd"], "fwdbwd_ratio_to_first": bwd / base["bwd"]}
            if reference is not None:
                errors |= {"max_abs_vs_reference": float(np.abs(images[name] - reference.color).max()),
                           "reference_seconds": ref_s, "speedup_vs_reference": ref_s / fwd}
            else:
                first = next(iter(images.values()))
                errors["max_abs_vs_first"] = float(np.abs(images[name] - first).max())
            records.append({"role": "splat_renderer", "implementation": name, "preset": label,
                            "settings": {"size": camera.width, "gaussians": len(world.means)}, "seconds": fwd,
                            "seconds_forward_backward": bwd, "peak_mb": round(max(peak, peak_b), 1),
                            "errors": errors, "versions": env})
            print(f"  {label} {name}: forward {1e3 * fwd:.0f} ms, forward+backward {1e3 * bwd:.0f} ms", flush=True)
            rows.append({"scene": label, "backend": name, "fwd ms": f"{1e3 * fwd:.0f}", "fwd+bwd ms": f"{1e3 * bwd:.0f}",
                         "fwd / first": f"{errors['fwd_ratio_to_first']:.2f}",
                         "fwd+bwd / first": f"{errors['fwdbwd_ratio_to_first']:.2f}",
                         "x reference": f"{errors['speedup_vs_reference']:.0f}" if reference is not None else "",
                         "max err": f"{errors.get('max_abs_vs_reference', errors.get('max_abs_vs_first')):.1e}",
                         "peak MB": f"{max(peak, peak_b):.0f}"})
    print_table(rows, ["scene", "backend", "fwd ms", "fwd+bwd ms", "fwd / first", "fwd+bwd / first", "x reference",
                       "max err", "peak MB"])
    return records


def fit_benchmark(args, reg, env) -> list[dict[str, Any]]:
    if args.capture:
        from pgc.io.capture import read_capture
        from pgc.io.mesh import read_mesh

        capture = read_capture(args.capture)
        mesh = read_mesh(Path(args.capture) / args.mesh)
    else:
        from pgc.testing.capture_scenes import body_mesh, make_capture

        capture, mesh = make_capture(body_mesh(0.02), views=32, size=256)
    records = []
    for name in args.fit_backends:
        renderer = reg.create("splat_renderer", name)
        start, cpu = time.perf_counter(), time.process_time()
        with PeakRSS() as mem:
            fit = renderer.fit(capture, mesh, {"iterations": args.fit_iterations, "keep": "all"})
        seconds = time.perf_counter() - start
        f = fit.figures
        records.append({"role": "splat_renderer", "implementation": name, "preset": args.capture or "testscene-256",
                        "settings": {"stage": "fit_splats", "iterations": args.fit_iterations}, "seconds": seconds,
                        "cpu_seconds": time.process_time() - cpu, "peak_mb": round(mem.mb, 1),
                        "errors": {"psnr_heldout": f.get("psnr_heldout"), "time_to_psnr": f.get("time_to_psnr"),
                                   "iterations": f.get("iterations"), "gaussians": f.get("gaussians")},
                        "versions": env})
        print(f"fit {name}: {seconds:.0f} s wall, held-out PSNR {f.get('psnr_heldout'):.2f} dB, "
              f"{f.get('iterations')} steps, {f.get('gaussians')} Gaussians")
        for point in f.get("time_to_psnr", []):
            print(f"  {point['seconds']:7.1f} s  step {point['iteration']:5d}  {point['psnr_heldout']:.2f} dB")
    return records


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[128, 256, 512])
    parser.add_argument("--counts", type=int, nargs="+", default=[10000, 50000, 200000])
    parser.add_argument("--backends", nargs="+", default=["torch", "jax"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--kernel-sizes", type=int, nargs="*", default=[256])
    parser.add_argument("--kernel-counts", type=int, nargs="*", default=[50000])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="kernel threads of the kernel table")
    parser.add_argument("--fit", action="store_true", help="also measure the fit's time-to-PSNR curve")
    parser.add_argument("--fit-backends", nargs="+", default=["torch"])
    parser.add_argument("--fit-iterations", type=int, default=3000,
                        help="planned fit steps (it stops earlier on convergence)")
    parser.add_argument("--capture", help="capture directory (default: the test body at 256 px, 32 views)")
    parser.add_argument("--mesh", default="gt/body_garment.obj", help="mesh path inside --capture")
    parser.add_argument("--out", default="bench_splat.json")
    args = parser.parse_args(argv)

    from pgc.io.asset import package_versions
    from pgc.registry import default_registry

    reg = default_registry()
    env = package_versions(("pgc", "numpy", "torch", "jax", "jaxlib"))
    records = kernel_benchmarks(args, reg, env)
    if args.sizes:
        records += renderer_benchmarks(args, reg, env)
    if args.fit:
        records += fit_benchmark(args, reg, env)
    Path(args.out).write_text(json.dumps(records, indent=1, default=float) + "\n")
    print(f"wrote {len(records)} records to {args.out}")
    return records


if __name__ == "__main__":
    main()
