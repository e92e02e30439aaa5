"""``pgc plugins``: list every registered implementation, whether it is available, and why not."""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plugins", help="list installed implementations per role",
                       description="List every implementation registered through the 'pgc' entry points, "
                                   "by role, with its provider and availability. Unavailable ones say what to "
                                   "install; plugins that failed to load show their error.")
    from pgc.registry import ROLES

    p.add_argument("--role", choices=list(ROLES), help="only this role")
    p.add_argument("--json", action="store_true", help="machine-readable list of objects")
    p.set_defaults(func=run)


def rows(registry) -> list[dict]:
    out = [{"role": i.role, "name": i.name, "provider": i.provider, "plugin": i.plugin, "available": i.available,
            "reason": i.reason, "description": i.spec.description} for i in registry.list()]
    out += [{"role": None, "name": b.plugin, "provider": b.provider, "plugin": b.plugin, "available": False,
             "reason": f"plugin failed to load: {b.error}", "description": ""} for b in registry.broken]
    return out


def run(args: argparse.Namespace) -> int:
    from pgc.registry import ROLES, Registry

    registry = Registry.discover()
    data = [r for r in rows(registry) if args.role is None or r["role"] in (args.role, None)]
    if args.json:
        print(json.dumps(data, indent=2))
        return 0
    for role in ROLES:
        if args.role and role != args.role:
            continue
        print(f"{role}:")
        entries = [r for r in data if r["role"] == role]
        if not entries:
            print("  (none registered)")
        for r in entries:
            mark = "ok " if r["available"] else "-- "
            line = f"  {mark}{r['name']:<16} {r['description']}  [{r['provider']}]"
            print(line if r["available"] else f"{line}\n       unavailable: {r['reason']}")
    broken = [r for r in data if r["role"] is None]
    if broken:
        print("plugins that failed to load:")
        for r in broken:
            print(f"  {r['name']} ({r['provider']}): {r['reason']}")
    return 0
