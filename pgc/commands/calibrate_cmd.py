"""``pgc calibrate``: refine a capture's camera poses with COLMAP (CPU)."""

from __future__ import annotations

import argparse

from pgc.commands._common import emit, reporter_for


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate", help="refine camera poses with COLMAP (feature matching + mapping, CPU)",
        description="Refine the camera poses of a capture with pycolmap: SIFT features, exhaustive matching and "
                    "incremental mapping with the intrinsics fixed, aligned back to the capture's frame by a "
                    "similarity. Works on textured real captures; smooth synthetic cloth at low resolution gives "
                    "too few matches (the figures say how many views registered).",
        epilog="example: pgc calibrate runs/cap --out runs/cap_calibrated")
    p.add_argument("capture", help="capture folder (transforms.json)")
    p.add_argument("--out", required=True, help="capture folder to write with the refined cameras")
    p.add_argument("--max-features", type=int, default=4096, help="SIFT features per image")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.io.capture import read_capture, write_capture
    from pgc.registry import module_available

    if not module_available("pycolmap"):
        from pgc.errors import PGCPluginError

        raise PGCPluginError("pgc calibrate needs pycolmap; install with: pip install 'pgc[colmap]'")
    from pgc_colmap.calibrate import calibrate

    _, reporter = reporter_for(args)
    refined, figures = calibrate(read_capture(args.capture), args.max_features, reporter=reporter)
    write_capture(args.out, refined)
    emit(args, figures, "  ".join(f"{k}={v}" for k, v in figures.items()) + f"\nwritten to {args.out}")
    return 0
