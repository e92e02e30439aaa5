"""``pgc report``: the HTML report of a demo folder or a rendered run."""

from __future__ import annotations

import argparse
from pathlib import Path

from pgc.checks import naming_output
from pgc.commands._common import check_out_folder, emit, read_json_object
from pgc.errors import PGCDataError
from pgc.io.limits import read_json

EPILOG = """\
examples:
  pgc report runs/demo-default                 rebuild the demo's report.html
  pgc report runs/demo-default/runs/spooky     the report of one rendered (and evaluated) run
  pgc report runs/demo-default --bench runs/bench-tiny   add speed-against-error charts from pgc bench

Open FOLDER/report.html in a browser: it links only to FOLDER/report/ and needs no network.
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report", help="write the HTML report of a demo folder or a run",
        description="Write FOLDER/report.html and its pictures in FOLDER/report/: per motion, ground truth | "
                    "3DGS-only | PBR-only | hybrid cropped to the garment and enlarged, error heatmaps, the "
                    "hybrid's decomposition l(S) and h(G), a looping animation (animated WebP) of ground truth and "
                    "hybrid, the relighting strip of a run rendered with --rotate-light, and charts of metrics, "
                    "timings and (with --bench) speed against error.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("folder", help="demo output folder (pgc demo --out) or run folder (pgc animate + pgc render)")
    p.add_argument("--bench", metavar="DIR", help="a pgc bench output folder (or its bench.json) to chart")
    p.add_argument("--json", action="store_true", help="print the report's path and size as JSON")
    p.set_defaults(func=run)


def check_inputs(folder: Path, bench: str | None) -> None:
    """What the report reads (run.json and metrics.json of each run, the demo's metrics.json, the bench
    records) and where it writes (FOLDER/report.html, FOLDER/report/), before any picture is made."""
    if not folder.is_dir():
        raise PGCDataError(f"{folder}: not a folder; give a demo output folder (pgc demo --out) or a run folder "
                           "(pgc animate, then pgc render)")
    runs = [folder] if (folder / "run.json").is_file() else sorted(
        p for p in (folder / "runs").glob("*") if (p / "render" / "render.json").is_file())
    if folder not in runs:
        _object(folder / "metrics.json", "rerun 'pgc demo' into this folder", optional=True)
    for run in runs:
        _object(run / "run.json", f"re-create the run with 'pgc animate ... --out {run}'")
        _object(run / "metrics.json", f"evaluate the run again with 'pgc eval {run} --gt CAPTURE'", optional=True)
    if bench is not None:
        path = Path(bench) / "bench.json" if Path(bench).is_dir() else Path(bench)
        data = read_json(path, "bench.json", fix="make one with 'pgc bench --out DIR' and pass that DIR")
        if not isinstance(data.get("records") if isinstance(data, dict) else data, list):
            raise PGCDataError(f"{path}: expected a list of bench records (or an object with 'records'); rerun "
                               "'pgc bench'")
    check_out_folder(folder, option="FOLDER")
    if (folder / "report").exists() and not (folder / "report").is_dir():
        raise PGCDataError(f"{folder / 'report'}: is a file, but the report's pictures go into this folder; move "
                           "the file away")
    if (folder / "report.html").is_dir():
        raise PGCDataError(f"{folder / 'report.html'}: is a folder, but the report is written to this path; move "
                           "the folder away")


def _object(path: Path, fix: str, optional: bool = False) -> None:
    """``path`` holds a JSON object (``optional``: or is absent), else a clear error naming it and ``fix``."""
    if optional and not path.exists():
        return
    read_json_object(path, fix)


def run(args: argparse.Namespace) -> int:
    from pgc.pipeline.report import report_folder

    check_inputs(Path(args.folder), args.bench)
    with naming_output(args.folder):
        result = report_folder(args.folder, args.bench)
    emit(args, result, f"report: {result['path']} ({result['files']} files, {result['bytes'] / 1024:.0f} KiB)")
    return 0
