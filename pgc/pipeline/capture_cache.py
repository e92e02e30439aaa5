"""Synthetic captures kept across run folders, by content key: a fibre truth costs minutes of path tracing (the
default demo's 128 views about 5 minutes on 2 cores), and the demo, the sweeps and the bench ask for the same scenes
again in new folders.

The cache is ``$PGC_CAPTURE_CACHE`` (a folder; ``off`` turns it off), default ``$PGC_CACHE_DIR/captures``
(``~/.cache/pgc/captures``). An entry is ``KEY/``, a whole capture folder, written under a temporary name and
renamed when complete, so that an interrupted generation leaves nothing that a later run could take for it. The key
covers what the caller says made the capture (preset, overrides, seed, scene renderer and body model) and the source
of the generator (:mod:`pgc.synth`) and of the scene renderer's package, so that an edited generator is not served
its old captures. Delete the folder to reclaim the space (the default capture: about 85 MB).
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pgc.pipeline.cache import content_key

if TYPE_CHECKING:
    from pgc.config import RunConfig

CACHE_ENV = "PGC_CAPTURE_CACHE"
KEY_FILE = ".pgc-synth-key"
"""Written last into a capture folder that a key made: the key (a folder holding it needs no generation)."""


def capture_cache_root() -> Path | None:
    """``$PGC_CAPTURE_CACHE``, default ``$PGC_CACHE_DIR/captures``; None when the variable is ``off``."""
    from pgc.user_cache import user_cache_dir

    value = os.environ.get(CACHE_ENV, "")
    if value.lower() == "off":
        return None
    return Path(value) if value else user_cache_dir() / "captures"


def source_key(*classes: type) -> str:
    """sha256 (16 hex digits) of the ``.py`` files (names and bytes) of the generator package and of each class's
    package."""
    import importlib
    import inspect

    folders = {Path(importlib.import_module("pgc.synth").__file__).parent}
    folders |= {Path(inspect.getfile(c)).parent for c in classes}
    h = hashlib.sha256()
    for folder in sorted(folders):
        for path in sorted(folder.rglob("*.py")):
            h.update(str(path.relative_to(folder.parent)).encode())
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def generator_classes(cfg: RunConfig) -> list[type]:
    """The classes of ``cfg``'s scene renderer and body model (whose source a capture's cache key covers)."""
    from pgc.synth.render import scene_renderer

    if "scene_renderer" not in cfg.roles:
        scene_renderer(cfg)  # raises, naming what to install
    return [cfg.roles[role].implementation.check() for role in ("scene_renderer", "body_model")]


def cached_capture(folder: str | Path, parts: Any, make: Callable[[Path], Any], *sources: type) -> bool:
    """Fill ``folder`` with the capture that ``make(path)`` generates into ``path``, keyed by ``parts`` (JSON-able:
    what made it) and the source of the generator and of the packages of the classes ``sources``. A folder already
    holding the key is left alone; otherwise the capture is copied from the cache, generated into the cache first
    when missing (one process generates while others wait), or generated in place when the cache is off. Returns
    whether ``folder`` was (re)filled."""
    folder = Path(folder)
    key = content_key("synth-capture", parts, source_key(*sources))
    marker = folder / KEY_FILE
    if marker.is_file() and marker.read_text() == key:
        return False
    root = capture_cache_root()
    if root is None:
        make(folder)
        marker.write_text(key)
        return True
    entry = root / key
    if not (entry / KEY_FILE).is_file():
        root.mkdir(parents=True, exist_ok=True)
        with open(root / f".{key}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not (entry / KEY_FILE).is_file():
                partial = root / f".{key}.{os.getpid()}.partial"
                shutil.rmtree(partial, ignore_errors=True)
                make(partial)
                (partial / KEY_FILE).write_text(key)
                shutil.rmtree(entry, ignore_errors=True)
                os.replace(partial, entry)
    marker.unlink(missing_ok=True)
    shutil.copytree(entry, folder, dirs_exist_ok=True, ignore=shutil.ignore_patterns(KEY_FILE))
    marker.write_text(key)
    return True
