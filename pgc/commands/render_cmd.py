"""``pgc render``: hybrid rendering of an animated run."""

from __future__ import annotations

import argparse

from pgc.commands._common import add_run_options, check_run, emit, load_config, reporter_for, writing


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "render", help="render an animated run (hybrid 3DGS + PBR)",
        description="Render the frames of a run with the hybrid renderer: the PBR renderer's radiance in "
                    "texture space colours the far-field Gaussians, the optimised Gaussians give the near "
                    "field, and an alpha-aware low-pass combines them: I = h(G) + l(S). The 3DGS-only and "
                    "PBR-only ablations are rendered too. --light relights with an environment map "
                    "(EXR, latitude-longitude), turned --light-rotation degrees about +Y; --rotate-light turns it a full "
                    "circle over the frames instead.",
        epilog="example: pgc render runs/spooky --light sky.exr --rotate-light")
    p.add_argument("run", help="run folder (from pgc animate)")
    p.add_argument("--light", help="environment map (EXR) to relight with; default: the fitted capture light")
    p.add_argument("--light-rotation", type=float, default=0.0, metavar="DEG",
                   help="turn the environment map DEG degrees about +Y (default 0)")
    p.add_argument("--rotate-light", action="store_true", help="rotate the environment 360 degrees over the frames")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import math

    from pgc.errors import PGCConfigError
    from pgc.pipeline.render import render_run

    if args.light_rotation and not args.light:
        raise PGCConfigError("--light-rotation turns an environment map: give it with --light ENV.exr")
    if not math.isfinite(args.light_rotation):
        raise PGCConfigError(f"--light-rotation {args.light_rotation}: give a finite angle in degrees")
    if args.light_rotation and args.rotate_light:
        raise PGCConfigError("give --light-rotation (a fixed angle) or --rotate-light (a full turn over the "
                             "frames), not both")
    check_run(args.run)
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    light = None
    if args.light:
        from dataclasses import replace

        from pgc.pipeline.render import envmap_light

        light = replace(envmap_light(args.run, args.light), rotation_deg=args.light_rotation)
    with writing(args.run, "pgc render"):
        out = render_run(args.run, cfg, light, reporter, rotate_light=args.rotate_light, light_file=args.light)
    emit(args, {"render": str(out)}, f"frames written to {out}")
    return 0
