"""``pgc body fit``: the body model's shape and capture pose fitted to a capture."""

from __future__ import annotations

import argparse

from pgc.commands._common import (add_run_options, check_not_inside, check_out_folder, emit, load_config,
                                  reporter_for, writing)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("body", help="body model tools: fit the body to a capture",
                       description="Body model tools (the [body_model] of the configuration).")
    actions = p.add_subparsers(dest="body_command", metavar="ACTION", required=True)
    fit = actions.add_parser(
        "fit", help="fit the body's shape and pose to a capture's masks, labels and keypoints",
        description="Fit the configured body model's shape and capture pose to a capture folder: its "
                    "segmentation labels (0 background, 1 body, 2 garment) and masks, and 2D keypoints where the "
                    "capture has keypoints/<view>.json. Writes DIR/body.json (model, shape, pose) and "
                    "DIR/body.ply (the posed mesh). With ground truth (a synthetic capture's ground_truth/body.obj) "
                    "the error against the true body is reported, under the garment separately. Settings: "
                    "[stages.body_fit] (docs/body.md).",
        epilog="example: pgc body fit runs/capture --out runs/body --json")
    fit.add_argument("capture", help="capture folder (transforms.json with segmentation labels)")
    fit.add_argument("--out", required=True, help="folder to write body.json and body.ply into")
    fit.add_argument("--views", type=int, help="views used (default: [stages.body_fit] views)")
    fit.add_argument("--iterations", type=int, help="most optimiser steps (default: [stages.body_fit] iterations)")
    fit.add_argument("--no-keypoints", action="store_true", help="ignore the capture's keypoints")
    add_run_options(fit)
    fit.set_defaults(func=run_fit)


def run_fit(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pgc.body.fit import fit_body, vertex_error
    from pgc.errors import PGCDataError
    from pgc.io.body_fit import write_body_fit
    from pgc.io.capture import read_capture
    from pgc.io.keypoints import read_keypoints
    from pgc.io.mesh import read_mesh

    out = check_out_folder(args.out)
    check_not_inside(out, args.capture, "capture folder")
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    overrides = {k: v for k, v in (("views", args.views), ("iterations", args.iterations)) if v is not None}
    if args.no_keypoints:
        overrides["keypoints"] = False
    try:
        settings = cfg.stage("body_fit").model_validate({**cfg.stage("body_fit").model_dump(), **overrides})
    except ValueError as exc:
        raise PGCDataError(f"--views/--iterations: {str(exc).splitlines()[-1].strip()}") from None
    capture = read_capture(args.capture)
    keypoints = read_keypoints(args.capture, [v.camera.name for v in capture.views])
    body = cfg.create("body_model")
    fit = fit_body(capture, body, settings, cfg.roles["body_model"].name, keypoints, reporter, where=args.capture)
    truth_dir = Path(args.capture) / "ground_truth"
    result = {"body": str(out / "body.json"), "model": fit.model, "shape": fit.shape,
              "translation": fit.translation.tolist(), "figures": fit.figures}
    if (truth_dir / "body.obj").is_file():
        garment = read_mesh(truth_dir / "garment.obj") if (truth_dir / "garment.obj").is_file() else None
        result["vertex_error_m"] = vertex_error(fit.mesh.vertices, read_mesh(truth_dir / "body.obj"), garment)
    with writing(out, "pgc body fit"):
        write_body_fit(out, fit)
    error = result.get("vertex_error_m")
    emit(args, result, f"body written to {out}: {fit.figures['iterations']} steps on {fit.figures['views']} views "
                       f"in {fit.figures['seconds']:.1f} s, silhouette IoU {fit.figures['silhouette_iou']:.3f}"
                       + (f"; vertex error mean {1000 * error['mean']:.1f} mm, max {1000 * error['max']:.1f} mm"
                          if error else ""))
    return 0
