"""``pgc animate``: simulate an asset's garment on a body motion."""

from __future__ import annotations

import argparse

from pgc.commands._common import (add_run_options, check_not_inside, check_out_folder, emit, load_config,
                                  reporter_for, writing)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "animate", help="simulate an asset on a body motion",
        description="Simulate the garment of an asset on a body motion with the configured simulator (XPBD\n"
                    "by default: 30 fps, 30 substeps, 20 iterations).",
        epilog="MOTION is one of:\n"
               "  a built-in name    goalpost, spooky, arms-up (the paper's three test motions), walk, arm-swing\n"
               "  a captured clip    an Acclaim .amc (its skeleton: the subject's .asf beside it, 02_01.amc ->\n"
               "                     02.asf, or --skeleton FILE) or a .bvh; retargeted onto the body, resampled\n"
               "                     to 30 fps and blended in from the capture pose over 0.5 s\n"
               "  an SMPL pose clip  an .npz in AMASS's layout ('poses', 'trans', 'mocap_framerate', 'betas'),\n"
               "                     with [body_model] use = \"smplx\" and its model_path (the clip's skeleton)\n"
               "  body vertices      an .npz with 'vertices' (T, V, 3) and 'faces', or a folder of OBJ frames,\n"
               "                     whose frame 0 is the capture pose\n"
               "Built-in motions and clips move the body model of the synthetic capture the asset came from.\n"
               "Shipped CMU clips, named cmu:NAME: cmu:02_01 (walk), cmu:02_03 (run; cmu:02_03.bvh as BVH),\n"
               "cmu:02_04 (jump), cmu:02_05 (punch); files, credit and terms in pgc/data/motions/cmu.\n\n"
               "examples:\n"
               "  pgc animate runs/asset --motion spooky --out runs/spooky\n"
               "  pgc animate runs/asset --motion cmu:02_01 --in-place --out runs/walk\n"
               "  pgc animate runs/asset --motion take.amc --skeleton actor.asf --clip-fps 60 --out runs/take\n"
               "  pgc animate runs/asset --motion take.bvh --joint-map names.json --out runs/take",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("asset", help="asset folder (from pgc reconstruct)")
    p.add_argument("--motion", required=True, help="built-in motion name, captured clip (.amc, .bvh, "
                                                    "cmu:NAME) or motion file (.npz, OBJ folder)")
    p.add_argument("--out", required=True, help="run folder to write")
    p.add_argument("--capture", help="capture folder whose body model built-in motions and clips move "
                                     "(default: the one the asset was reconstructed from)")
    p.add_argument("--skeleton", metavar="FILE", help="the .asf skeleton of an .amc clip (default: the subject's "
                                                      ".asf beside the clip)")
    p.add_argument("--clip-fps", type=float, metavar="FPS",
                   help="frame rate of the clip (an .amc carries none: default 120, CMU's capture rate; a .bvh's "
                        "default is its Frame Time)")
    p.add_argument("--clip-unit", type=float, metavar="METRES",
                   help="metres per length unit of a .bvh clip (default 0.01: centimetres; 0.0254: inches)")
    p.add_argument("--joint-map", metavar="FILE",
                   help="JSON object of clip joint -> rig joint names, for a clip whose joints the known maps "
                        "(CMU ASF, CMU and Mixamo-style BVH, SMPL) do not cover")
    p.add_argument("--in-place", action="store_true",
                   help="hold a clip's root over the capture position (its horizontal travel removed), so that a "
                        "walk stays in view of the capture's fixed cameras (as pgc demo does)")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pgc.errors import PGCDataError
    from pgc.io.asset import read_asset
    from pgc.io.motion import check_against_body, load_motion
    from pgc.motion.drive import ClipOptions, is_clip
    from pgc.pipeline.animate import animate, read_run

    out = check_out_folder(args.out)
    check_not_inside(out, args.asset, "asset folder")
    clip = ClipOptions(Path(args.skeleton) if args.skeleton else None, args.clip_fps, args.clip_unit,
                       Path(args.joint_map) if args.joint_map else None, args.in_place)
    if clip != ClipOptions() and not is_clip(args.motion):
        raise PGCDataError(f"--skeleton, --clip-fps, --clip-unit, --joint-map and --in-place are for captured clips "
                           f"(.amc, .bvh, AMASS .npz); '{args.motion}' is not one")
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    asset = read_asset(args.asset)  # manifest, hashes and every file checked before any work
    if Path(args.motion).exists() and not is_clip(args.motion):
        check_against_body(load_motion(args.motion), asset.body.vertices, args.motion)
    with writing(out, "pgc animate"):
        out = animate(args.asset, args.motion, out, cfg, args.capture, reporter, clip)
    meta = read_run(out)
    emit(args, meta, f"simulated {meta['frames']} frames of '{args.motion}' into {out}")
    return 0
