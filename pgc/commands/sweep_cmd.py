"""``pgc sweep``: scenes x configurations x steps, in-process or on a Dask cluster, into one table."""

from __future__ import annotations

import argparse

from pgc.commands._common import check_out_folder, emit, reporter_for


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep", help="scenes x configurations on a Dask cluster (or here), gathered into one table",
        description="Run a sweep file: every (scene, configuration) becomes tasks (reconstruct; animate, render "
                    "and eval per motion). Configurations that differ only downstream share the upstream work. "
                    "Writes OUT/sweep.json (records), OUT/sweep.csv, OUT/plots/ and OUT/sweep.html, and with a "
                    "[table] reference the paired table (OUT/paired.json: the reference against each other value, "
                    "record by record). A rerun resumes from OUT/results/ and the stage caches.",
        epilog="format and shipped sweeps: docs/sweeps.md (examples/sweeps/*.toml)")
    p.add_argument("sweep", metavar="SWEEP.toml", help="the sweep file")
    p.add_argument("--scheduler", metavar="local:N | tcp://HOST:PORT",
                   help="run on Dask distributed: a local cluster of N worker processes, or an existing "
                        "scheduler's address (default: in this process)")
    p.add_argument("--threads", type=int, metavar="N", help="threads per worker task (default: cores / workers)")
    p.add_argument("--retries", type=int, default=2, help="retries of a failed task (default 2)")
    p.add_argument("--out", default=None, help="output folder (default runs/sweep-NAME)")
    p.add_argument("--collect", action="store_true",
                   help="run nothing: write the table and records of the tasks finished so far (e.g. of an "
                        "interrupted sweep); the unfinished ones are listed as not run")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the records as JSON")
    p.set_defaults(func=run)


def check_options(args: argparse.Namespace) -> None:
    """The command-line options, before the sweep file is read."""
    from pgc.errors import PGCConfigError
    from pgc.sweep.engine import parse_scheduler

    if args.scheduler is not None:
        parse_scheduler(args.scheduler)
    if args.retries < 0:
        raise PGCConfigError(f"--retries {args.retries}: give 0 or more retries of a failed task")
    if args.threads is not None and args.threads < 1:
        raise PGCConfigError(f"--threads {args.threads}: give 1 or more threads per task (or leave it out)")
    if args.out is not None:
        check_out_folder(args.out)


def run(args: argparse.Namespace) -> int:
    from pgc.sweep.runner import NOT_RUN, run_sweep
    from pgc.sweep.table import text_table

    check_options(args)
    registry, reporter = reporter_for(args)
    result = run_sweep(args.sweep, args.out, args.scheduler, reporter, registry, args.retries, args.threads,
                       args.collect)
    failed = "".join(f"\nfailed: {k}: {v}" for k, v in result["failed"].items() if v != NOT_RUN)
    not_run = sum(v == NOT_RUN for v in result["failed"].values())
    failed += f"\nnot run: {not_run} tasks (run the sweep again to compute them)" if not_run else ""
    emit(args, result["records"], text_table(result["records"], result["table"], result["paired"])
         + f"\ntasks run: {result['computed']}  records: {result['out']}/sweep.json  page: {result['out']}/sweep.html"
         + failed)
    return 1 if any(v != NOT_RUN for v in result["failed"].values()) else 0
