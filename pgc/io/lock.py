"""One writer per output folder: an exclusive ``fcntl.flock`` on ``FOLDER/.pgc.lock``.

The lock is taken without waiting: a second writer fails at once with :class:`PGCLockError` naming the
holder (pid, command, start time, recorded in the lock file). The kernel releases it when the holder exits
or is killed (SIGKILL included), so a stale lock file never blocks a rerun. The file itself stays (removing
it would race with a writer opening it); :func:`pgc.pipeline.cache.file_key` skips folders that hold one.
"""

from __future__ import annotations

import datetime
import fcntl
import json
import os
from pathlib import Path
from types import TracebackType

from pgc.errors import PGCLockError

LOCK_NAME = ".pgc.lock"


class FolderLock:
    """Context manager holding the exclusive lock of ``folder`` (created if missing) for ``command``."""

    def __init__(self, folder: str | os.PathLike, command: str) -> None:
        self.folder = Path(folder)
        self.command = command
        self._fd: int | None = None

    def __enter__(self) -> "FolderLock":
        self.acquire()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.release()

    def acquire(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / LOCK_NAME
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            raise PGCLockError(f"{self.folder}: being written by {holder}; wait for it to finish or give another "
                               "output folder") from None
        os.ftruncate(fd, 0)
        info = {"pid": os.getpid(), "command": self.command,
                "since_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
        os.write(fd, json.dumps(info).encode())
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None


def _read_holder(fd: int) -> str:
    """'pid N (COMMAND, since T)' from an open lock file, or a generic phrase when it is unreadable."""
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode())
        return f"pid {int(info['pid'])} ({info['command']}, since {info['since_utc']})"
    except (ValueError, KeyError, TypeError, OSError, RecursionError):
        return "another process"


def is_locked(folder: str | os.PathLike) -> bool:
    """Whether a live process holds the lock of ``folder``."""
    path = Path(folder) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False
