"""``pgc bench``: compare implementations: speed against error."""

from __future__ import annotations

import argparse

from pgc.commands._common import emit, reporter_for


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench", help="compare implementations: speed against error",
        description="Run a matrix of implementations per role (a TOML file; the default covers every installed "
                    "implementation of every role) on a synthetic preset and record, per run, seconds, peak "
                    "memory and errors against ground truth or the role's reference implementation, with speed "
                    "as a ratio to the reference measured in the same run. Writes OUT/bench.json (records), "
                    "OUT/details/ (per-run detail files), OUT/bench.csv, OUT/plots/ROLE.png (speed against "
                    "error) and OUT/bench.html.",
        epilog="presets: tiny (a few minutes on 2 cores), default (larger workloads). Matrix format: docs/bench.md")
    p.add_argument("--preset", default="tiny", choices=("tiny", "default"), help="workload preset (default tiny)")
    p.add_argument("--config", metavar="FILE", help="bench matrix TOML (default: pgc/bench/default_matrix.toml)")
    p.add_argument("--role", nargs="+", metavar="ROLE", help="run only these roles of the matrix")
    p.add_argument("--out", default=None, help="output folder (default runs/bench-PRESET)")
    p.add_argument("--scheduler", metavar="local:N | tcp://HOST:PORT",
                   help="run each role as a task on Dask distributed: a local cluster of N worker processes, or "
                        "an existing scheduler's address (default: in this process)")
    p.add_argument("--threads", type=int, metavar="N", help="threads per worker task (default: cores / workers)")
    p.add_argument("--report", metavar="DIR", help="only re-render the plots, CSV and HTML from DIR/bench.json")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the records as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pgc.bench import records as rec
    from pgc.bench.report import text_tables, write_report
    from pgc.bench.runner import run_bench
    from pgc.checks import naming_output

    if args.report:
        out = Path(args.report)
        records = rec.read_json(out / "bench.json")
        with naming_output(out):
            rec.write_csv(out / "bench.csv", records)
            write_report(out, records)
    else:
        out = Path(args.out or f"runs/bench-{args.preset}")
        registry, reporter = reporter_for(args)
        with naming_output(out):
            records = run_bench(out, args.preset, args.config, args.role, registry=registry, reporter=reporter,
                                scheduler=args.scheduler, threads=args.threads)
    emit(args, records, text_tables(records) + f"\nrecords: {out}/bench.json  report: {out}/bench.html")
    return 0
