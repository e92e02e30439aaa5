"""On-disk stage cache keyed by content hash: long pipelines resume where they stopped.

A stage's key hashes everything that decides its result: its options, the implementation chosen, what it
reads (the content of upstream outputs: :meth:`StageCache.output_key`, not only upstream keys), the
``code_version`` of the code computing it and a format version. Its outputs are written into a temporary
folder ``.<stage>.<pid>.*`` that is renamed into place only when complete, so an interrupted run never leaves
a half-written stage; ``stage.json`` records the hash of the outputs, and a stage whose files no longer
match it (edited, truncated) is recomputed. The next run recomputes exactly the stages whose key changed or
that never finished, and removes temporary folders left by processes that are no longer alive.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Generic, TypeVar

from pgc.errors import PGCDataError
from pgc.io.atomic import process_alive, write_json
from pgc.io.limits import read_json

T = TypeVar("T")
CACHE_FORMAT = 2
STAGE_META = "stage.json"
SKIPPED_NAMES = (".pgc.lock",)
"""Files never hashed by :func:`file_key`: the folder lock (:mod:`pgc.io.lock`) changes on every run."""


def content_key(*parts: Any) -> str:
    """A stable sha256 (first 16 hex digits) of JSON-serialisable parts (dict keys sorted)."""
    text = json.dumps([CACHE_FORMAT, *parts], sort_keys=True, default=_default)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


ASSET_KEY_FIELDS = ("schema_version", "files", "hashes", "heldout_views")
"""The parts of an asset's manifest that decide what a later stage reads: its files, their sha256 and the
views its splat fit held out; not the run configuration or the timings it also records."""


def asset_key(asset_dir: str | Path) -> str:
    """Content key of an asset folder (:data:`ASSET_KEY_FIELDS` of its ``manifest.json``): the same asset
    files give the same key whichever settings of later stages the reconstruct run recorded."""
    manifest = read_json(Path(asset_dir) / "manifest.json", "asset manifest")
    return content_key("asset", {k: manifest.get(k) for k in ASSET_KEY_FIELDS})


def file_key(path: str | Path, chunk: int = 1 << 20, exclude: tuple[str, ...] = ()) -> str:
    """sha256 (first 16 hex digits) of a file's bytes, or of every file below a folder (names included;
    lock files and ``exclude`` names at the top of the folder left out)."""
    path = Path(path)
    h = hashlib.sha256()
    files = [path] if path.is_file() else sorted(
        p for p in path.rglob("*") if p.is_file() and p.name not in SKIPPED_NAMES
        and p.relative_to(path).parts[0] not in exclude)
    for f in files:
        h.update(str(f.relative_to(path) if f != path else f.name).encode())
        with open(f, "rb") as fh:
            while block := fh.read(chunk):
                h.update(block)
    return h.hexdigest()[:16]


def array_key(array: Any) -> str:
    """sha256 (first 16 hex digits) of an array's dtype, shape and bytes."""
    import numpy as np

    a = np.ascontiguousarray(array)
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()[:16]


def _default(obj: Any) -> Any:
    if hasattr(obj, "model_dump"):
        return obj.model_dump(mode="json")
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot hash {type(obj).__name__}")


@dataclass
class StageResult(Generic[T]):
    value: T
    key: str
    cached: bool
    folder: Path


class StageCache:
    """Stages stored below ``root/<stage>/`` with a ``stage.json`` recording the key, the code version, the
    hash of the outputs and the figures."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    def folder(self, stage: str) -> Path:
        return self.root / stage

    def _meta(self, stage: str) -> dict[str, Any] | None:
        meta = self.folder(stage) / STAGE_META
        if not meta.is_file():
            return None
        try:
            data = read_json(meta, STAGE_META)
        except PGCDataError:  # malformed or over the limits: the stage is recomputed
            return None
        return data if isinstance(data, dict) else None

    def cached_key(self, stage: str, code_version: str = "") -> str | None:
        """The key of the stored stage, or None when there is none, it was computed by another
        ``code_version``, or its files do not match its record."""
        meta = self._meta(stage)
        if meta is None or not isinstance(meta.get("key"), str) or meta.get("code_version", "") != code_version:
            return None
        if meta.get("outputs") != file_key(self.folder(stage), exclude=(STAGE_META,)):
            return None
        return meta["key"]

    def output_key(self, stage: str) -> str:
        """The hash of a finished stage's output files (for the keys of the stages that read them)."""
        meta = self._meta(stage)
        if meta is None or "outputs" not in meta:
            raise KeyError(f"stage '{stage}' has not been computed in {self.root}")
        return meta["outputs"]

    def figures(self, stage: str) -> dict[str, Any]:
        meta = self._meta(stage)
        return meta.get("figures", {}) if meta else {}

    def clean_orphans(self, stage: str) -> list[Path]:
        """Remove ``.<stage>.<pid>.*`` temporary folders whose process is gone; returns what was removed."""
        removed = []
        for tmp in self.root.glob(f".{stage}.*"):
            parts = tmp.name.split(".")
            pid = int(parts[2]) if len(parts) > 3 and parts[2].isdigit() else None
            if tmp.is_dir() and (pid is None or not process_alive(pid)):
                shutil.rmtree(tmp, ignore_errors=True)
                removed.append(tmp)
        return removed

    def run(self, stage: str, key: str, compute: Callable[[Path], tuple[T, dict[str, Any]]],
            load: Callable[[Path], T], code_version: str = "") -> StageResult[T]:
        """Load ``stage`` if its stored key equals ``key`` (with ``code_version``: the stage's declared version,
        :attr:`pgc.stages.declaration.Stage.version`, passed by :class:`pgc.pipeline.runner.StageRunner`); else ``compute(tmp_folder)`` ->
        (value, figures).

        ``compute`` writes its files into the folder it is given; ``load(folder)`` reads them back.
        """
        final = self.folder(stage)
        if self.cached_key(stage, code_version) == key:
            return StageResult(load(final), key, True, final)
        self.root.mkdir(parents=True, exist_ok=True)
        self.clean_orphans(stage)
        tmp = Path(tempfile.mkdtemp(prefix=f".{stage}.{os.getpid()}.", dir=self.root))
        try:
            value, figures = compute(tmp)
            write_json(tmp / STAGE_META, {"stage": stage, "key": key, "code_version": code_version,
                                          "outputs": file_key(tmp, exclude=(STAGE_META,)), "figures": figures})
            if final.exists():
                shutil.rmtree(final)
            tmp.rename(final)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
        return StageResult(value, key, False, final)

