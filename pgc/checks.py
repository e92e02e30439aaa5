"""Checks shared by the numeric APIs (one message format for non-finite arrays and too-small images) and the
output path carried into OS errors that name no file."""

from __future__ import annotations

import contextlib
import os
from typing import Any, Iterator

import numpy as np

from pgc.errors import PGCDataError

__all__ = ["naming_output", "require_finite", "require_min_size"]


def require_finite(where: str, name: str, array: Any, fix: str = "") -> np.ndarray:
    """``array`` as a numpy array, or a :class:`PGCDataError` naming ``where`` (the API or file), the array
    ``name``, how many of its entries are NaN or Inf and the first one. One ``np.isfinite`` pass; integer and
    boolean arrays pass without it."""
    a = np.asarray(array)
    if a.dtype.kind not in "fc":
        if a.dtype.kind == "O":
            raise PGCDataError(f"{where}: {name} must be a numeric array, got objects of {a.dtype}")
        return a
    bad = ~np.isfinite(a)
    if bad.any():
        count = int(bad.sum())
        first = tuple(int(i) for i in np.argwhere(bad)[0]) if a.ndim else ()
        at = f", first at index {first if len(first) != 1 else first[0]}" if a.ndim else ""
        raise PGCDataError(f"{where}: {name} has {count} non-finite value{'s' if count != 1 else ''} (NaN or Inf) "
                           f"of {a.size}{at}; {fix or 'give finite values'}")
    return a


def require_min_size(where: str, height: int, width: int, minimum: int, why: str) -> None:
    """A :class:`PGCDataError` if an image of ``height`` x ``width`` px has a side under ``minimum`` px."""
    if min(height, width) < minimum:
        raise PGCDataError(f"{where}: images of {height}x{width} px are too small: at least {minimum}x{minimum} px "
                           f"are needed ({why})")


@contextlib.contextmanager
def naming_output(path: str | os.PathLike) -> Iterator[None]:
    """Give ``path`` (the output being written) to an OSError raised inside that names no file: ``write()`` and
    ``fsync()`` on a full disk (ENOSPC), over a quota (EDQUOT) or on an I/O error report only the reason."""
    try:
        yield
    except OSError as exc:
        if exc.filename is None and exc.errno is not None:
            exc.filename = str(path)
        raise
