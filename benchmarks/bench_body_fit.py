#!/usr/bin/env python
"""Time against vertex error of the body fit (``pgc body fit``, :func:`pgc.body.fit.fit_body`).

    python benchmarks/bench_body_fit.py [--seeds 0 1 2 3 4] [--scenes tiny default] [--sweep] [--out FILE]
    python benchmarks/bench_body_fit.py --capture DIR [DIR ...] [--sweep]   # pgc synth captures (with ground_truth/)
    python benchmarks/bench_body_fit.py --capture DIR --views 8 [--iterations N] [--keypoints]   # one setting

Scenes (made in-process, :func:`pgc.testing.body_scenes.anny_capture`: an Anny body of a per-seed shape and pose,
:func:`~pgc.testing.body_scenes.random_body`, in a tight and a loose shirt, masks and labels from the scene
renderer's exact layers): ``tiny`` 6 views at 64 px (the tiny synth preset's), ``default`` 16 views at 192 px
(the default preset's image size) of which the fit uses its ``views``. ``--sweep`` also varies the settings on
the first seed (views used, iterations, keypoints from the true joints or not). ``--capture`` fits ``pgc synth``
captures instead (the scene named by the capture's image size and view count, the garment by its kind, fit and
looseness from the capture's metadata; ``--sweep`` varies the settings on the first capture). Per fit: wall
seconds, CPU seconds of the process, steps run, the silhouette IoU, the vertex error (mean, max; under the garment
and elsewhere) and the fitted shape (with the true one where known). Records follow docs/bench.md,
"Record schema"; the table is printed.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

SCENES = {"tiny": {"views": 6, "size": 64}, "default": {"views": 16, "size": 192}}


def keypoints_of(capture, body, joints: np.ndarray):
    """Keypoints at the true joints' projections (confidence 1), per view."""
    from pgc.body.fit import Keypoints

    out = {}
    for view in capture.views:
        uv, _ = view.camera.project(joints)
        out[view.camera.name] = Keypoints(tuple(body.joint_names), uv, np.ones(len(uv)))
    return out


def sweep_runs(base, use_kp: bool) -> list[tuple[Any, bool]]:
    """The settings of a sweep: the base, fewer and more views, half the iterations, keypoints (``use_kp``)."""
    runs = [(base, False)]
    runs += [(base.model_copy(update={"views": v}), False) for v in (8, 24) if v != base.views]
    runs.append((base.model_copy(update={"iterations": base.iterations // 2}), False))
    return runs + ([(base, True)] if use_kp else [])


def run_fit(capture, body, truth, cloth, keypoints, settings) -> dict[str, Any]:
    from pgc.body.fit import fit_body, vertex_error

    wall, cpu = time.perf_counter(), time.process_time()
    fit = fit_body(capture, body, settings, "anny", keypoints)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    err = vertex_error(fit.mesh.vertices, truth, cloth)
    return {"seconds": wall, "cpu_seconds": cpu, "steps": fit.figures["iterations"],
            "silhouette_iou": fit.figures["silhouette_iou"], "shape": fit.shape,
            "start_search": fit.figures["start_search"], "start_alternatives": fit.figures["start_alternatives"],
            "errors": {"mean_m": err["mean"], "max_m": err["max"], "under_garment_mean_m": err["under_garment"]["mean"],
                       "under_garment_max_m": err["under_garment"]["max"], "exposed_mean_m": err["exposed"]["mean"]}}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    p.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    p.add_argument("--garments", nargs="+", default=["tight", "loose"])
    p.add_argument("--sweep", action="store_true", help="vary views, iterations and keypoints on the first seed")
    p.add_argument("--capture", nargs="+", type=Path, help="synthetic captures (with ground_truth/) instead")
    p.add_argument("--views", type=int, help="views used (default: [stages.body_fit]'s)")
    p.add_argument("--iterations", type=int, help="most steps (default: [stages.body_fit]'s)")
    p.add_argument("--keypoints", action="store_true", help="keypoints at the true joints' projections")
    p.add_argument("--out", type=Path, default=Path("bench_body_fit.json"))
    args = p.parse_args()

    from pgc.config import load
    from pgc.registry import Registry
    from pgc.stages.body_fit import BodyFitSettings
    from pgc.types import Mesh

    body = Registry.discover().create("body_model", "anny")
    base = BodyFitSettings(**{k: v for k, v in (("views", args.views), ("iterations", args.iterations)) if v})
    records: list[dict[str, Any]] = []

    def record(scene: str, seed, garment: str, settings, keypoints: bool, result: dict[str, Any],
               true_shape: dict[str, float]) -> None:
        rec = {"role": "body_model", "implementation": "anny", "preset": scene,
               "settings": {"case": f"{scene} seed {seed} {garment}", "seed": seed, "garment": garment,
                            "views": settings.views, "iterations": settings.iterations, "keypoints": keypoints},
               "error_key": "mean_m", "label": "body_fit", **result, "true_shape": true_shape,
               "versions": {"python": platform.python_version(), "numpy": np.__version__}}
        records.append(rec)
        e = rec["errors"]
        print(f"| {scene} | {seed} | {garment} | {settings.views} | {settings.iterations} "
              f"| {'yes' if keypoints else 'no'} | {result['steps']} | {result['seconds']:.1f} "
              f"| {result['cpu_seconds']:.1f} | {result['silhouette_iou']:.3f} | {1000 * e['mean_m']:.1f} | {1000 * e['max_m']:.1f} "
              f"| {1000 * (e['under_garment_mean_m'] or float('nan')):.1f} | "
              f"{1000 * e['exposed_mean_m']:.1f} |", flush=True)
        args.out.write_text(json.dumps(records, indent=1))

    print("| scene | seed | garment | views | iterations | keypoints | steps | wall s | CPU s | silhouette IoU "
          "| mean mm | max mm | under garment mean mm | exposed mean mm |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    if args.capture:
        from pgc.io.capture import read_capture
        from pgc.io.mesh import read_mesh
        from pgc.synth.ground_truth import read_body_model

        for k, folder in enumerate(args.capture):
            capture = read_capture(folder)
            truth = read_mesh(folder / "ground_truth" / "body.obj")
            cloth = read_mesh(folder / "ground_truth" / "garment.obj")
            synth_body = read_body_model(folder / "ground_truth")
            meta = capture.metadata
            preset = meta.get("preset") if isinstance(meta.get("preset"), dict) else {}
            scene = f"synth {capture.views[0].camera.width} px x {len(capture.views)}"
            garment = f"{meta.get('garment', '?')} {preset.get('fit', '?')} {1000 * meta.get('looseness', 0):.0f} mm"
            for settings, use_kp in sweep_runs(base, True) if args.sweep and k == 0 else [(base, args.keypoints)]:
                kp = keypoints_of(capture, body, synth_body.joints) if use_kp else None
                record(scene, meta.get("seed"), garment, settings, use_kp,
                       run_fit(capture, body, truth, cloth, kp, settings), synth_body.phenotype)
        return
    from pgc.synth.render import scene_renderer
    from pgc.testing.body_scenes import anny_capture, random_body

    renderer = scene_renderer(load(require_available=False))
    for scene in args.scenes:
        for seed in args.seeds:
            shape, rotations = random_body(body, seed)
            for garment in args.garments:
                capture, state, cloth = anny_capture(body, renderer, shape, rotations, (0.0, 0.0, 0.0), garment,
                                                     **SCENES[scene])
                truth = Mesh(state.vertices, state.faces)
                sweep = args.sweep and seed == args.seeds[0] and garment == args.garments[0]
                for settings, use_kp in sweep_runs(base, True) if sweep else [(base, args.keypoints)]:
                    kp = keypoints_of(capture, body, state.joints) if use_kp else None
                    record(scene, seed, garment, settings, use_kp,
                           run_fit(capture, body, truth, cloth, kp, settings), shape)


if __name__ == "__main__":
    main()
