"""``pgc animate``: simulate an asset on a body motion."""

from __future__ import annotations

import argparse

from pgc.errors import PGCError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("animate", help="simulate an asset on a body motion (not available yet)",
                       description="Simulate the garment of an asset on a body motion (a built-in motion name or a file) with the configured simulator. NOT AVAILABLE YET in this version.")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise PGCError("'pgc animate' is not available yet in this version of PGC")
