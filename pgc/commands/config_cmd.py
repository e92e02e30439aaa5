"""``pgc config show|validate``: the resolved run configuration."""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("config", help="show or validate a run configuration",
                       description="A run is configured by one TOML file: one table per role naming the "
                                   "implementation (or an ordered fallback list) and its options, and "
                                   "[stages.NAME] tables. Missing tables take the defaults.")
    s = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    show = s.add_parser("show", help="print the resolved config with every default")
    show.add_argument("file", nargs="?", help="config TOML (default: the built-in defaults)")
    show.add_argument("--json", action="store_true", help="print JSON instead of TOML")
    val = s.add_parser("validate", help="check a config file, and that its chosen plugins implement their roles, "
                                        "without running anything")
    val.add_argument("file", help="config TOML")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc import config

    cfg = config.load(args.file, require_available=args.action == "validate")
    if args.action == "validate":
        cfg.check_implementations()
        chosen = ", ".join(f"{r}={c.name}" for r, c in cfg.roles.items())
        print(f"{args.file}: ok ({chosen})")
        return 0
    data = cfg.to_dict()
    print(json.dumps(data, indent=2) if args.json else config.dumps_toml(data), end="" if not args.json else "\n")
    return 0
