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
import re
import shutil
import stat
import tempfile
from pathlib import Path
from typing import IO, Any, Iterator

from pgc.errors import PGCDataError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path; on success its content replaces ``path`` (see :func:`write_target`).

    The temporary name keeps the target's suffix so that libraries choosing a format by extension work.
    A regular file (or a new path) is replaced atomically by a rename in its folder; a symbolic link is
    followed, so its target's content is replaced and the link kept; a character device (``/dev/null``,
    ``/dev/stdout``) or a pipe reached through ``/dev/stdout``, ``/dev/stderr`` or ``/dev/fd/N`` is written
    in place. Anything else (a folder, a FIFO, a socket, a block device, a dangling link) is refused before
    anything is written.
    """
    target, in_place = write_target(path)
    if in_place:
        with _in_place(target) as tmp:
            yield tmp
        return
    ensure_folder(target.parent)
    remove_orphans(target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.{os.getpid()}.", suffix=f".tmp{target.suffix}",
                               dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp_path, target)
    except OSError as exc:  # write() and fsync() on a full disk or an I/O error name no file: name the output
        if exc.filename is None and exc.errno is not None:  # (an OSError made from a message alone keeps it)
            exc.filename = str(path)
        raise
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


_OPEN_STREAMS = re.compile(r"/dev/(stdout|stderr|fd/\d+)|/proc/(self|\d+)/fd/\d+")
"""Paths naming a descriptor the process already has open: writing to them never blocks on a pipe."""


def write_target(path: str | os.PathLike) -> tuple[Path, bool]:
    """Where a write of ``path`` goes, and whether it is written in place (a character device, or an open
    pipe); refuses, with :class:`PGCDataError`, a path that is no file to write (see :func:`atomic_path`)."""
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            raise PGCDataError(f"{path}: is a symbolic link to {os.readlink(path)}, which does not exist; remove "
                               "the link or give another path") from None
        return path, False
    except NotADirectoryError:
        return path, False  # a part of the path is a file: ensure_folder says which
    if stat.S_ISCHR(st.st_mode) or (_OPEN_STREAMS.fullmatch(os.path.abspath(path))
                                    and (stat.S_ISFIFO(st.st_mode) or stat.S_ISREG(st.st_mode))):
        return path, True
    if stat.S_ISREG(st.st_mode):
        return (Path(os.path.realpath(path)) if os.path.islink(path) else path), False
    if stat.S_ISDIR(st.st_mode):
        raise PGCDataError(f"{path}: is a folder; give a file path (e.g. {path / ('out' + path.suffix)})")
    kind = {stat.S_ISFIFO: "a named pipe (FIFO)", stat.S_ISSOCK: "a socket",
            stat.S_ISBLK: "a block device"}
    what = next((name for test, name in kind.items() if test(st.st_mode)), "not a regular file")
    raise PGCDataError(f"{path}: is {what}, not a regular file; PGC writes files (or character devices such "
                       "as /dev/null): give another path")


def check_folder(folder: str | os.PathLike) -> Path:
    """The nearest existing part of ``folder`` (``folder`` itself if it exists), once every existing part is
    a folder; refuses, with :class:`PGCDataError`, a path of which a part is a file or another node. Creates
    nothing (:func:`ensure_folder` does)."""
    folder = Path(folder)
    part = folder
    while not os.path.lexists(part) and part != part.parent:
        part = part.parent
    if os.path.lexists(part) and not part.is_dir():
        where = "is" if part == folder else f"lies below {part}, which is"
        raise PGCDataError(f"{folder}: {where} not a folder: it is {_node_kind(part)}; give another path")
    return part


def ensure_folder(folder: str | os.PathLike) -> Path:
    """Create ``folder`` (and its parents) unless it exists; refuses a path of which a part is not a folder."""
    folder = Path(folder)
    check_folder(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _node_kind(path: Path) -> str:
    """What the existing ``path`` is, in words (a file, a named pipe, a dangling link, ...)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return "a symbolic link to a missing target" if os.path.islink(path) else "not readable"
    kinds = ((stat.S_ISREG, "a file"), (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket"),
             (stat.S_ISBLK, "a block device"), (stat.S_ISCHR, "a character device"))
    return next((name for test, name in kinds if test(mode)), "another kind of node")


@contextlib.contextmanager
def _in_place(device: Path) -> Iterator[Path]:
    """A temporary file (in the system's temporary folder) whose bytes are then written to ``device``."""
    fd, tmp = tempfile.mkstemp(prefix=".pgc.", suffix=f".tmp{device.suffix}")
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        try:
            with open(tmp_path, "rb") as src, open(device, "wb") as dst:
                shutil.copyfileobj(src, dst)
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror or str(exc), str(device)) from None
    finally:
        tmp_path.unlink(missing_ok=True)


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
