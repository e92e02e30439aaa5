"""The user cache folder of PGC: ``$PGC_CACHE_DIR``, default ``~/.cache/pgc`` (compiled kernels, LPIPS weights,
synthetic captures kept across run folders)."""

from __future__ import annotations

import os
from pathlib import Path


def user_cache_dir() -> Path:
    """``$PGC_CACHE_DIR`` or ``~/.cache/pgc``."""
    return Path(os.environ.get("PGC_CACHE_DIR") or Path.home() / ".cache" / "pgc")
