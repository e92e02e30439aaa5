"""``pgc synth``: generate a synthetic capture with ground truth."""

from __future__ import annotations

import argparse

from pgc.errors import PGCError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("synth", help="generate a synthetic capture with ground truth (not available yet)",
                       description="Generate a synthetic multi-view capture of a clothed body (Mitsuba path tracing) with complete ground truth: meshes, materials, textures, light, albedo and depth per view. NOT AVAILABLE YET in this version.")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise PGCError("'pgc synth' is not available yet in this version of PGC")
