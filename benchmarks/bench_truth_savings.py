#!/usr/bin/env python
"""Two ways to cut the converged fibre truth's cost, measured as ratios within one run.

``pgc eval`` renders each truth view in passes of 64 samples until the garment's relative noise reaches 4 %
(docs/synth.md, "Converged truth"). For each fabric and light, on a few dome views of the preset's scene at rest:

- ``crop_speedup``: seconds of a pass on the whole film over seconds of a pass on the film cropped to the
  garment's bounding box (2 px margin), the two interleaved, ``--repeats`` of each (Mitsuba's film crop);
- ``allocation_gain``: from ``--passes`` passes, each garment pixel's standard deviation ``s``; sampling each
  pixel in proportion to ``s`` reaches the same coverage-weighted mean variance with ``E[s^2] / E[s]^2`` times
  fewer samples than sampling every pixel alike (the most any per-pixel allocation can save);
- ``median_sd``: the median garment pixel's standard deviation of one pass over the garment's mean brightness.

    python benchmarks/bench_truth_savings.py [--preset default] [--fabrics fleece] [--lights capture,low-key]
        [--views 2] [--passes 8] [--repeats 3] [--out bench_truth_savings.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_filter import print_table  # noqa: E402  (shared benchmark helpers)

SPP = 64


def light_named(name: str, capture_light):
    """The capture light, or an evaluation light of :data:`pgc.pipeline.relight.EVAL_LIGHTS` by name."""
    from dataclasses import replace

    from pgc.pipeline.relight import ENVMAP_HEIGHT, EVAL_LIGHTS
    from pgc.synth.rig import relight_envmap

    light = EVAL_LIGHTS[name]
    if light.envmap is None:
        return capture_light
    return replace(capture_light, envmap=relight_envmap(ENVMAP_HEIGHT, light.envmap).astype(np.float32),
                   rotation_deg=light.rotation_deg)


def garment_box(coverage: np.ndarray, margin: int = 2) -> tuple[int, int, int, int]:
    """(x0, y0, width, height) of the pixels with garment coverage, grown by ``margin`` within the image."""
    ys, xs = np.nonzero(coverage > 0)
    h, w = coverage.shape
    x0, y0 = max(int(xs.min()) - margin, 0), max(int(ys.min()) - margin, 0)
    return x0, y0, min(int(xs.max()) + margin + 1, w) - x0, min(int(ys.max()) + margin + 1, h) - y0


def crop_speedup(renderer, scene, camera, box: tuple[int, int, int, int], sampler: str, repeats: int) -> float:
    """Whole-film pass seconds over cropped-film pass seconds (interleaved; results forced to host memory)."""
    from pgc_mitsuba.runtime import mitsuba
    from pgc_mitsuba.synth_scene import sensor_dict

    mi = mitsuba()
    spec = sensor_dict(camera, SPP, sampler)
    spec["film"].update(crop_offset_x=box[0], crop_offset_y=box[1], crop_width=box[2], crop_height=box[3])
    cropped = mi.load_dict(spec)
    whole = crop = 0.0
    for k in range(repeats + 1):  # the first of each compiles its kernel
        start = time.perf_counter()
        renderer.render_color(scene, camera, SPP, k, sampler)
        middle = time.perf_counter()
        np.asarray(mi.render(scene, sensor=cropped, spp=SPP, seed=k))
        if k:
            whole, crop = whole + middle - start, crop + time.perf_counter() - middle
    return whole / crop


def noise_spread(renderer, scene, camera, coverage: np.ndarray, sampler: str, passes: int) -> tuple[float, float]:
    """(allocation gain, median relative standard deviation of one pass) over the garment (see module doc)."""
    from pgc.synth.frames import pass_seed

    stack = np.array([renderer.render_color(scene, camera, SPP, pass_seed(1, k), sampler)[0] for k in range(passes)],
                     np.float64)
    sd = np.sqrt(stack.var(0, ddof=1).mean(-1))
    w = coverage / coverage.sum()
    gain = float((w * sd ** 2).sum() / (w * sd).sum() ** 2)
    brightness = float((w * stack.mean(0).mean(-1)).sum())
    return gain, float(np.median(sd[coverage > 0.5]) / brightness)


def study(preset: str, fabric: str, lights: list[str], seed: int, views: int, passes: int, repeats: int,
          cfg) -> list[dict]:
    from pgc.sampling import spread
    from pgc.synth.generate import build_scene, resolve_preset
    from pgc.synth.render import scene_renderer

    renderer = scene_renderer(cfg)
    p = resolve_preset(preset, fabric=fabric)
    synth = build_scene(p, seed, cfg.create("body_model"))
    geometry = synth.ground_truth.geometry()
    rows = []
    for name in lights:
        scene, labels = renderer.build_scene(geometry, light_named(name, synth.ground_truth.light))
        for camera in spread(synth.cameras, views):
            coverage = renderer.ground_truth_layers(scene, labels, geometry, camera, p.gt_samples)["garment_coverage"]
            box = garment_box(coverage)
            gain, median_sd = noise_spread(renderer, scene, camera, coverage, p.sampler, passes)
            rows.append({"preset": preset, "fabric": fabric, "seed": seed, "light": name, "view": camera.name,
                         "box_fraction": round(box[2] * box[3] / (camera.width * camera.height), 3),
                         "crop_speedup": round(crop_speedup(renderer, scene, camera, box, p.sampler, repeats), 3),
                         "allocation_gain": round(gain, 3), "median_sd": round(median_sd, 3)})
            print_table(rows[-1:], list(rows[-1]))
    return rows


def main() -> None:
    from pgc.config import load

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="default")
    ap.add_argument("--fabrics", default="fleece", help="comma-separated fabrics of the preset")
    ap.add_argument("--lights", default="capture,low-key", help="comma-separated evaluation lights")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--views", type=int, default=2, help="dome views, spread around the garment")
    ap.add_argument("--passes", type=int, default=8, help="passes of 64 samples for each pixel's deviation")
    ap.add_argument("--repeats", type=int, default=3, help="timed passes of each film (after one warm-up)")
    ap.add_argument("--out", default="bench_truth_savings.json")
    args = ap.parse_args()
    cfg = load()
    rows = []
    for fabric in args.fabrics.split(","):
        rows += study(args.preset, fabric, args.lights.split(","), args.seed, args.views, args.passes, args.repeats,
                      cfg)
    print()
    print_table(rows, list(rows[0]))
    Path(args.out).write_text(json.dumps(rows, indent=2))
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
