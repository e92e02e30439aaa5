"""``pgc bench``: compare implementations: speed against error."""

from __future__ import annotations

import argparse

from pgc.errors import PGCError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="compare implementations: speed against error (not available yet)",
                       description="Run a matrix of implementations per role on synthetic presets and record seconds, peak memory and error against ground truth (bench.json, CSV, plots, HTML). NOT AVAILABLE YET in this version.")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise PGCError("'pgc bench' is not available yet in this version of PGC")
