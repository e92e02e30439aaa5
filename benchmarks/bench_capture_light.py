#!/usr/bin/env python
"""Does the capture light let the material fit recover the in-family controls' pgc-sheen parameters?

    python benchmarks/bench_capture_light.py --work DIR [--fabrics F ...] [--seeds 0 1] [--lights uniform sky-sun]
        [--mode truth|pipeline|linear] [--views 6] [--resolution 64] [--spp 16] [--framing body|garment]
        [--config FILE.toml] [--remove weave fibres body depth] [--starts paper far truth] [--loss-spp N]
        [--study-spp N] [--out FILE.json]

For each fabric x seed x capture light: a synthetic capture (``tiny`` preset, overridable views and size) is
generated into ``DIR`` (kept and reused), then the material is fitted (``stages.material`` of ``--config``
over the tiny demo's settings) under the capture's recorded light:
- ``--mode truth``: on the TRUE garment (and body occluder) with the TRUE base-colour texture: what the light
  identifies, without reconstruction or albedo-estimation errors;
- ``--mode pipeline``: ``pgc reconstruct`` end to end (reconstructed mesh, estimated base colour).
Reported per run: fitted and true roughness, sheen colour, sheen roughness, light radiance, the mean base
colour over the garment's texels, their relative errors, and the fit's seconds (with the polish, its
figures and Adam's end point: ``polish``). The sheen colour and the base
colour are also given in the truth's units, times the fitted-over-true radiance per channel: the exact null
space ``(base_c, sheen_c, light_c) -> (s base_c, s sheen_c, light_c / s)`` (docs/pbr.md) makes only those
products identifiable when the base-colour texture's scale is not known.

The oracle (``--remove``, truth mode): the capture's colour is rendered again by the same scene renderer,
at the capture's samples, sampler and seeds, with the named differences between the truth's scene and the
fit's forward model removed from the truth: ``weave`` (the weave normal map), ``fibres`` (the control's sparse
fibres), ``body`` (the skin-coloured body, made the fit's grey occluder albedo), ``depth`` (the truth's path
length, made the fit's ``max_depth``). With all four removed the truth's renderer is the fit's forward model
(``path`` against ``prb``: the same estimator's expectation). ``--starts``: the fit's initial values
(:data:`STARTS`); ``--loss-spp``: the fit's loss at the fitted and at the true parameters (did it reach the
minimum?). ``--mode linear``: no fit; the Jacobian of the fit's pixels at the truth of the exact scene, the
Cramér-Rao errors it gives at the capture's noise (identifiability), and the first-order shift of the fit's
minimum caused by each mismatch kept alone (:func:`linear_study`). Rows are appended to ``--out``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

FABRICS = ("cotton-sheen", "fleece-sheen", "knit-sheen", "rib-knit-sheen", "satin-sheen")
MISMATCHES = ("weave", "fibres", "body", "depth")
"""What the truth's scene renders and the material fit's forward model does not (see the module docstring)."""
STARTS = ("paper", "far", "truth")
"""Initial pgc-sheen parameters of the fit: the BRDF's initial values (the paper's: roughness 0.8, sheen colour
(0.75, 0.73, 0.27), sheen roughness 0.5), ``FAR`` (on the other side of every control's truth but the satin's
roughness), or the truth's (where the fit's dynamics settle near the loss minimum, whatever its descent from
afar would do)."""
FAR = {"roughness": 0.4, "sheen_color": [0.05, 0.05, 0.05], "sheen_roughness": 0.8}


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


def oracle_capture(folder: Path, removed: tuple[str, ...], cfg) -> Path:
    """``folder``'s capture rendered again with the ``removed`` mismatches taken out of the truth's scene
    (written next to it, kept and reused); ``folder`` itself when nothing is removed."""
    if not removed:
        return folder
    out = folder.with_name(f"{folder.name}_exact-{'-'.join(sorted(removed))}")
    if (out / "transforms.json").is_file():
        return out
    from pgc.io.capture import read_capture, write_capture

    cap = read_capture(folder)
    cap.views = oracle_views(folder, removed, cfg)
    write_capture(out, cap)
    return out


def oracle_scene(folder: Path, removed: tuple[str, ...], cfg, params: dict | None = None):
    """The truth's scene of ``folder`` with the ``removed`` mismatches taken out (and the pgc-sheen ``params``
    replacing the truth's where given): (renderer, scene, labels, geometry, ground truth)."""
    from dataclasses import replace

    from pgc.synth.ground_truth import read_ground_truth
    from pgc.synth.render import scene_renderer
    from pgc.types import Material

    unknown = set(removed) - set(MISMATCHES)
    if unknown:
        raise SystemExit(f"--remove: unknown {sorted(unknown)}; choose from {', '.join(MISMATCHES)}")
    gt = read_ground_truth(folder)
    renderer = scene_renderer(cfg)
    if "depth" in removed:
        renderer = type(renderer)(renderer.options.model_copy(update={"max_depth": cfg.stage("material").max_depth}))
    geometry = gt.geometry()
    grey = float(cfg.create("pbr_renderer").options.occluder_albedo)
    material = gt.material if params is None else Material(gt.material.brdf, {**gt.material.params, **params},
                                                           gt.material.base_color)
    geometry = replace(geometry, material=material, normal_map=None if "weave" in removed else geometry.normal_map,
                       fibres=None if "fibres" in removed else geometry.fibres,
                       skin_albedo=(grey,) * 3 if "body" in removed else geometry.skin_albedo)
    scene, labels = renderer.build_scene(geometry, gt.light)
    return renderer, scene, labels, geometry, gt


def oracle_views(folder: Path, removed: tuple[str, ...], cfg) -> list:
    """The views of ``folder``'s capture rendered by the configuration's scene renderer with the ``removed``
    mismatches taken out (colour at the capture's spp, sampler and seeds; mask and labels ray-cast again)."""
    from pgc.io.capture import read_capture
    from pgc.types import View

    cap = read_capture(folder)
    renderer, scene, labels, geometry, gt = oracle_scene(folder, removed, cfg)
    preset, seed = gt.manifest["preset"], gt.manifest["seed"]
    views = []
    for i, view in enumerate(cap.views):
        color, _ = renderer.render_color(scene, view.camera, preset["spp"], seed * 100003 + i, preset["sampler"])
        layers = renderer.ground_truth_layers(scene, labels, geometry, view.camera, preset["gt_samples"])
        views.append(View(view.camera, color, layers["mask"], layers["segmentation"], view.background,
                          {"linear": color, "albedo": layers["albedo"], "depth": layers["depth"]}))
    return views


def fit_pixels(folder: Path, cfg, removed: tuple[str, ...], params: dict | None, spp: int, seed: int = 0,
               capture_folder: Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A render of ``folder``'s truth scene (``removed`` mismatches taken out, ``params`` over the truth's) at
    ``spp`` on the views of ``capture_folder`` (default ``folder``) as the material fit sees them (area-downsampled
    to ``max_image_side``, its interior garment pixels): (rendered, capture) (N, 3) linear float64."""
    from dataclasses import replace

    from pgc.brdfs.fitdata import prepare_views
    from pgc.io.capture import read_capture

    cap = read_capture(capture_folder or folder)
    side = cfg.stage("material").max_image_side
    fit_views = prepare_views(cap, side)
    inside = np.concatenate([v.weight.reshape(-1) for v in fit_views]) > 0
    renderer, scene, *_, gt = oracle_scene(folder, removed, cfg, params)
    views = [replace(v, image=renderer.render_color(scene, v.camera, spp, seed * 7919 + i,
                                                    gt.manifest["preset"]["sampler"])[0])
             for i, v in enumerate(cap.views)]
    rendered = prepare_views(type(cap)(views, cap.labels, cap.light), side)
    flat = [np.concatenate([v.target.reshape(-1, 3) for v in vs])[inside].astype(np.float64)
            for vs in (rendered, fit_views)]
    return flat[0], flat[1]


def linear_study(folder: Path, cfg, spp: int, step: float = 0.05) -> dict:
    """Identifiability and mismatch bias at the truth, to first order, on the fit's own pixels (the capture's
    views area-downsampled to ``max_image_side``, interior garment weights).

    J: the pixels' derivatives with respect to the relative pgc-sheen parameters and light (roughness, sheen
    colour r/g/b, sheen roughness, radiance r/g/b; ``p dI/dp``), of the exact model (every mismatch removed),
    by central differences of ``spp``-sample renders with common seeds (the radiance's column is the image
    itself, the sheen colour's exact: the pixels are linear in it). Noise: the capture's per-pixel standard
    deviation at the fit's size, from two seeds of the exact model at the capture's spp. Reported: the
    singular values of J / sqrt(pixels) (RMS pixel change per unit relative change), the Cramer-Rao relative
    errors ``noise sqrt(diag((J^T J)^-1))``, and per mismatch the least-squares shift of the relative
    parameters that best absorbs it (``J^+ (I_with - I_exact)``: where the fit's minimum moves, to first order).
    """
    from pgc.synth.ground_truth import read_ground_truth

    gt = read_ground_truth(folder)

    def pixels(removed: tuple[str, ...], params: dict | None = None, seed: int = 0, samples: int = spp) -> np.ndarray:
        return fit_pixels(folder, cfg, removed, params, samples, seed)[0]

    true = gt.material.params
    exact = MISMATCHES
    base = pixels(exact)
    columns, names = [], []
    for c in range(3):  # radiance: the image is linear in each channel's radiance
        col = np.zeros_like(base)
        col[:, c] = base[:, c]
        columns.append(col)
        names.append(f"radiance_{'rgb'[c]}")
    for name in ("roughness", "sheen_roughness", "sheen_color"):
        value = np.asarray(true[name], np.float64)
        up = pixels(exact, {name: (value * (1 + step)).tolist()})
        down = pixels(exact, {name: (value * (1 - step)).tolist()})
        d = (up - down) / (2 * step)
        if name == "sheen_color":  # channel c's pixels depend on sheen_c only
            for c in range(3):
                col = np.zeros_like(d)
                col[:, c] = d[:, c]
                columns.append(col)
                names.append(f"sheen_color_{'rgb'[c]}")
        else:
            columns.append(d)
            names.append(name)
    J = np.stack([col.reshape(-1) for col in columns], axis=1)
    spp_capture = gt.manifest["preset"]["spp"]
    a, b = pixels(exact, seed=1, samples=spp_capture), pixels(exact, seed=2, samples=spp_capture)
    noise = float(np.sqrt(np.mean((a - b) ** 2) / 2))
    sv = np.linalg.svd(J, compute_uv=False) / np.sqrt(len(base) * 3)
    crb = noise * np.sqrt(np.diag(np.linalg.inv(J.T @ J)))
    shifts = {}
    for kept in (*MISMATCHES, "all"):
        removed = () if kept == "all" else tuple(m for m in MISMATCHES if m != kept)
        r = (pixels(removed) - base).reshape(-1)
        shift = np.linalg.lstsq(J, r, rcond=None)[0]
        shifts[kept] = {"shift": dict(zip(names, shift.tolist())),
                        "rms": float(np.sqrt(np.mean(r ** 2))),
                        "rms_left": float(np.sqrt(np.mean((r - J @ shift) ** 2)))}
    return {"names": names, "pixels": int(len(base)), "noise": noise, "spp": spp, "step": step,
            "singular_values": sv.tolist(), "cramer_rao": dict(zip(names, crb.tolist())), "mismatch": shifts}


def fit_losses(folder: Path, fitted: Path, cfg, params: dict, radiance, spp: int) -> dict:
    """The material fit's loss (MSE over its pixels of ``fitted``'s capture) at the fitted parameters and
    radiance and at the truth's, each rendered by the exact forward model at ``spp`` (one seed for both)."""
    from pgc.synth.ground_truth import read_ground_truth

    true_radiance = read_ground_truth(folder).light.radiance
    out = {}
    for name, p, gain in (("loss_fit", {k: v for k, v in params.items() if k != "base_color"},
                           np.asarray(radiance) / true_radiance), ("loss_true", None, np.ones(3))):
        rendered, target = fit_pixels(folder, cfg, MISMATCHES, p, spp, seed=5, capture_folder=fitted)
        out[name] = float(np.mean((rendered * gain - target) ** 2))
    return out


def fit_truth(folder: Path, cfg, truth: Path | None = None, start: str = "paper"
              ) -> tuple[dict, np.ndarray, np.ndarray, float, dict]:
    """Fit ``folder``'s capture on the true geometry and base colour (of the ground truth in ``truth``, default
    ``folder``) from the initial values named ``start`` (:data:`STARTS`): (params, radiance, base mean, seconds, fit figures)."""
    from pgc.io.capture import read_capture
    from pgc.pipeline.garment import with_occluder
    from pgc.synth.ground_truth import read_ground_truth
    from pgc.types import Material

    cap, gt = read_capture(folder), read_ground_truth(truth or folder)
    renderer = cfg.create("pbr_renderer")
    initial = {"paper": cfg.create("brdf").initial_params(), "far": FAR, "truth": gt.material.params}[start]
    init = Material("pgc-sheen", dict(initial), gt.material.base_color)
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
    ap.add_argument("--mode", choices=("truth", "pipeline", "linear"), default="truth")
    ap.add_argument("--views", type=int, default=6)
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--framing", choices=("body", "garment"), default="body")
    ap.add_argument("--config", default=None, help="TOML merged over the tiny demo's settings")
    ap.add_argument("--remove", nargs="*", default=[], choices=MISMATCHES,
                    help="truth mode: mismatches taken out of the truth's renderer (the oracle)")
    ap.add_argument("--starts", nargs="+", default=["paper"], choices=STARTS)
    ap.add_argument("--study-spp", type=int, default=256, help="linear mode: samples per pixel of its renders")
    ap.add_argument("--loss-spp", type=int, default=0,
                    help="truth mode: also the fit's loss at the fitted and at the true parameters, by the exact "
                         "forward model at this many samples per pixel (0: not measured)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    removed = tuple(sorted(set(args.remove)))
    if args.mode == "linear":
        args.starts = args.starts[:1]
    if removed and args.mode != "truth":
        raise SystemExit("--remove needs --mode truth")

    from pgc.pipeline.demo import demo_config
    from pgc.synth.ground_truth import read_ground_truth

    cfg = demo_config("tiny", args.config)
    rows = json.loads(args.out.read_text()) if args.out and args.out.is_file() else []
    for fabric, seed, light, start in itertools.product(args.fabrics, args.seeds, args.lights, args.starts):
        folder = capture(args.work, fabric, seed, light, args, cfg)
        gt = read_ground_truth(folder)
        if args.mode == "linear":
            started = time.process_time()
            study = linear_study(folder, cfg, args.study_spp)
            rows.append({"fabric": fabric, "seed": seed, "light": light, "mode": "linear",
                         "cpu_seconds": time.process_time() - started, **study})
            crb = study["cramer_rao"]
            print(f"{fabric:15s} s{seed} {light:8s} linear: noise {study['noise']:.2e} sigma_min "
                  f"{study['singular_values'][-1]:.2e} CRB " + " ".join(f"{k} {v:.1%}" for k, v in crb.items()),
                  flush=True)
            for kept, m in study["mismatch"].items():
                print(f"   {kept:7s} rms {m['rms']:.2e} left {m['rms_left']:.2e} shift " +
                      " ".join(f"{k} {v:+.1%}" for k, v in m["shift"].items()), flush=True)
            if args.out:
                args.out.parent.mkdir(parents=True, exist_ok=True)
                args.out.write_text(json.dumps(rows, indent=1))
            continue
        losses = {}
        if args.mode == "truth":
            fitted = oracle_capture(folder, removed, cfg)
            params, radiance, base, seconds, figures = fit_truth(fitted, cfg, folder, start)
            adam = (figures.get("polish") or {}).get("adam")
            if adam:
                print(f"  Adam alone: rough {adam['roughness']:.3f} sheen {np.round(adam['sheen_color'], 3)} "
                      f"sheen_rough {adam['sheen_roughness']:.3f} radiance {np.round(adam['radiance'], 3)}; polish "
                      f"{ {k: v for k, v in figures['polish'].items() if k != 'adam'} }", flush=True)
            if args.loss_spp:
                losses = fit_losses(folder, fitted, cfg, params, radiance, args.loss_spp)
        else:
            params, radiance, base, seconds, figures = fit_pipeline(
                folder, folder.with_name(folder.name + "_run"), cfg)
        true = gt.material.params
        gauge = np.asarray(radiance) / gt.light.radiance
        true_base = texture_mean(gt.material.base_color)
        row = {"fabric": fabric, "seed": seed, "light": light, "mode": args.mode, "removed": list(removed),
               "start": start, "seconds": seconds,
               "iterations": figures.get("iterations"), "stopped": figures.get("stopped"),
               "polish": figures.get("polish"), **losses,
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
        print(f"{fabric:15s} s{seed} {light:8s} {args.mode} -{','.join(removed)} {start}: rough {params['roughness']:.3f}/"
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
