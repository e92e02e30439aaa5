"""Run a sweep file: validate, plan the tasks still to do, run them, gather the records and write the table."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from pgc.events import Reporter
from pgc.sweep.engine import Outcome, run_tasks
from pgc.sweep.spec import SCENE_RECORD_FIELDS, Sweep, load_sweep
from pgc.sweep.work import Unit, plan

NOT_RUN = "not run (pgc sweep --collect)"
"""What a task not yet finished is marked with when a sweep's outputs are collected without running it."""


def records_of(sweep: Sweep, units: list[Unit], results: dict[str, Any], failed: dict[str, str]) -> list[dict]:
    """One record per unit, evaluation mode, light and variant (per unit when the sweep has no 'eval'); a unit
    whose asset or run task failed gives one record with ``failed`` and no metrics, a failed mode task one such
    record for its mode."""
    out = []
    for u in units:
        s = u.scene.synth or {}
        base = {"sweep": sweep.name, "scene": u.scene.name, "configuration": u.configuration.name, "motion": u.motion,
                "light": None, "mode": None, "variant": None, **{k: s.get(k) for k in SCENE_RECORD_FIELDS},
                "capture": u.capture}
        bad = next((failed[k] for k in (u.asset_task, u.run_task) if k in failed), None)
        if bad is not None:
            out.append(base | {"metrics": {}, "figures": {}, "seconds": {}, "failed": bad})
            continue
        asset = results[u.asset_task]
        run = results.get(u.run_task) if u.run_task else None
        base |= {"brdf": asset["brdf"], "figures": asset["figures"], "asset": asset["asset"],
                 "run": run["run"] if run else None,
                 "seconds": {"reconstruct": asset["seconds"], **(run["seconds"] if run else {})}}
        if not u.mode_tasks or not (run and run["metrics"]):
            out.append(base | {"metrics": dict(asset["figures"])})
            continue
        for mode, task in u.mode_tasks.items():
            if task in failed:
                out.append(base | {"mode": mode, "metrics": {}, "failed": failed[task]})
                continue
            done = results[task]
            seconds = base["seconds"] | (done["seconds"] if task != u.run_task else {})
            out += [base | {"light": light, "mode": mode, "variant": v, "metrics": m, "seconds": seconds}
                    for light, per_variant in done["metrics"].items() for v, m in per_variant.items()]
    return out


def run_sweep(path: str | os.PathLike, out: str | os.PathLike | None = None, scheduler: str | None = None,
              reporter: Reporter | None = None, registry: Any = None, retries: int = 2,
              threads: int | None = None, collect: bool = False) -> dict[str, Any]:
    """Run the sweep file ``path`` into ``out`` (default ``runs/sweep-NAME``); returns ``{"records", "failed",
    "computed", "out", "table", "paired"}`` (``computed``: how many tasks ran now; 0 on a rerun of a finished
    sweep; ``table``: the file's :class:`~pgc.sweep.spec.Table`; ``paired``: the cells of :mod:`pgc.sweep.paired`).
    ``collect``: run nothing, build the outputs from the tasks finished so far (the others are listed in
    ``failed`` as :data:`NOT_RUN`)."""
    from pgc.checks import naming_output
    from pgc.io.lock import FolderLock
    from pgc.sweep.paired import metric_directions, paired_cells
    from pgc.sweep.table import metric_names, write_outputs

    sweep = load_sweep(path, registry)
    out = Path(out or f"runs/sweep-{sweep.name}")
    with FolderLock(out, "pgc sweep"), naming_output(out):
        tasks, units, done = plan(sweep, out, need_folders=not collect)
        if collect:
            outcome = Outcome(failed={t.key: NOT_RUN for t in tasks})
        else:
            outcome = run_tasks(tasks, scheduler, reporter, retries=retries, threads=threads, name="sweep")
        results = done | outcome.results
        records = records_of(sweep, units, results, outcome.failed)
        directions = metric_directions(metric_names(records, sweep.table), registry) if sweep.table.reference else {}
        paired = paired_cells(records, sweep.table, directions)
        write_outputs(out, sweep.name, records, sweep.table, outcome.failed, paired)
    return {"records": records, "failed": outcome.failed, "computed": len(outcome.results), "out": str(out),
            "table": sweep.table, "paired": paired}
