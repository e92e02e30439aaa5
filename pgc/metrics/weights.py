"""Where the converted LPIPS weights live (light module: no torch).

``lpips_{net}.npz`` is looked up in the package's ``pgc/data`` (AlexNet ships there) and then in the user
cache ``$PGC_CACHE_DIR`` (default ``~/.cache/pgc``), where ``scripts/convert_lpips_weights.py --net vgg``
writes the VGG weights at install time.
"""

from __future__ import annotations

from pathlib import Path

from pgc.errors import PGCPluginError
from pgc.user_cache import user_cache_dir

LPIPS_NETS = ("alex", "vgg")
PACKAGE_DATA = Path(__file__).resolve().parents[1] / "data"


def lpips_weights_path(net: str) -> Path:
    """The ``.npz`` of LPIPS backbone ``net`` ('alex' or 'vgg'), or a PGCPluginError saying how to make it."""
    if net not in LPIPS_NETS:
        raise PGCPluginError(f"lpips: unknown backbone '{net}'; choose one of {', '.join(LPIPS_NETS)}")
    for folder in (PACKAGE_DATA, user_cache_dir()):
        path = folder / f"lpips_{net}.npz"
        if path.is_file():
            return path
    raise PGCPluginError(f"lpips: weights 'lpips_{net}.npz' not found in {PACKAGE_DATA} or {user_cache_dir()}; "
                         f"create them once with: python scripts/convert_lpips_weights.py --net {net}")
