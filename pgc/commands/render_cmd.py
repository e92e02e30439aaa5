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
                    "(EXR, latitude-longitude); --rotate-light turns it a full circle over the frames.",
        epilog="example: pgc render runs/spooky --light sky.exr --rotate-light")
    p.add_argument("run", help="run folder (from pgc animate)")
    p.add_argument("--light", help="environment map (EXR) to relight with; default: the fitted capture light")
    p.add_argument("--rotate-light", action="store_true", help="rotate the environment 360 degrees over the frames")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.pipeline.render import render_run

    check_run(args.run)
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    light = None
    if args.light:
        from pgc.pipeline.render import envmap_light

        light = envmap_light(args.run, args.light)
    with writing(args.run, "pgc render"):
        out = render_run(args.run, cfg, light, reporter, rotate_light=args.rotate_light, light_file=args.light)
    emit(args, {"render": str(out)}, f"frames written to {out}")
    return 0
