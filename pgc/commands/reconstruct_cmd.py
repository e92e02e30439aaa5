"""``pgc reconstruct``: capture -> garment asset."""

from __future__ import annotations

import argparse

from pgc.commands._common import (add_run_options, check_not_inside, check_out_folder, emit, load_config,
                                  reporter_for, writing)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reconstruct", help="capture -> garment asset (mesh, Gaussians, albedo, material)",
        description="Reconstruct a simulation-ready, relightable garment asset from a capture folder "
                    "(transforms.json with masks and garment segmentation): the labelled full-body mesh, "
                    "mesh-embedded Gaussians (only the garment's kept), the base-colour texture and the fitted "
                    "BRDF and light. Every stage is cached under OUT/stages by content hash: an interrupted run "
                    "resumes, and changing one stage's options recomputes only it and what follows.",
        epilog="example: pgc reconstruct runs/capture --out runs/asset --config my.toml")
    p.add_argument("capture", help="capture folder (transforms.json)")
    p.add_argument("--out", required=True, help="asset folder to write")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.pipeline.reconstruct import reconstruct

    from pgc.io.capture import read_capture

    out = check_out_folder(args.out)
    check_not_inside(out, args.capture, "capture folder")
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    read_capture(args.capture)  # every file checked (sizes, finite pixels, cameras) before any work
    with writing(out, "pgc reconstruct"):
        asset = reconstruct(args.capture, out, cfg, reporter)
    emit(args, {"asset": args.out, "figures": asset.figures},
         f"asset written to {args.out}: garment {len(asset.garment.vertices)} vertices, "
         f"{len(asset.gaussians)} Gaussians, BRDF '{asset.material.brdf}'")
    return 0
