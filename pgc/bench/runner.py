"""Run a bench matrix and write bench.json, the per-run detail files, bench.csv, plots and bench.html."""

from __future__ import annotations

import importlib
import os
import time
from pathlib import Path
from typing import Any

from pgc.bench import records as rec
from pgc.bench.matrix import WORKLOADS, RolePlan, load_matrix
from pgc.bench.measure import versions
from pgc.bench.workloads import Context
from pgc.events import Reporter

DETAILS = "details"


def synthetic_capture(out: Path, preset: str, registry: Any, reporter: Reporter) -> str:
    """The synthetic capture of ``preset`` in ``out/capture-PRESET``, rendered by the default configuration's scene
    renderer (generated once per preset and renderer: :func:`pgc.pipeline.demo.synthetic_capture`). Workers of a
    distributed bench wait on a lock file while one of them generates it."""
    import fcntl

    from pgc.config import resolve
    from pgc.pipeline.demo import synthetic_capture as generate_once

    root = out / f"capture-{preset}"
    out.mkdir(parents=True, exist_ok=True)
    with open(out / f".capture-{preset}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        generate_once(root, preset, 0, resolve(None, registry, require_available=False), reporter)
    return str(root)


def bench_role(out: Path, preset: str, plan: RolePlan, registry: Any, reporter: Reporter) -> list[dict[str, Any]]:
    """The records of one role of the matrix (a failed workload gives one record saying why)."""
    capture: list[str] = []

    def capture_dir() -> str:
        if not capture:
            capture.append(synthetic_capture(out, preset, registry, reporter))
        return capture[0]

    module = importlib.import_module(WORKLOADS[plan.role])
    with reporter.stage(f"bench_{plan.role}", runs=len(plan.runs)) as stage:
        start = time.perf_counter()
        ctx = Context(plan.role, preset, plan.workload, plan.runs, registry, versions(), capture_dir, stage)
        try:
            new = module.bench(ctx)
        except Exception as exc:  # the workload itself (scene, reference) failed: one record says why
            new = [ctx.failed("(workload)", "", {}, exc, "")]
        stage.record(records=len(new), seconds=time.perf_counter() - start)
    if plan.workload.get("options"):
        for r in new:  # the preset's options for every implementation, recorded with each run
            r["settings"]["preset_options"] = plan.workload["options"]
    return new


def bench_role_task(out: str, preset: str, matrix: str | None, role: str) -> list[dict[str, Any]]:
    """:func:`bench_role` on a worker: the role's plan from the matrix with the worker's installed registry."""
    from pgc.registry import default_registry

    registry = default_registry()
    plan = load_matrix(matrix, registry, preset, [role])[0]
    return bench_role(Path(out), preset, plan, registry, Reporter.silent())


def run_bench(out: str | os.PathLike, preset: str = "tiny", matrix: str | os.PathLike | None = None,
              roles: list[str] | None = None, registry: Any = None, reporter: Reporter | None = None,
              scheduler: str | None = None, threads: int | None = None) -> list[dict[str, Any]]:
    """Run the matrix (default: the shipped one) on ``preset`` for ``roles`` (default: all in the matrix),
    write everything into ``out`` and return the records. Invalid matrices fail before any work starts.
    With ``scheduler`` (``local:N`` or a Dask scheduler address, :mod:`pgc.sweep.engine`) each role is one
    task on Dask distributed, run with the workers' installed plugins; the records are merged in matrix
    order into the same outputs."""
    from pgc.registry import default_registry

    registry = registry or default_registry()
    reporter = reporter or Reporter.silent()
    out = Path(out)
    plans = load_matrix(matrix, registry, preset, roles)
    out.mkdir(parents=True, exist_ok=True)
    records: list[dict[str, Any]] = []
    if scheduler is None:
        for plan in plans:
            records += bench_role(out, preset, plan, registry, reporter)
            write_outputs(out, records)  # after every role: an interrupted run keeps what it measured
        return records
    from pgc.sweep.engine import Task, run_tasks

    where = None if matrix is None else str(Path(matrix).resolve())
    tasks = [Task(f"bench-{p.role}", bench_role_task, (str(out.resolve()), preset, where, p.role)) for p in plans]
    outcome = run_tasks(tasks, scheduler, reporter, threads=threads, name="bench")
    for plan, task in zip(plans, tasks):
        if task.key in outcome.results:
            records += outcome.results[task.key]
        else:
            records.append(failed_task_record(plan.role, preset, outcome.failed[task.key]))
    write_outputs(out, records)
    return records


def failed_task_record(role: str, preset: str, message: str) -> dict[str, Any]:
    """The record of a role whose task failed on the cluster (its retries spent)."""
    r = rec.make_record(role, "(workload)", preset, "", {}, float("nan"), float("nan"), {}, "", versions())
    r["failed"] = message
    r["label"] = "(workload)"
    return r


def write_outputs(out: Path, records: list[dict[str, Any]]) -> None:
    """A detail file per run (the record's settings and errors with its per-view/per-frame data, moved out of
    the record), ratios, bench.json, bench.csv, plots and bench.html."""
    from pgc.bench.report import write_report
    from pgc.io.atomic import write_json

    details = out / DETAILS
    details.mkdir(exist_ok=True)
    for i, r in enumerate(records):
        if r.get("detail") is not None:  # written by an earlier call (one call per finished role)
            continue
        name = f"{i:03d}-{r['role']}-{r['implementation']}.json".replace("/", "_").replace(" ", "_")
        write_json(details / name, {"role": r["role"], "implementation": r["implementation"], "label": r.get("label"),
                                    "settings": r["settings"], "errors": r["errors"], **r.pop("_detail", {})})
        r["detail"] = f"{DETAILS}/{name}"
    rec.add_reference_ratios(records)
    rec.validate(records)
    rec.write_json(out / "bench.json", records)
    rec.write_csv(out / "bench.csv", records)
    write_report(out, records)
