"""``pgc demo``: the whole pipeline on the default synthetic scene."""

from __future__ import annotations

import argparse

from pgc.errors import PGCError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="the whole pipeline on the default synthetic scene (not available yet)",
                       description="Synthetic capture -> reconstruct -> animate on the paper's test motions -> ground-truth renders -> eval -> an HTML report and metrics.json. NOT AVAILABLE YET in this version.")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise PGCError("'pgc demo' is not available yet in this version of PGC")
