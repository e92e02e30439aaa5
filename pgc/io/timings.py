"""Wall-clock figures kept apart from results, so that the same inputs give byte-identical assets and runs.

A figure is a timing when its key is ``seconds``, starts with ``seconds_`` or ends with ``_seconds`` or
``_per_second`` (at any depth of dicts and lists). :func:`split_timings` separates them; an asset or run folder
keeps them in ``timings.json`` (a measurement of this run, written after the folder's manifest and never hashed
into it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pgc.errors import PGCDataError
from pgc.io.atomic import write_json
from pgc.io.limits import read_json

TIMINGS = "timings.json"


def is_timing(key: str) -> bool:
    """Whether a figure named ``key`` is a wall-clock measurement (seconds, or a rate per second)."""
    return key == "seconds" or key.startswith("seconds_") or key.endswith(("_seconds", "_per_second"))


def split_timings(figures: Any) -> tuple[Any, Any]:
    """``(figures without timings, the timings alone)``, both with the nesting of ``figures`` (dicts and lists;
    the timings' side keeps only the branches that hold a timing, None when there is none)."""
    if isinstance(figures, dict):
        kept, timed = {}, {}
        for key, value in figures.items():
            if isinstance(key, str) and is_timing(key):
                timed[key] = value
                continue
            kept[key], sub = split_timings(value)
            if sub is not None:
                timed[key] = sub
        return kept, (timed or None)
    if isinstance(figures, list):
        pairs = [split_timings(v) for v in figures]
        timed = [t for _, t in pairs]
        return [k for k, _ in pairs], (timed if any(t is not None for t in timed) else None)
    return figures, None


def write_timings(folder: str | Path, timings: dict[str, Any]) -> None:
    """Write ``folder/timings.json`` (atomically)."""
    write_json(Path(folder) / TIMINGS, timings)


def read_timings(folder: str | Path) -> dict[str, Any]:
    """``folder/timings.json``, or {} when the folder has none or it is unreadable (timings are informative)."""
    path = Path(folder) / TIMINGS
    try:
        data = read_json(path, TIMINGS)
    except (OSError, PGCDataError):
        return {}
    return data if isinstance(data, dict) else {}
