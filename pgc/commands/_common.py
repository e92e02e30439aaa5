"""Shared pieces of the run commands: the --config/--quiet options and the registry + progress display."""

from __future__ import annotations

import argparse
import json
from typing import Any


def add_run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE", help="run configuration TOML (default: built-in defaults; "
                                                     "see 'pgc config show')")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def reporter_for(args: argparse.Namespace):
    """A registry with the progress display attached (unless --quiet) and a Reporter on its hooks."""
    from pgc.events import Reporter
    from pgc.progress import ProgressPrinter
    from pgc.registry import Registry

    registry = Registry.discover()
    if not getattr(args, "quiet", False):
        registry.plugin_manager.register(ProgressPrinter(), name="progress")
    return registry, Reporter(registry.hook)


def load_config(args: argparse.Namespace, registry: Any):
    from pgc import config

    return config.load(getattr(args, "config", None), registry)


def emit(args: argparse.Namespace, result: dict[str, Any], text: str) -> None:
    print(json.dumps(result, indent=2, default=str) if getattr(args, "json", False) else text)
