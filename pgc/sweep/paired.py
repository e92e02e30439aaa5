"""Paired comparison of a sweep's records against a reference value of one field (``[table] reference``): the
hybrid against each ablation, or one configuration against the others.

Two records are a pair when they differ only in that field (same scene, seed, configuration, motion, light, mode,
...). Per pair and metric, the reference's relative margin, signed so that positive means the reference is better
(each metric's ``higher_is_better``)::

    margin = (other - reference) / |other|    lower is better (LPIPS)
    margin = (reference - other) / |other|    higher is better (PSNR, SSIM, FSIM)

Per cell (the other value, the values of the table's other row and column fields, the metric): the mean margin
over the pairs, the smallest, how many pairs the reference wins, and the reference's own spread between seeds:
over each group of its records that differ only in the seed, ``(max - min) / |mean|``, averaged over the groups.
``beyond_spread`` says whether the mean margin exceeds that spread (None without a group of two seeds).
"""

from __future__ import annotations

import math
import statistics
from typing import Any

from pgc.sweep.spec import RECORD_FIELDS, SEED_FIELDS, Table, selected

PAIRED_CAPTION = ("Paired against the reference: mean relative margin over the pairs (positive: the reference "
                  "better), (pairs it wins / pairs), then '>' or '<=' the reference's own spread between seeds.")


def metric_directions(names: list[str], registry: Any = None) -> dict[str, bool]:
    """``higher_is_better`` of each name that is a registered metric; other names (figures) are left out."""
    if registry is None:
        from pgc.registry import default_registry

        registry = default_registry()
    known = {impl.name: impl for impl in registry.list("metric")}
    return {n: bool(known[n].check().higher_is_better) for n in names if n in known}


def margin(reference: float, other: float, higher_is_better: bool) -> float | None:
    """The reference's relative margin over ``other`` (positive: the reference is better); None when ``other`` is 0."""
    if other == 0:
        return None
    return ((reference - other) if higher_is_better else (other - reference)) / abs(other)


def _usable(record: dict[str, Any], metric: str) -> float | None:
    v = record.get("metrics", {}).get(metric)
    return float(v) if not record.get("failed") and isinstance(v, (int, float)) and math.isfinite(v) else None


def _seed_spread(refs: list[dict[str, Any]], metric: str) -> tuple[float | None, int]:
    """(mean over seed groups of (max - min) / |mean|, number of groups with two seeds or more)."""
    groups: dict[tuple, list[float]] = {}
    for r in refs:
        v = _usable(r, metric)
        if v is None or r.get("seed") is None:
            continue
        key = tuple(r.get(f) for f in RECORD_FIELDS if f not in SEED_FIELDS)
        groups.setdefault(key, []).append(v)
    spreads = [(max(vs) - min(vs)) / abs(mean) for vs in groups.values()
               if len(vs) > 1 and (mean := statistics.fmean(vs)) != 0]
    return (statistics.fmean(spreads) if spreads else None), len(spreads)


def paired_cells(records: list[dict[str, Any]], table: Table, directions: dict[str, bool]) -> list[dict[str, Any]]:
    """One cell per (other value, column values, metric) with at least one pair; see the module docstring."""
    if not table.reference:
        return []
    (field, reference), = table.reference.items()
    columns = [c for c in dict.fromkeys([*table.rows, *table.columns]) if c != field]
    pair_fields = [f for f in RECORD_FIELDS if f != field]
    rows = selected(records, table)
    refs = {tuple(r.get(f) for f in pair_fields): r for r in rows if r.get(field) == reference}
    others = list(dict.fromkeys(r.get(field) for r in rows if r.get(field) != reference))
    cells = []
    for other in others:
        pairs: dict[tuple, list[tuple[dict, dict]]] = {}
        for r in rows:
            if r.get(field) != other:
                continue
            ref = refs.get(tuple(r.get(f) for f in pair_fields))
            if ref is not None:
                pairs.setdefault(tuple(r.get(c) for c in columns), []).append((ref, r))
        for column, members in pairs.items():
            for metric, higher in directions.items():
                margins = [m for ref, r in members
                           if (a := _usable(ref, metric)) is not None and (b := _usable(r, metric)) is not None
                           and (m := margin(a, b, higher)) is not None]
                if not margins:
                    continue
                spread, groups = _seed_spread([ref for ref, _ in members], metric)
                mean = statistics.fmean(margins)
                cells.append({"reference": reference, "against": other, "field": field,
                              "column": dict(zip(columns, column)), "metric": metric, "margin": mean,
                              "worst": min(margins), "wins": sum(m > 0 for m in margins), "pairs": len(margins),
                              "seed_spread": spread, "seed_groups": groups,
                              "beyond_spread": None if spread is None else mean > spread})
    return cells


def paired_grid(cells: list[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """Header and rows: one row per (other value, column values), one column per metric, cells
    ``+12.3 % (7/8) > 4.0 %`` (mean margin, wins / pairs, the reference's seed spread; ``>`` when beyond it)."""
    if not cells:
        return [], []
    metrics = list(dict.fromkeys(c["metric"] for c in cells))
    keys = list(dict.fromkeys((c["against"], tuple(c["column"].items())) for c in cells))
    by = {(c["against"], tuple(c["column"].items()), c["metric"]): c for c in cells}
    first = cells[0]
    head = [f"{first['reference']} vs {first['field']}", *first["column"], *metrics]
    grid = []
    for against, column in keys:
        row = [str(against), *(str(v) for _, v in column)]
        for m in metrics:
            c = by.get((against, column, m))
            if c is None:
                row.append("-")
                continue
            text = f"{100 * c['margin']:+.1f} % ({c['wins']}/{c['pairs']})"
            if c["seed_spread"] is not None:
                text += f" {'>' if c['beyond_spread'] else '<='} {100 * c['seed_spread']:.1f} %"
            row.append(text)
        grid.append(row)
    return head, grid
