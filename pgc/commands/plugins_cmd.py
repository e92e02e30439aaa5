"""``pgc plugins``: list every registered implementation, whether it is available, and why not."""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plugins", help="list installed implementations per role",
                       description="List every implementation registered through the 'pgc' entry points, "
                                   "by role, with its provider and availability. Each available one's factory is "
                                   "imported and checked against its role's interface. Unavailable ones say what "
                                   "to install or what is wrong; plugins that failed to load show their error.")
    from pgc.registry import ROLES

    p.add_argument("--role", choices=list(ROLES), help="only this role")
    p.add_argument("--json", action="store_true", help="machine-readable list of objects")
    p.set_defaults(func=run)


def rows(registry, role: str | None = None) -> list[dict]:
    """One row per implementation (of ``role``, default every role; each available one's factory imported and
    checked) and per plugin that failed to load."""
    out = []
    for i in registry.list(role):
        reason = i.problem()
        out.append({"role": i.role, "name": i.name, "provider": i.provider, "plugin": i.plugin,
                    "available": reason is None, "reason": reason, "description": i.spec.description})
    out += [{"role": None, "name": b.plugin, "provider": b.provider, "plugin": b.plugin, "available": False,
             "reason": f"plugin failed to load: {b.error}", "description": ""} for b in registry.broken]
    return out


def run(args: argparse.Namespace) -> int:
    from pgc.registry import ROLES, Registry

    registry = Registry.discover()
    data = rows(registry, args.role)
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
