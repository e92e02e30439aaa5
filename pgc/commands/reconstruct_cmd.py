"""``pgc reconstruct``: capture -> garment asset."""

from __future__ import annotations

import argparse

from pgc.commands._common import (add_run_options, check_not_inside, check_out_folder, emit, load_config,
                                  reporter_for, writing)


def add_parser(sub: argparse._SubParsersAction) -> None:
    from pgc.stages.body_fit import MOTION_BODIES

    p = sub.add_parser(
        "reconstruct", help="capture -> garment asset (mesh, Gaussians, albedo, material)",
        description="Reconstruct a simulation-ready, relightable garment asset from a capture folder "
                    "(transforms.json with masks and garment segmentation): the labelled full-body mesh, "
                    "mesh-embedded Gaussians (only the garment's kept), the base-colour texture and the fitted "
                    "BRDF and light. Every stage is cached under OUT/stages by content hash: an interrupted run "
                    "resumes, and changing one stage's options recomputes only it and what follows.",
        epilog="examples: pgc reconstruct runs/capture --out runs/asset --config my.toml; "
               "pgc reconstruct runs/capture --out runs/asset-fit --body fit (then pgc animate, pgc render and "
               "pgc eval --mode independent)")
    p.add_argument("capture", help="capture folder (transforms.json)")
    p.add_argument("--out", required=True, help="asset folder to write")
    p.add_argument("--body", choices=MOTION_BODIES,
                   help="the body the garment moves on in 'pgc animate' (default: [stages.body_fit] motion_body, "
                        "'truth'): 'truth' = a synthetic capture's true body; 'fit' = the body model fitted to the "
                        "capture (the body_fit stage, as 'pgc body fit' runs it), as the paper's pipeline moves it, "
                        "so that 'pgc eval --mode independent' compares a garment moved on the fitted body with a "
                        "truth moved on the true body. A capture without a true body always moves on its fitted body")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.io.capture import read_capture
    from pgc.pipeline.motion_source import with_motion_body
    from pgc.pipeline.reconstruct import reconstruct

    out = check_out_folder(args.out)
    check_not_inside(out, args.capture, "capture folder")
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    if args.body is not None:
        cfg = with_motion_body(cfg, args.body)
    read_capture(args.capture)  # every file checked (sizes, finite pixels, cameras) before any work
    with writing(out, "pgc reconstruct"):
        asset = reconstruct(args.capture, out, cfg, reporter)
    body = asset.config["source"]["body"]
    emit(args, {"asset": args.out, "body": body, "figures": asset.figures},
         f"asset written to {args.out}: garment {len(asset.garment.vertices)} vertices, "
         f"{len(asset.gaussians)} Gaussians, BRDF '{asset.material.brdf}'; moves on the "
         + ("capture's true body" if body == "truth" else "body fitted to the capture (ASSET/body_fit)"))
    return 0
