"""Limits on what untrusted files may make PGC allocate or parse, and the checks every reader in ``pgc.io``
uses: file sizes, counts (frames, vertices, points), pixels and nesting depth.

A small file must not be able to ask for unbounded work (a header declaring 100000 x 100000 pixels, a list of
a million frames, 100000 nested lists). Each limit is far above every real capture, asset and preset (the
largest preset capture has 128 views of 256 px); exceeding one is a :class:`PGCDataError` naming the file, the
field and the limit.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from pgc.errors import PGCDataError

MAX_JSON_BYTES = 256 << 20
"""Largest JSON file read (bytes): a transforms.json of 10000 frames with every layer is about 10 MB."""
MAX_CONFIG_BYTES = 4 << 20
"""Largest configuration (TOML) file read (bytes)."""
MAX_TEXT_BYTES = 2 << 30
"""Largest text model read whole (COLMAP text files, PLY and OBJ files; bytes)."""
MAX_DEPTH = 64
"""Deepest nesting of lists and objects in a JSON or TOML file (PGC's own files nest 5 levels)."""
MAX_VIEWS = 10_000
"""Most frames (views) of a capture."""
MAX_IMAGE_PIXELS = 1 << 28
"""Most pixels of one image (16384 x 16384)."""
MAX_CAPTURE_PIXELS = 1 << 32
"""Most pixels of all the colour images of a capture together (e.g. 500 views of 8 megapixels)."""
MAX_MOTION_FRAMES = 100_000
"""Most frames of a body motion (55 minutes at 30 frames per second)."""
MAX_ELEMENTS = 1 << 28
"""Most vertices, faces, Gaussians, points or motion positions (frames x vertices) of one file."""


def fail(path: str | os.PathLike, field: str, problem: str) -> PGCDataError:
    """The error for ``path``: ``PATH: FIELD: PROBLEM``."""
    return PGCDataError(f"{path}: {field}: {problem}" if field else f"{path}: {problem}")


def check_count(path: str | os.PathLike, field: str, count: int, limit: int, unit: str = "entries") -> int:
    """``count`` if it is at most ``limit``, else an error naming the file, the field and the limit."""
    if count > limit:
        raise fail(path, field, f"{count} {unit} is more than the limit of {limit} (pgc.io.limits); the file is "
                                "corrupt or not meant for PGC: check it, or split it")
    return count


def check_pixels(path: str | os.PathLike, width: int, height: int, field: str = "image size") -> None:
    """Refuse a non-positive image size or one above :data:`MAX_IMAGE_PIXELS` (before decoding anything)."""
    if width <= 0 or height <= 0:
        raise fail(path, field, f"{width}x{height} pixels: the image has no pixels")
    if width * height > MAX_IMAGE_PIXELS:
        raise fail(path, field, f"{width}x{height} = {width * height} pixels is more than the limit of "
                                f"{MAX_IMAGE_PIXELS} (pgc.io.limits.MAX_IMAGE_PIXELS); the header is corrupt or "
                                "the image must be scaled down")


def check_file_size(path: str | os.PathLike, limit: int, what: str = "file") -> int:
    """The size of ``path`` in bytes if it is at most ``limit``, else an error naming the file and the limit."""
    size = os.stat(path).st_size
    if size > limit:
        raise fail(path, "", f"the {what} is {size} bytes, more than the limit of {limit} bytes (pgc.io.limits); "
                             f"is it the right file?")
    return size


def nesting_depth(obj: Any) -> int:
    """Depth of nested lists, tuples and dicts in ``obj`` (a scalar is 0), without recursion."""
    depth, level = 0, [(obj, 1)]
    while level:
        value, d = level.pop()
        items = value.values() if isinstance(value, dict) else value if isinstance(value, (list, tuple)) else None
        if items is None:
            continue
        depth = max(depth, d)
        level.extend((v, d + 1) for v in items if isinstance(v, (dict, list, tuple)))
    return depth


def check_depth(path: str | os.PathLike, obj: Any, limit: int = MAX_DEPTH) -> Any:
    """``obj`` if its lists and objects nest at most ``limit`` levels deep, else an error naming the file."""
    depth = nesting_depth(obj)
    if depth > limit:
        raise fail(path, "", f"lists or objects nested {depth} levels deep, more than the limit of {limit}")
    return obj


def _too_deep(path: str | os.PathLike, kind: str) -> PGCDataError:
    return fail(path, "", f"lists or objects nested too deeply to parse ({kind}; the limit is {MAX_DEPTH} levels); "
                          "the file is corrupt or hostile")


def read_json(path: str | os.PathLike, what: str = "JSON file", limit: int = MAX_JSON_BYTES, fix: str = "") -> Any:
    """Parse a JSON file read from an untrusted source: at most ``limit`` bytes, UTF-8, strict JSON, nested at
    most :data:`MAX_DEPTH` levels. Errors name the file (``what`` says what it should be) and end with ``fix``
    (what the user can do about it), when given."""
    try:
        return _read_json(Path(path), what, limit)
    except PGCDataError as exc:
        if not fix:
            raise
        raise PGCDataError(f"{exc}; {fix}") from None


def _read_json(path: Path, what: str, limit: int) -> Any:
    if not path.is_file():
        raise fail(path, "", f"not found (or not a file); expected a {what}")
    check_file_size(path, limit, what)
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise fail(path, "", f"malformed {what}: not UTF-8 text (byte {exc.start}: {exc.reason}); a {what} is "
                             "UTF-8 JSON") from None
    return loads_json(text, path, what)


def loads_json(text: str, source: str | os.PathLike, what: str = "JSON document") -> Any:
    """Parse JSON ``text`` read from ``source`` (a file, or a field of one), nested at most :data:`MAX_DEPTH`
    levels; errors name ``source``."""
    try:
        return check_depth(source, json.loads(text))
    except json.JSONDecodeError as exc:
        raise fail(source, "", f"malformed JSON ({exc}); expected a {what}") from None
    except RecursionError:
        raise _too_deep(source, "JSON") from None


def read_toml(path: str | os.PathLike, limit: int = MAX_CONFIG_BYTES) -> dict[str, Any]:
    """Parse a TOML file read from an untrusted source (size, nesting depth); raises ``UnicodeDecodeError``
    and ``tomllib.TOMLDecodeError`` for the caller to word, and :class:`PGCDataError` for the limits."""
    import tomllib

    path = Path(path)
    check_file_size(path, limit, "TOML file")
    with open(path, "rb") as f:
        raw = f.read()
    try:
        return check_depth(path, tomllib.loads(raw.decode("utf-8")))
    except RecursionError:
        raise _too_deep(path, "TOML") from None
