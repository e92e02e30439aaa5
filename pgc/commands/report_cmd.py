"""``pgc report``: the HTML report of a demo folder or a rendered run."""

from __future__ import annotations

import argparse

from pgc.commands._common import emit

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


def run(args: argparse.Namespace) -> int:
    from pgc.pipeline.report import report_folder

    result = report_folder(args.folder, args.bench)
    emit(args, result, f"report: {result['path']} ({result['files']} files, {result['bytes'] / 1024:.0f} KiB)")
    return 0
