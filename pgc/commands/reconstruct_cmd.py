"""``pgc reconstruct``: capture -> garment asset."""

from __future__ import annotations

import argparse

from pgc.errors import PGCError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("reconstruct", help="capture -> garment asset (not available yet)",
                       description="Reconstruct a simulation-ready, relightable garment asset from a capture: mesh, mesh-embedded Gaussians, albedo texture, material and light. Every stage is cached and resumable. NOT AVAILABLE YET in this version.")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise PGCError("'pgc reconstruct' is not available yet in this version of PGC")
