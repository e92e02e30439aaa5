"""``pgc calibrate``: refine a capture's camera poses with the configured ``calibrator`` (default: COLMAP, CPU)."""

from __future__ import annotations

import argparse

from pgc.checks import naming_output
from pgc.commands._common import add_run_options, emit, load_config, reporter_for


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate", help="refine camera poses with COLMAP (feature matching + mapping, CPU)",
        description="Refine the camera poses of a capture with the configured calibrator ([calibrator] in the "
                    "run configuration; default colmap: SIFT features, exhaustive matching and incremental mapping "
                    "with the intrinsics fixed, aligned back to the capture's frame by a similarity). Works on "
                    "textured real captures; smooth synthetic cloth at low resolution gives too few matches (the "
                    "figures say how many views registered).",
        epilog="example: pgc calibrate runs/cap --out runs/cap_calibrated")
    p.add_argument("capture", help="capture folder (transforms.json)")
    p.add_argument("--out", required=True, help="capture folder to write with the refined cameras")
    p.add_argument("--max-features", type=int, default=None,
                   help="SIFT features per image (overrides the calibrator's option max_features)")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.errors import PGCPluginError
    from pgc.io.capture import read_capture, write_capture

    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    if "calibrator" not in cfg.roles:
        raise PGCPluginError("no calibrator is registered; install one with: pip install 'pgc[colmap]'")
    choice = cfg.roles["calibrator"]
    impl = choice.implementation
    options = choice.options.get(impl.name) or impl.validate_options({})
    if args.max_features is not None:
        options = impl.validate_options(dict(options.model_dump(), max_features=args.max_features),
                                        where="--max-features")
    calibration = impl.create(options).calibrate(read_capture(args.capture), reporter=reporter)
    with naming_output(args.out):
        write_capture(args.out, calibration.capture)
    figures = calibration.figures
    emit(args, figures, "  ".join(f"{k}={v}" for k, v in figures.items()) + f"\nwritten to {args.out}")
    return 0
