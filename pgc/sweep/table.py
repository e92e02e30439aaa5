"""Sweep records -> the table (mean and spread per cell), JSON, CSV and an HTML page with plots.

A record is one (scene, configuration, motion, variant) after ``eval``, or one (scene, configuration) when the
sweep stops earlier::

    {"sweep", "scene", "configuration", "motion", "variant", "preset", "garment", "fabric", "seed", "framing",
     "detail", "fit", "looseness", "capture", "brdf", "metrics": {name: value}, "figures": {...},
     "seconds": {step: s}, "asset", "run"}

``seconds`` are the wall-clock seconds of the tasks that computed the record's asset and run (shared work
appears in every record that uses it; a folder seeded from another configuration's caches took only the
stages it recomputed). Table cells are the mean over the records of the cell, ``± std`` (sample standard
deviation) when there are several.
"""

from __future__ import annotations

import csv
import html
import math
import statistics
from pathlib import Path
from typing import Any

from pgc.sweep.paired import PAIRED_CAPTION, paired_grid
from pgc.sweep.spec import RECORD_FIELDS, Table, selected

PLOTS = "plots"


def metric_names(records: list[dict[str, Any]], table: Table) -> list[str]:
    if table.metrics:
        return list(table.metrics)
    return list(dict.fromkeys(k for r in records for k in r["metrics"]))


def cells(records: list[dict[str, Any]], table: Table) -> tuple[list[tuple], list[tuple], dict]:
    """(row labels, column labels, {(row, column, metric): [values]}) in first-seen order, over the records that
    did not fail."""
    rows, cols, values = [], [], {}
    for r in selected(records, table):
        if r.get("failed"):  # no metrics: listed with the failed tasks, not as an empty row
            continue
        row = tuple(r.get(k) for k in table.rows)
        col = tuple(r.get(k) for k in table.columns)
        rows += [row] if row not in rows else []
        cols += [col] if col not in cols else []
        for m, v in r["metrics"].items():
            if isinstance(v, (int, float)) and math.isfinite(v):
                values.setdefault((row, col, m), []).append(float(v))
    return rows, cols, values


def _cell(vs: list[float] | None) -> str:
    if not vs:
        return "-"
    mean = statistics.fmean(vs)
    return f"{mean:.4g}" + (f" ± {statistics.stdev(vs):.2g}" if len(vs) > 1 else "")


def table_grid(records: list[dict[str, Any]], table: Table) -> tuple[list[str], list[list[str]]]:
    """Header and rows: the row fields, then one column per (column value, metric)."""
    rows, cols, values = cells(records, table)
    metrics = metric_names(records, table)
    head = list(table.rows) + [("/".join(str(c) for c in col) + " " if col else "") + m for col in cols
                               for m in metrics]
    grid = [[str(x) for x in row] + [_cell(values.get((row, col, m))) for col in cols for m in metrics]
            for row in rows]
    return head, grid


def aligned(head: list[str], grid: list[list[str]]) -> str:
    """A header and rows as plain-text columns."""
    widths = [max(len(h), *(len(g[i]) for g in grid)) for i, h in enumerate(head)]
    return "\n".join(["  ".join(h.ljust(w) for h, w in zip(head, widths))]
                     + ["  ".join(c.ljust(w) for c, w in zip(g, widths)) for g in grid])


def text_table(records: list[dict[str, Any]], table: Table, paired: list[dict[str, Any]] | None = None) -> str:
    """The table, then the paired comparison (:mod:`pgc.sweep.paired`) when there is one."""
    head, grid = table_grid(records, table)
    if not grid:
        return "(no records)"
    text = aligned(head, grid)
    head, grid = paired_grid(paired or [])
    return text + (f"\n\n{PAIRED_CAPTION}\n" + aligned(head, grid) if grid else "")


def write_csv(path: Path, records: list[dict[str, Any]]) -> None:
    """One row per record: the fields, ``metric.<name>`` and ``seconds.<step>`` columns."""
    from pgc.io.atomic import atomic_open

    metrics = sorted({k for r in records for k in r["metrics"]})
    steps = sorted({k for r in records for k in r["seconds"]})
    with atomic_open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*RECORD_FIELDS, "brdf", *(f"metric.{m}" for m in metrics), *(f"seconds.{s}" for s in steps),
                    "asset", "run", "failed"])
        for r in records:
            w.writerow([("" if r.get(k) is None else r[k]) for k in RECORD_FIELDS] + [r.get("brdf") or ""]
                       + [repr(r["metrics"][m]) if m in r["metrics"] else "" for m in metrics]
                       + [repr(r["seconds"][s]) if s in r["seconds"] else "" for s in steps]
                       + [r.get("asset") or "", r.get("run") or "", r.get("failed") or ""])


def _plots(out: Path, records: list[dict[str, Any]], table: Table) -> list[str]:
    """``plots/metric-M.png`` (M per table row, one bar group per column value) and ``plots/speed-error.png``
    (total seconds of a configuration against its mean first metric); returns the file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, cols, values = cells(records, table)
    names = []
    (out / PLOTS).mkdir(parents=True, exist_ok=True)
    for m in metric_names(records, table):
        if not any((row, col, m) in values for row in rows for col in cols):
            continue
        fig, ax = plt.subplots(figsize=(max(5.0, 0.9 * len(rows) * max(len(cols), 1)), 3.6), dpi=110)
        width = 0.8 / max(len(cols), 1)
        for j, col in enumerate(cols):
            vs = [values.get((row, col, m), []) for row in rows]
            ax.bar([i + j * width for i in range(len(rows))], [statistics.fmean(v) if v else 0.0 for v in vs],
                   width, yerr=[statistics.stdev(v) if len(v) > 1 else 0.0 for v in vs],
                   label="/".join(str(c) for c in col) or None, capsize=3)
        ax.set_xticks([i + 0.4 - width / 2 for i in range(len(rows))],
                      ["/".join(str(x) for x in row) for row in rows], fontsize=7, rotation=15)
        ax.set_ylabel(m)
        ax.set_title(f"{m} per {'/'.join(table.rows)} (mean ± std)", fontsize=9)
        if any(cols[0]):
            ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / PLOTS / f"metric-{m}.png")
        plt.close(fig)
        names.append(f"metric-{m}.png")
    first = next(iter(metric_names(records, table)), None)
    by_conf: dict[str, tuple[list[float], list[float]]] = {}
    for r in selected(records, table):
        if first in r["metrics"] and math.isfinite(r["metrics"][first]):
            s, e = by_conf.setdefault(r["configuration"], ([], []))
            s.append(sum(r["seconds"].values()))
            e.append(r["metrics"][first])
    if by_conf:
        fig, ax = plt.subplots(figsize=(5.5, 4.0), dpi=110)
        for conf, (s, e) in by_conf.items():
            ax.errorbar([statistics.fmean(s)], [statistics.fmean(e)], yerr=[statistics.stdev(e) if len(e) > 1 else 0],
                        fmt="o", capsize=3, label=conf)
            ax.annotate(conf, (statistics.fmean(s), statistics.fmean(e)), fontsize=7, xytext=(4, 3),
                        textcoords="offset points")
        ax.set_xlabel("seconds per record (tasks that computed its asset and run)")
        ax.set_ylabel(first)
        ax.set_title(f"speed against {first} per configuration", fontsize=9)
        ax.grid(True, alpha=0.3)
        fig.tight_layout()
        fig.savefig(out / PLOTS / "speed-error.png")
        plt.close(fig)
        names.append("speed-error.png")
    return names


def _html_table(head: list[str], grid: list[list[str]]) -> str:
    """A header and rows as an HTML table, escaped."""
    return ("<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"
            + "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in g) + "</tr>" for g in grid)
            + "</table>")


def write_outputs(out: Path, name: str, records: list[dict[str, Any]], table: Table,
                  failed: dict[str, str], paired: list[dict[str, Any]] | None = None) -> None:
    """``sweep.json`` (records), ``sweep.csv``, ``plots/*.png``, ``sweep.html`` and, with a ``[table] reference``,
    ``paired.json`` (the cells of :mod:`pgc.sweep.paired`)."""
    from pgc.io.atomic import finite_or_none, write_json, write_text

    write_json(out / "sweep.json", finite_or_none(records))
    if table.reference:
        write_json(out / "paired.json", finite_or_none(paired or []))
    write_csv(out / "sweep.csv", records)
    plots = _plots(out, records, table)
    head, grid = table_grid(records, table)
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>pgc sweep</title><style>"
             "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;font-size:12px}"
             "td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#eee}"
             ".fail{color:#a00}</style></head><body>", f"<h1>pgc sweep: {html.escape(name)}</h1>",
             f"<p>{len(records)} records (sweep.json, sweep.csv). Cells: mean ± sample standard deviation over the "
             "records of the cell.</p>", _html_table(head, grid)]
    paired_head, paired_rows = paired_grid(paired or [])
    if paired_rows:
        parts += [f"<h2>Paired</h2><p>{html.escape(PAIRED_CAPTION)} (paired.json)</p>",
                  _html_table(paired_head, paired_rows)]
    parts += [f"<p><img src='{PLOTS}/{p}' alt='{html.escape(p)}'></p>" for p in plots]
    if failed:
        parts.append("<h2 class='fail'>failed tasks</h2><ul>" + "".join(
            f"<li class='fail'>{html.escape(k)}: {html.escape(v)}</li>" for k, v in failed.items()) + "</ul>")
    parts.append("</body></html>\n")
    write_text(out / "sweep.html", "\n".join(parts))
