#!/usr/bin/env python
"""Does the capture light let the material fit recover the in-family controls' pgc-sheen parameters?

    python benchmarks/bench_capture_light.py --work DIR [--fabrics F ...] [--seeds 0 1] [--lights uniform sky-sun]
        [--mode truth|pipeline] [--views 6] [--resolution 64] [--spp 16] [--framing body|garment]
        [--config FILE.toml] [--out FILE.json]

For each fabric x seed x capture light: a synthetic capture (``tiny`` preset, overridable views and size) is
generated into ``DIR`` (kept and reused), then the material is fitted (``stages.material`` of ``--config``
over the tiny demo's settings) under the capture's recorded light:
- ``--mode truth``: on the TRUE garment (and body occluder) with the TRUE base-colour texture: what the light
  identifies, without reconstruction or albedo-estimation errors;
- ``--mode pipeline``: ``pgc reconstruct`` end to end (reconstructed mesh, estimated base colour).
Reported per run: fitted and true roughness, sheen colour, sheen roughness, light radiance, the mean base
colour over the garment's texels, their relative errors, and the fit's seconds. The sheen colour and the base
colour are also given in the truth's units, times the fitted-over-true radiance per channel: the exact null
space ``(base_c, sheen_c, light_c) -> (s base_c, s sheen_c, light_c / s)`` (docs/pbr.md) makes only those
products identifiable when the base-colour texture's scale is not known.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

FABRICS = ("cotton-sheen", "fleece-sheen", "knit-sheen", "rib-knit-sheen", "satin-sheen")


def relative(fit, true) -> float:
    """Largest relative error over the channels."""
    fit, true = np.asarray(fit, np.float64), np.asarray(true, np.float64)
    return float(np.max(np.abs(fit - true) / np.maximum(np.abs(true), 1e-9)))


def texture_mean(texture: np.ndarray) -> np.ndarray:
    """Mean colour of a texture's covered texels (non-zero: atlas charts), (3,)."""
    t = np.asarray(texture, np.float64)[..., :3]
    covered = t.sum(-1) > 0
    return t[covered].mean(0)


def capture(work: Path, fabric: str, seed: int, light: str, args: argparse.Namespace, cfg) -> Path:
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.render import scene_renderer

    folder = work / f"{fabric}_s{seed}_{light}_v{args.views}_r{args.resolution}_spp{args.spp}_{args.framing}"
    if not (folder / "ground_truth" / "scene.json").is_file():
        preset = get_preset("tiny", views=args.views, resolution=args.resolution, spp=args.spp, framing=args.framing)
        generate(folder, preset, fabric=fabric, seed=seed, capture_light=light, renderer=scene_renderer(cfg),
                 body_model=cfg.create("body_model"))
    return folder


def fit_truth(folder: Path, cfg) -> tuple[dict, np.ndarray, np.ndarray, float, dict]:
    """Fit on the true geometry and base colour: (params, radiance, base mean, seconds, fit figures)."""
    from pgc.io.capture import read_capture
    from pgc.pipeline.garment import with_occluder
    from pgc.synth.ground_truth import read_ground_truth
    from pgc.types import Material

    cap, gt = read_capture(folder), read_ground_truth(folder)
    renderer = cfg.create("pbr_renderer")
    init = Material("pgc-sheen", cfg.create("brdf").initial_params(), gt.material.base_color)
    start = time.perf_counter()
    fit = renderer.fit(cap, with_occluder(gt.garment, gt.body), init, cfg.stage("material"))
    return fit.material.params, fit.light.radiance, texture_mean(gt.material.base_color), \
        time.perf_counter() - start, fit.figures


def fit_pipeline(folder: Path, out: Path, cfg) -> tuple[dict, np.ndarray, np.ndarray, float, dict]:
    from pgc.io.timings import read_timings
    from pgc.pipeline.reconstruct import reconstruct

    asset = reconstruct(folder, out, cfg)
    seconds = read_timings(out)["seconds"]["material"]
    return asset.material.params, asset.light.radiance, texture_mean(asset.material.base_color), seconds, \
        asset.figures.get("material", {})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", required=True, type=Path)
    ap.add_argument("--fabrics", nargs="+", default=list(FABRICS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    ap.add_argument("--lights", nargs="+", default=["uniform", "sky-sun"])
    ap.add_argument("--mode", choices=("truth", "pipeline"), default="truth")
    ap.add_argument("--views", type=int, default=6)
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--framing", choices=("body", "garment"), default="body")
    ap.add_argument("--config", default=None, help="TOML merged over the tiny demo's settings")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()

    from pgc.pipeline.demo import demo_config
    from pgc.synth.ground_truth import read_ground_truth

    cfg = demo_config("tiny", args.config)
    rows = []
    for fabric in args.fabrics:
        for seed in args.seeds:
            for light in args.lights:
                folder = capture(args.work, fabric, seed, light, args, cfg)
                gt = read_ground_truth(folder)
                if args.mode == "truth":
                    params, radiance, base, seconds, figures = fit_truth(folder, cfg)
                else:
                    params, radiance, base, seconds, figures = fit_pipeline(
                        folder, folder.with_name(folder.name + "_run"), cfg)
                true = gt.material.params
                gauge = np.asarray(radiance) / gt.light.radiance
                true_base = texture_mean(gt.material.base_color)
                row = {"fabric": fabric, "seed": seed, "light": light, "mode": args.mode, "seconds": seconds,
                       "iterations": figures.get("iterations"), "stopped": figures.get("stopped"),
                       "fit": {k: v for k, v in params.items() if k != "base_color"},
                       "true": true, "radiance": np.asarray(radiance).tolist(),
                       "base_mean": base.tolist(), "true_base_mean": true_base.tolist(),
                       "error": {"roughness": relative(params["roughness"], true["roughness"]),
                                 "sheen_roughness": relative(params["sheen_roughness"], true["sheen_roughness"]),
                                 "sheen_color": relative(params["sheen_color"], true["sheen_color"]),
                                 "sheen_color_gauge": relative(np.asarray(params["sheen_color"]) * gauge,
                                                               true["sheen_color"]),
                                 "base_color": relative(base, true_base),
                                 "base_color_gauge": relative(base * gauge, true_base),
                                 "radiance": relative(radiance, gt.light.radiance)}}
                rows.append(row)
                e = row["error"]
                print(f"{fabric:15s} s{seed} {light:8s} {args.mode}: rough {params['roughness']:.3f}/"
                      f"{true['roughness']} ({e['roughness']:.1%}) sheen {np.round(params['sheen_color'], 3)}/"
                      f"{true['sheen_color']} ({e['sheen_color']:.1%}; x gain {e['sheen_color_gauge']:.1%}) "
                      f"sheen_rough {params['sheen_roughness']:.3f}/{true['sheen_roughness']} "
                      f"({e['sheen_roughness']:.1%}) base ({e['base_color']:.1%}; x gain "
                      f"{e['base_color_gauge']:.1%}) radiance {np.round(radiance, 3)} {seconds:.0f} s", flush=True)
                if args.out:
                    args.out.parent.mkdir(parents=True, exist_ok=True)
                    args.out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
