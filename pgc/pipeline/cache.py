"""On-disk stage cache keyed by content hash: long pipelines resume where they stopped.

A stage's key hashes everything that decides its result: its options, the implementation chosen, the keys
of the stages it reads and a format version. Its outputs are written into a temporary folder that is
renamed into place only when complete, so an interrupted run never leaves a half-written stage; the next
run recomputes exactly the stages whose key changed or that never finished.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Generic, TypeVar

from pgc.io.atomic import write_json

T = TypeVar("T")
CACHE_FORMAT = 1


def content_key(*parts: Any) -> str:
    """A stable sha256 (first 16 hex digits) of JSON-serialisable parts (dict keys sorted)."""
    text = json.dumps([CACHE_FORMAT, *parts], sort_keys=True, default=_default)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def file_key(path: str | Path, chunk: int = 1 << 20) -> str:
    """sha256 (first 16 hex digits) of a file's bytes, or of every file below a folder (names included)."""
    path = Path(path)
    h = hashlib.sha256()
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
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
    """Stages stored below ``root/<stage>/`` with a ``stage.json`` recording the key and figures."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    def folder(self, stage: str) -> Path:
        return self.root / stage

    def cached_key(self, stage: str) -> str | None:
        meta = self.folder(stage) / "stage.json"
        if not meta.is_file():
            return None
        try:
            return json.loads(meta.read_text())["key"]
        except (json.JSONDecodeError, KeyError):
            return None

    def figures(self, stage: str) -> dict[str, Any]:
        meta = self.folder(stage) / "stage.json"
        return json.loads(meta.read_text()).get("figures", {}) if meta.is_file() else {}

    def run(self, stage: str, key: str, compute: Callable[[Path], tuple[T, dict[str, Any]]],
            load: Callable[[Path], T]) -> StageResult[T]:
        """Load ``stage`` if its stored key equals ``key``; else ``compute(tmp_folder)`` -> (value, figures).

        ``compute`` writes its files into the folder it is given; ``load(folder)`` reads them back.
        """
        final = self.folder(stage)
        if self.cached_key(stage) == key:
            return StageResult(load(final), key, True, final)
        self.root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{stage}.", dir=self.root))
        try:
            value, figures = compute(tmp)
            write_json(tmp / "stage.json", {"stage": stage, "key": key, "figures": figures})
            if final.exists():
                shutil.rmtree(final)
            tmp.rename(final)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
        return StageResult(value, key, False, final)
