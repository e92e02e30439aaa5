"""``pgc render``: render an animated run (hybrid 3DGS + PBR)."""

from __future__ import annotations

import argparse

from pgc.errors import PGCError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("render", help="render an animated run (hybrid 3DGS + PBR) (not available yet)",
                       description="Render every frame of an animated run with the hybrid renderer: PBR far field into texture space, Gaussians near field, alpha-aware frequency composition; optional relighting. NOT AVAILABLE YET in this version.")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise PGCError("'pgc render' is not available yet in this version of PGC")
