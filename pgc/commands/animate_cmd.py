"""``pgc animate``: simulate an asset's garment on a body motion."""

from __future__ import annotations

import argparse

from pgc.commands._common import (add_run_options, check_not_inside, check_out_folder, emit, load_config,
                                  reporter_for, writing)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "animate", help="simulate an asset on a body motion",
        description="Simulate the garment of an asset on a body motion with the configured simulator (XPBD "
                    "by default: 30 fps, 30 substeps, 20 iterations). MOTION is a built-in name (goalpost, "
                    "spooky, arms-up, walk, arm-swing; they pose the body model of the synthetic capture the "
                    "asset came from) or a file: an .npz with 'vertices' (T, V, 3) and 'faces', or a folder of "
                    "OBJ frames, whose frame 0 is the capture pose.",
        epilog="example: pgc animate runs/asset --motion spooky --out runs/spooky")
    p.add_argument("asset", help="asset folder (from pgc reconstruct)")
    p.add_argument("--motion", required=True, help="built-in motion name or motion file")
    p.add_argument("--out", required=True, help="run folder to write")
    p.add_argument("--capture", help="capture folder whose body model poses built-in motions "
                                     "(default: the one the asset was reconstructed from)")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pgc.io.asset import read_asset
    from pgc.io.motion import check_against_body, load_motion
    from pgc.pipeline.animate import animate, read_run

    out = check_out_folder(args.out)
    check_not_inside(out, args.asset, "asset folder")
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    asset = read_asset(args.asset)  # manifest, hashes and every file checked before any work
    if Path(args.motion).exists():
        check_against_body(load_motion(args.motion), asset.body.vertices, args.motion)
    with writing(out, "pgc animate"):
        out = animate(args.asset, args.motion, out, cfg, args.capture, reporter)
    meta = read_run(out)
    emit(args, meta, f"simulated {meta['frames']} frames of '{args.motion}' into {out}")
    return 0
