"""The ``pgc`` command line. Each subcommand lives in ``pgc/commands/<name>.py``.

Importing this module (and ``pgc --help``) stays light: no torch, jax, mitsuba, open3d or pycolmap.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from pgc.errors import PGCError

COMMANDS = ("plugins", "config", "synth", "calibrate", "reconstruct", "animate", "render", "eval", "bench", "demo")

EPILOG = """\
typical session:
  pgc plugins                      what is installed, and what is missing
  pgc demo --preset tiny           synthetic capture -> asset -> novel poses -> metrics, in minutes
  pgc synth OUT --preset default   a synthetic capture with ground truth
  pgc reconstruct OUT --out ASSET  mesh, Gaussians, albedo, material
  pgc config show                  the resolved configuration with every default
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pgc", description="PGC: physics-based Gaussian cloth from a single pose.", epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"pgc {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module = importlib.import_module(f"pgc.commands.{name}_cmd")
        module.add_parser(sub)
    return parser


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("pgc")
    except PackageNotFoundError:
        return "unknown"


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except PGCError as exc:
        print(f"pgc {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"pgc {args.command}: interrupted; completed stages are kept and a rerun resumes", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
