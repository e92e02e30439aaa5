"""Atomic file writes: write to a temporary file beside the target, fsync, then rename.

A crash mid-write leaves the previous file intact; readers never see a half-written file. The temporary file
is named ``.<stem>.<pid>.<random>.tmp<suffix>``: a process killed mid-write (SIGKILL) leaves it behind, and
the next write of the same target removes the ones whose process is gone.
"""

from __future__ import annotations

import contextlib
import glob
import json
import math
import os
import tempfile
from pathlib import Path
from typing import IO, Any, Iterator


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success it replaces ``path`` atomically.

    The temporary name keeps the target's suffix so that libraries choosing a format by extension work.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_orphans(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.{os.getpid()}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def remove_orphans(path: Path) -> list[Path]:
    """Remove the temporary files of earlier writes of ``path`` whose process is gone (killed mid-write);
    returns what was removed. A temporary file of a live process (a concurrent writer) is kept."""
    prefix, suffix = f".{path.stem}.", f".tmp{path.suffix}"
    removed = []
    for tmp in path.parent.glob(f"{glob.escape(prefix)}*{glob.escape(suffix)}"):
        pid, _, rest = tmp.name[len(prefix):-len(suffix)].partition(".")
        if pid.isdigit() and rest and "." not in rest and tmp.is_file() and not process_alive(int(pid)):
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
    return removed


def process_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (a pid reused by another process counts as alive: nothing is lost)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", **kwargs: Any) -> Iterator[IO]:
    """Open a temporary file for writing that replaces ``path`` atomically when closed without error."""
    if not any(m in mode for m in "wx"):
        raise ValueError("atomic_open is for writing ('w' or 'wb')")
    with atomic_path(path) as tmp:
        with open(tmp, mode.replace("x", "w"), **kwargs) as f:
            yield f


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write strict JSON atomically (UTF-8, indented, keys in insertion order).

    Non-finite floats (NaN, +-inf), which JSON cannot hold, are written as ``null``.
    """
    text = json.dumps(finite_or_none(obj), indent=2, default=_json_default, allow_nan=False)
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(text + "\n")


def finite_or_none(obj: Any) -> Any:
    """``obj`` with every non-finite float (also in numpy scalars and arrays) replaced by ``None``, containers
    (dict, list, tuple) rebuilt; anything else unchanged."""
    import numpy as np

    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    elif isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_none(v) for v in obj]
    return obj


def write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(text)


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot write {type(obj).__name__} as JSON")
