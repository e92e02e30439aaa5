"""Subcommands of ``pgc``: each module exposes ``add_parser(subparsers)`` and keeps heavy imports in ``run``."""
