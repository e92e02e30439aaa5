"""The benchmark record (DESIGN.md "Benchmark records"): schema, reference ratios, JSON and CSV.

One record per measured run::

    {"role", "implementation", "preset", "settings": {...}, "seconds", "peak_mb", "errors": {...},
     "versions": {...}, "error_key", "label", "x_reference", "detail"}

``settings["case"]`` names the workload case (image size, kernel, scene); the run with
``settings["reference"] == True`` in the same role and case is the speed base: ``x_reference = seconds /
reference seconds``. ``error_key`` names the error plotted against seconds (lower is better);
``label`` names the run in tables and plots (implementation and variant options). ``errors`` keys are
lower-case, ``_std`` suffixes for standard deviations of averaged errors. ``detail`` is the path, relative to
bench.json, of the run's per-view/per-frame file. A failed run has ``failed`` (the message) and no errors.
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
from typing import Any

from pgc.errors import PGCDataError

REQUIRED = {"role": str, "implementation": str, "preset": str, "settings": dict, "seconds": (int, float),
            "peak_mb": (int, float), "errors": dict, "versions": dict}
CSV_FIXED = ("role", "implementation", "label", "preset", "case", "seconds", "x_reference", "peak_mb", "error_key",
             "failed", "detail", "settings", "versions")
ERROR_PREFIX = "error."


def make_record(role: str, implementation: str, preset: str, case: str, settings: dict[str, Any],
                seconds: float, peak_mb: float, errors: dict[str, float], error_key: str,
                versions: dict[str, str], reference: bool = False) -> dict[str, Any]:
    """A record with the common keys; ``x_reference`` and ``detail`` are filled in by the runner."""
    return {"role": role, "implementation": implementation, "preset": preset,
            "settings": {"case": case, "reference": reference, "options": {}, **settings}, "seconds": float(seconds),
            "peak_mb": float(peak_mb), "errors": {k.lower(): float(v) for k, v in errors.items()},
            "error_key": error_key, "versions": versions, "x_reference": None, "detail": None}


def validate(records: list[dict[str, Any]], where: str = "bench.json") -> None:
    """Raise PGCDataError naming the record and key when a record misses a field or has the wrong type."""
    if not isinstance(records, list):
        raise PGCDataError(f"{where}: expected a JSON list of records, got {type(records).__name__}")
    for i, r in enumerate(records):
        for key, kind in REQUIRED.items():
            if key not in r:
                raise PGCDataError(f"{where}: record {i} has no '{key}' (required: {', '.join(REQUIRED)})")
            if not isinstance(r[key], kind):
                raise PGCDataError(f"{where}: record {i} '{key}' is {type(r[key]).__name__}, expected {kind}")
        bad = [k for k in r["errors"] if k != k.lower()]
        if bad:
            raise PGCDataError(f"{where}: record {i} has error keys that are not lower-case: {bad}")


def add_reference_ratios(records: list[dict[str, Any]]) -> None:
    """Set ``x_reference`` of every record from the reference run of its role and case (None without one)."""
    base = {(r["role"], r["settings"].get("case")): r["seconds"] for r in records
            if r["settings"].get("reference") and not r.get("failed") and r["seconds"] > 0}
    for r in records:
        b = base.get((r["role"], r["settings"].get("case")))
        r["x_reference"] = None if b is None or r.get("failed") else r["seconds"] / b


def write_json(path: str | os.PathLike, records: list[dict[str, Any]]) -> None:
    from pgc.io import atomic

    atomic.write_json(path, records)


def read_json(path: str | os.PathLike) -> list[dict[str, Any]]:
    path = Path(path)
    if not path.is_file():
        raise PGCDataError(f"{path}: no bench.json there; run 'pgc bench --out {path.parent}' first")
    from pgc.io.limits import read_json as read_limited

    records = read_limited(path, "bench.json (a list of bench records)")
    validate(records, str(path))
    return records


def write_csv(path: str | os.PathLike, records: list[dict[str, Any]]) -> None:
    """One row per record: the fixed columns, then ``error.<key>`` per error key; settings and versions as JSON."""
    keys = sorted({k for r in records for k in r["errors"]})
    from pgc.io.atomic import atomic_open

    with atomic_open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*CSV_FIXED, *(ERROR_PREFIX + k for k in keys)])
        for r in records:
            row = [r["role"], r["implementation"], r.get("label") or r["implementation"], r["preset"], r["settings"].get("case", ""), repr(r["seconds"]),
                   _num(r.get("x_reference")), repr(r["peak_mb"]), r.get("error_key") or "", r.get("failed") or "",
                   r.get("detail") or "", json.dumps(r["settings"], sort_keys=True),
                   json.dumps(r["versions"], sort_keys=True)]
            w.writerow(row + [_num(r["errors"].get(k)) for k in keys])


def _num(x: float | None) -> str:
    return "" if x is None else repr(float(x))


def read_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """The records of a CSV written by :func:`write_csv` (the inverse: floats round-trip exactly)."""
    from pgc.io.limits import loads_json

    out = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            r: dict[str, Any] = {"role": row["role"], "implementation": row["implementation"],
                                 "preset": row["preset"],
                                 "settings": loads_json(row["settings"], f"{path}: column 'settings'"),
                                 "seconds": float(row["seconds"]), "peak_mb": float(row["peak_mb"]),
                                 "errors": {k[len(ERROR_PREFIX):]: float(v) for k, v in row.items()
                                            if k.startswith(ERROR_PREFIX) and v != ""},
                                 "error_key": row["error_key"], "label": row["label"],
                                 "versions": loads_json(row["versions"], f"{path}: column 'versions'"),
                                 "x_reference": float(row["x_reference"]) if row["x_reference"] else None,
                                 "detail": row["detail"] or None}
            if row["failed"]:
                r["failed"] = row["failed"]
            out.append(r)
    return out


def finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)
