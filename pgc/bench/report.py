"""Tables, speed-against-error plots and the HTML page, made from benchmark records only."""

from __future__ import annotations

import html
import math
import os
from pathlib import Path
from typing import Any

from pgc.bench.records import finite

PLOTS = "plots"


def by_role(records: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        out.setdefault(r["role"], []).append(r)
    return out


def label(r: dict[str, Any]) -> str:
    return r.get("label") or r["implementation"]


def _fmt(x: Any, digits: int = 3) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        if not math.isfinite(x):
            return str(x)
        return f"{x:.{digits}g}"
    return str(x)


def table_rows(records: list[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of one role: label, case, seconds, x reference, peak MB, every error key, and a
    ``failed`` column (the message) when a run failed."""
    keys: list[str] = []
    for r in records:
        for k in ([r["error_key"]] if r.get("error_key") else []) + list(r["errors"]):
            if k not in keys:
                keys.append(k)
    any_failed = any(r.get("failed") for r in records)
    head = ["implementation", "case", "seconds", "x reference", "peak MB", *keys] + (["failed"] if any_failed else [])
    rows = []
    for r in records:
        ref = " (reference)" if r["settings"].get("reference") else ""
        row = [label(r) + ref, str(r["settings"].get("case", "")), _fmt(r["seconds"]), _fmt(r.get("x_reference")),
               _fmt(r["peak_mb"]), *(_fmt(r["errors"].get(k)) for k in keys)]
        if r.get("failed"):
            row[2:] = ["failed"] + ["-"] * (len(row) - 3)
        rows.append(row + ([r.get("failed") or ""] if any_failed else []))
    return head, rows


def text_tables(records: list[dict[str, Any]]) -> str:
    """Plain-text tables, one per role (what ``pgc bench`` prints)."""
    out = []
    for role, rs in by_role(records).items():
        head, rows = table_rows(rs)
        widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]
        out.append(f"== {role} (error plotted: {rs[0].get('error_key')}; x reference = seconds / reference seconds)")
        out.append("  ".join(h.ljust(w) for h, w in zip(head, widths)))
        out += ["  ".join(c.ljust(w) for c, w in zip(row, widths)) for row in rows]
        out.append("")
    return "\n".join(out)


def plot_role(path: Path, role: str, records: list[dict[str, Any]]) -> bool:
    """Speed against error of one role: x = seconds (log), y = the records' ``error_key`` (log when it spans
    more than a decade; exact zeros are drawn at the bottom with an open marker); failed runs are named
    under the plot. Drawn when the role has two or more implementations and a point to plot; else False."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = [r for r in records if not r.get("failed") and r.get("error_key") and finite(r["seconds"])
           and finite(r["errors"].get(r["error_key"]))]
    if len({r["implementation"] for r in records}) < 2 or not pts:
        return False
    ys = [r["errors"][r["error_key"]] for r in pts]
    positive = [y for y in ys if y > 0]
    log_y = bool(positive) and min(ys) >= 0 and max(positive) / min(positive) > 10
    floor = min(positive) / 10 if log_y else 0.0
    impls = sorted({r["implementation"] for r in pts})
    cases = sorted({str(r["settings"].get("case", "")) for r in pts})
    markers = "osD^vP*Xh<>"
    cmap = plt.get_cmap("tab10")
    fig, ax = plt.subplots(figsize=(7.5, 5.0), dpi=110)
    for r, y in zip(pts, ys):
        colour = cmap(impls.index(r["implementation"]) % 10)
        marker = markers[cases.index(str(r["settings"].get("case", ""))) % len(markers)]
        exact = log_y and y <= 0
        ax.scatter([max(r["seconds"], 1e-9)], [floor if exact else y], color=colour, marker=marker, s=46,
                   facecolors="none" if exact else colour, edgecolors="k" if r["settings"].get("reference") else colour,
                   linewidths=1.6 if r["settings"].get("reference") else 1.0, zorder=3)
        ax.annotate(label(r) + (" (ref)" if r["settings"].get("reference") else ""), (r["seconds"], floor if exact else y),
                    fontsize=6.5, xytext=(4, 3), textcoords="offset points")
    ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    for i, c in enumerate(cases):
        ax.scatter([], [], color="grey", marker=markers[i % len(markers)], label=c)
    ax.legend(fontsize=7, title="case", title_fontsize=7, loc="best")
    units = {r["error_key"] for r in pts}
    ax.set_xlabel("seconds (log)")
    ax.set_ylabel(", ".join(sorted(units)) + (" (log; open marker = 0)" if log_y else "") + "  (lower is better)")
    preset = ", ".join(sorted({r["preset"] for r in pts}))
    ax.set_title(f"{role}: speed against error ({preset})", fontsize=10)
    failed = sorted({label(r) for r in records if r.get("failed")})
    if failed:
        fig.text(0.01, 0.01, "failed (see the table): " + ", ".join(failed), fontsize=7, color="#a00")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return True


def write_report(out: str | os.PathLike, records: list[dict[str, Any]]) -> dict[str, Path]:
    """Write ``out/plots/ROLE.png`` (roles with >= 2 plotted implementations) and ``out/bench.html``;
    returns the plot paths by role."""
    from pgc.io.atomic import write_text

    out = Path(out)
    plots: dict[str, Path] = {}
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>pgc bench</title><style>"
             "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;font-size:12px}"
             "td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}td:first-child,td:nth-child(2)"
             "{text-align:left}th{background:#eee}.fail{color:#a00}</style></head><body>",
             "<h1>pgc bench: speed against error</h1>",
             "<p>One record per run (bench.json, bench.csv). <i>x reference</i> = seconds / seconds of the role's "
             "reference run in the same case and the same run (the machine is shared: ratios, not seconds, are "
             "comparable). peak MB: peak resident memory above the level at the start of the run.</p>"]
    for role, rs in by_role(records).items():
        path = out / PLOTS / f"{role}.png"
        if plot_role(path, role, rs):
            plots[role] = path
        head, rows = table_rows(rs)
        parts.append(f"<h2>{html.escape(role)}</h2><p>error plotted: <code>{html.escape(str(rs[0].get('error_key')))}"
                     f"</code> (lower is better)</p><table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head)
                     + "</tr>")
        for r, row in zip(rs, rows):
            cls = " class='fail'" if r.get("failed") else ""
            parts.append(f"<tr{cls}>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>")
        parts.append("</table>")
        if role in plots:
            parts.append(f"<p><img src='{PLOTS}/{role}.png' alt='{html.escape(role)} speed against error'></p>")
    versions = next((r["versions"] for r in records), {})
    parts.append("<h2>versions</h2><p>" + html.escape(", ".join(f"{k} {v}" for k, v in versions.items())) + "</p>")
    parts.append("</body></html>\n")
    write_text(out / "bench.html", "\n".join(parts))
    return plots
