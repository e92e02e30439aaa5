"""``pgc eval``: metrics of a run against ground truth."""

from __future__ import annotations

import argparse

from pgc.errors import PGCError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="metrics of a run against ground truth (not available yet)",
                       description="Compare the frames of a run with ground truth: PSNR, SSIM, FSIM and LPIPS for the hybrid render and the 3DGS-only and PBR-only ablations. NOT AVAILABLE YET in this version.")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise PGCError("'pgc eval' is not available yet in this version of PGC")
