"""Where the converted LPIPS weights live (light module: no torch).

``lpips_{net}.npz`` is looked up in the package's ``pgc/data`` (AlexNet ships there) and then in the user
cache ``$PGC_CACHE_DIR`` (default ``~/.cache/pgc``), where ``scripts/convert_lpips_weights.py --net vgg``
writes the VGG weights at install time.
"""

from __future__ import annotations

import os
from pathlib import Path

from pgc.errors import PGCPluginError

LPIPS_NETS = ("alex", "vgg")
PACKAGE_DATA = Path(__file__).resolve().parents[1] / "data"


def cache_dir() -> Path:
    """The user cache folder of PGC: ``$PGC_CACHE_DIR`` or ``~/.cache/pgc``."""
    return Path(os.environ.get("PGC_CACHE_DIR") or Path.home() / ".cache" / "pgc")


def lpips_weights_path(net: str) -> Path:
    """The ``.npz`` of LPIPS backbone ``net`` ('alex' or 'vgg'), or a PGCPluginError saying how to make it."""
    if net not in LPIPS_NETS:
        raise PGCPluginError(f"lpips: unknown backbone '{net}'; choose one of {', '.join(LPIPS_NETS)}")
    for folder in (PACKAGE_DATA, cache_dir()):
        path = folder / f"lpips_{net}.npz"
        if path.is_file():
            return path
    raise PGCPluginError(f"lpips: weights 'lpips_{net}.npz' not found in {PACKAGE_DATA} or {cache_dir()}; "
                         f"create them once with: python scripts/convert_lpips_weights.py --net {net}")
