"""What a fibre truth costs and how many samples its ground truth needs: CPU seconds and noise per spp.

For each fabric, the synth preset's scene (seed 0 unless told) is built as ``pgc synth`` builds it; then, on a few
of its dome views: the scene build (CPU seconds, with and without the fibres), the path tracing per view at each
spp, and the noise of each spp's image against a high-spp reference, measured with the evaluation's own metrics
on the garment region over black (as ``pgc eval`` compares): PSNR, LPIPS, FSIM. CPU seconds are the process's
user + system time (every Mitsuba thread), so they hold on a shared machine where wall seconds do not.

    python benchmarks/bench_fibre_truth.py [--preset default] [--fabrics cotton-sheen,cotton] [--views 3]
        [--spps 4,16,64] [--ref-spp 1024] [--out bench_fibre_truth.json]
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import numpy as np


def cpu_seconds() -> float:
    """User + system CPU seconds of this process so far (all threads)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def timed(fn):
    """``fn()``, its CPU seconds and wall seconds."""
    c, w = cpu_seconds(), time.perf_counter()
    value = fn()
    return value, cpu_seconds() - c, time.perf_counter() - w


def study(preset: str, fabric: str, seed: int, views: int, spps: list[int], ref_spp: int, cfg) -> dict:
    from dataclasses import replace

    from pgc.sampling import spread
    from pgc.synth.generate import build_scene, resolve_preset
    from pgc.synth.render import scene_renderer

    renderer = scene_renderer(cfg)
    p = resolve_preset(preset, fabric=fabric)
    synth = build_scene(p, seed, cfg.create("body_model"))
    gt = synth.ground_truth
    geometry = gt.geometry()
    bare = replace(geometry, fibres=None)
    renderer.build_scene(bare, gt.light)  # the first build also loads the plugins
    _, bare_cpu, _ = timed(lambda: renderer.build_scene(bare, gt.light))
    (scene, labels), build_cpu, build_wall = timed(lambda: renderer.build_scene(geometry, gt.light))
    metrics = cfg.roles["metric"].create_all()
    cameras = spread(synth.cameras, views)
    for spp in spps:  # a kernel is compiled per sample count (cached for every camera after)
        renderer.render_color(scene, cameras[0], spp, 0, p.sampler)
    rows: dict[int, dict[str, list[float]]] = {s: {"cpu": [], **{m: [] for m in metrics}} for s in spps}
    ref_cpu = []
    for i, cam in enumerate(cameras):
        cover = renderer.ground_truth_layers(scene, labels, geometry, cam, p.gt_samples)["garment_coverage"]
        (ref, _), c, _ = timed(lambda: renderer.render_color(scene, cam, ref_spp, 7919 + i, p.sampler))
        ref_cpu.append(c)
        target = ref * cover[..., None]
        region = (cover > 0.5).astype(np.float32)
        for spp in spps:
            (img, _), c, _ = timed(lambda: renderer.render_color(scene, cam, spp, i, p.sampler))
            rows[spp]["cpu"].append(c)
            for name, metric in metrics.items():
                rows[spp][name].append(float(metric(img * cover[..., None], target, region)))
    return {"preset": preset, "fabric": fabric, "seed": seed, "views": [c.name for c in cameras],
            "fibres": 0 if gt.fibres is None else len(gt.fibres.face), "resolution": p.resolution,
            "scene_build_cpu_s": build_cpu, "scene_build_wall_s": build_wall, "scene_build_without_fibres_cpu_s": bare_cpu,
            "ref_spp": ref_spp, "ref_cpu_s_per_view": float(np.mean(ref_cpu)),
            "per_spp": {str(s): {k: float(np.mean(v)) for k, v in r.items()} for s, r in rows.items()}}


def main() -> None:
    from pgc.config import load

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="default")
    ap.add_argument("--fabrics", default="cotton-sheen,cotton")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--views", type=int, default=3)
    ap.add_argument("--spps", default="4,16,64")
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--out", default="bench_fibre_truth.json")
    args = ap.parse_args()
    cfg = load()
    records = []
    for fabric in args.fabrics.split(","):
        rec = study(args.preset, fabric, args.seed, args.views, [int(s) for s in args.spps.split(",")],
                    args.ref_spp, cfg)
        records.append(rec)
        print(f"{fabric}: {rec['fibres']} fibres, scene build {rec['scene_build_cpu_s']:.1f} s CPU "
              f"({rec['scene_build_without_fibres_cpu_s']:.1f} without fibres), reference {args.ref_spp} spp "
              f"{rec['ref_cpu_s_per_view']:.1f} s CPU a view")
        for spp, r in rec["per_spp"].items():
            print(f"  {spp:>5} spp: {r['cpu']:.2f} s CPU a view; against the reference "
                  + ", ".join(f"{k} {v:.4f}" for k, v in r.items() if k != "cpu"))
        Path(args.out).write_text(json.dumps(records, indent=2))


if __name__ == "__main__":
    main()
