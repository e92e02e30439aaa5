"""Run a graph of tasks in this process or on Dask distributed, with progress, retries and pinned threads.

A task is ``Task(key, fn, args, deps)``: ``fn(*args, *results_of_deps)`` returns a JSON-serialisable value.
Without a scheduler the tasks run here in dependency order (as every other command runs). With one,
``"local:N"`` starts a :class:`distributed.LocalCluster` of N worker processes (one task at a time each,
``cores // N`` threads for its libraries) and ``"tcp://HOST:PORT"`` (or any address Dask accepts) uses an
existing cluster; the engine submits the ready tasks of highest priority, one per free worker thread, so
priorities hold on a cluster as they do here. Each task is submitted with ``retries``; a worker that dies
(killed, out of memory) loses only the tasks it was running, which the scheduler runs again elsewhere (Dask's
``allowed-failures``).
A task whose retries are spent is reported as failed, and the tasks that need it are not run.

Thread pinning: every worker sets ``OMP_NUM_THREADS`` (and MKL/OpenBLAS), ``XLA_FLAGS
= --xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=N`` and ``torch.set_num_threads(N)`` to its
allotment N before it runs a task (:func:`pin_threads`), so N workers on one host never oversubscribe it.
Dask is imported only when a scheduler is given.
"""

from __future__ import annotations

import os
import sys
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable

from pgc.cores import given_threads, usable_cores
from pgc.errors import PGCConfigError
from pgc.events import Reporter

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


@dataclass
class Task:
    key: str
    """Unique name of the task (also its Dask key)."""
    fn: Callable[..., Any]
    args: tuple = ()
    deps: tuple[str, ...] = ()
    """Keys of the tasks whose results are appended to ``args``."""
    priority: int = 0
    """Among tasks ready to run, those of higher priority run first (ties: in the order given)."""


@dataclass
class Outcome:
    results: dict[str, Any] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    """Task key -> the error (its own, or 'needs failed task K')."""


def thread_environment(threads: int) -> dict[str, str]:
    """The environment variables that pin OpenMP/BLAS and XLA's CPU client to ``threads`` threads."""
    env = {name: str(threads) for name in THREAD_VARIABLES}
    flags = os.environ.get("XLA_FLAGS", "").split()
    flags = [f for f in flags if not f.startswith(("--xla_cpu_multi_thread_eigen", "intra_op_parallelism_threads"))]
    env["XLA_FLAGS"] = " ".join(flags + ["--xla_cpu_multi_thread_eigen=false",
                                         f"intra_op_parallelism_threads={threads}"])
    return env


def pin_threads(threads: int) -> None:
    """Pin this process's compute threads to ``threads``: the environment (read when torch, JAX or a BLAS load)
    and torch's intra-op pool when torch is already loaded."""
    os.environ.update(thread_environment(threads))
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)


def parse_scheduler(text: str) -> tuple[str, int | str]:
    """``("local", N)`` for ``local:N``, else ``("address", text)``; a clear error for anything else."""
    if text.startswith("local:"):
        n = text[len("local:"):]
        if not n.isdigit() or int(n) < 1:
            raise PGCConfigError(f"--scheduler {text}: expected local:N with N >= 1 worker processes")
        return "local", int(n)
    if "://" not in text:
        raise PGCConfigError(f"--scheduler {text}: give local:N (a local cluster of N worker processes) or a "
                             "scheduler address such as tcp://HOST:8786")
    return "address", text


def run_tasks(tasks: list[Task], scheduler: str | None = None, reporter: Reporter | None = None,
              retries: int = 2, threads: int | None = None, name: str = "tasks") -> Outcome:
    """Run ``tasks`` (see the module docstring); progress is the stage ``name`` with done / running / failed.
    ``threads``: each worker's allotment (default: the host's cores // workers for ``local:N``; on an existing
    cluster, :func:`worker_allotment`)."""
    reporter = reporter or Reporter.silent()
    keys = {t.key for t in tasks}
    for t in tasks:
        missing = [d for d in t.deps if d not in keys]
        if missing:
            raise ValueError(f"task {t.key} needs unknown tasks {missing}")
    if scheduler is None:
        return _run_here(tasks, reporter, name)
    return _run_dask(tasks, scheduler, reporter, retries, threads, name)


def _describe(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


def _run_here(tasks: list[Task], reporter: Reporter, name: str) -> Outcome:
    out = Outcome()
    with reporter.stage(name, total=len(tasks)) as st:
        for t in _ordered(tasks):
            bad = [d for d in t.deps if d in out.failed]
            if bad:
                out.failed[t.key] = f"needs failed task {bad[0]}"
            else:
                try:
                    out.results[t.key] = t.fn(*t.args, *(out.results[d] for d in t.deps))
                except Exception as exc:  # noqa: BLE001  (one failed task must not stop the others)
                    out.failed[t.key] = _describe(exc)
                    traceback.print_exc()
            st.progress(len(out.results) + len(out.failed), len(tasks), finished=len(out.results), running=0,
                        failed=len(out.failed))
    return out


def _ordered(tasks: list[Task]) -> list[Task]:
    """Tasks in an order where every task follows its dependencies, higher priorities first where the
    dependencies allow (stable otherwise)."""
    by_key, done, order = {t.key: t for t in tasks}, set(), []

    def visit(t: Task, path: tuple[str, ...]) -> None:
        if t.key in done:
            return
        if t.key in path:
            raise ValueError(f"task cycle: {' -> '.join(path + (t.key,))}")
        for d in t.deps:
            visit(by_key[d], path + (t.key,))
        done.add(t.key)
        order.append(t)

    for t in sorted(tasks, key=lambda t: -t.priority):
        visit(t, ())
    return order


class _PinnedCall:
    """``fn`` run after :func:`pin_threads` with the worker's allotment (picklable)."""

    def __init__(self, fn: Callable[..., Any], threads: int | None) -> None:
        self.fn, self.threads = fn, threads

    def __call__(self, *args: Any) -> Any:
        pin_threads(self.threads or worker_allotment())
        return self.fn(*args)


def worker_allotment() -> int:
    """This worker's share of the cores: ``OMP_NUM_THREADS`` when whoever started the worker set it (a local
    cluster does; so can a job script), else usable cores // the worker's Dask threads (>= 1)."""
    given = given_threads()
    if given:
        return given
    cores = usable_cores()
    try:
        from distributed import get_worker

        slots = get_worker().state.nthreads
    except (ImportError, ValueError, AttributeError):
        slots = 1
    return max(1, cores // max(1, slots))


def _run_dask(tasks: list[Task], scheduler: str, reporter: Reporter, retries: int, threads: int | None,
              name: str) -> Outcome:
    import dask
    from distributed import Client, LocalCluster, as_completed

    kind, where = parse_scheduler(scheduler)
    cluster = None
    with dask.config.set({"distributed.scheduler.allowed-failures": max(retries, 1),
                          "distributed.worker.daemon": False}):
        if kind == "local":
            threads = threads or max(1, usable_cores() // int(where))
            cluster = LocalCluster(n_workers=int(where), threads_per_worker=1, processes=True,
                                   dashboard_address=None, env=thread_environment(threads))
            address: Any = cluster
        else:
            address = where
        try:
            with connect(Client, address, scheduler) as client:
                return _submit_all(client, tasks, reporter, retries, threads, name, as_completed)
        finally:
            if cluster is not None:
                cluster.close()


def connect(client_class: Any, address: Any, scheduler: str) -> Any:
    """A Dask client of ``address``; a scheduler address nothing answers at is a user error that says so (Dask
    raises a bare OSError, 'Timed out trying to connect', after ``distributed.comm.timeouts.connect``)."""
    try:
        return client_class(address)
    except OSError as exc:
        if not isinstance(address, str):
            raise
        raise PGCConfigError(
            f"--scheduler {scheduler}: no Dask scheduler could be reached at {address} ({exc}); start one there "
            f"('dask scheduler --port PORT' on that host, then 'dask worker {address}' on each worker machine) or "
            "run on this machine with --scheduler local:N (N worker processes)") from exc


def _submit_all(client: Any, tasks: list[Task], reporter: Reporter, retries: int, threads: int | None,
                name: str, as_completed: Any) -> Outcome:
    """Submit the ready tasks of highest priority, one per free worker thread, and the next as each ends: the
    engine, not Dask, decides the order. (Dask sends a task whose dependencies are done straight to a worker but
    queues tasks without dependencies on the scheduler, so a capture would wait behind every run that became
    ready before it, whatever the priorities.) Results travel as values: they are small."""
    out = Outcome()
    in_order = _ordered(tasks)
    rank = {t.key: i for i, t in enumerate(in_order)}
    waiting = sorted(tasks, key=lambda t: (-t.priority, rank[t.key]))
    running: dict[str, str] = {}  # future key -> task key
    finished = as_completed()
    with reporter.stage(name, total=len(tasks)) as st:
        while waiting or running:
            for t in in_order:  # dependencies first: one pass fails a whole chain
                bad = [d for d in t.deps if d in out.failed]
                if bad and t.key not in out.failed and t.key not in out.results:
                    out.failed[t.key] = f"needs failed task {bad[0]}"
            waiting = [t for t in waiting if t.key not in out.failed]
            slots = max(1, sum(client.nthreads().values()))
            ready = [t for t in waiting if all(d in out.results for d in t.deps)][:max(0, slots - len(running))]
            for t in ready:
                future = client.submit(_PinnedCall(t.fn, threads), *t.args, *(out.results[d] for d in t.deps),
                                       key=t.key, retries=retries, pure=False, priority=t.priority)
                running[future.key] = t.key
                finished.add(future)
            submitted = {t.key for t in ready}
            waiting = [t for t in waiting if t.key not in submitted]
            if not running:
                break
            future = next(finished)
            key = running.pop(future.key)
            if future.status == "finished":
                out.results[key] = future.result()
            else:
                out.failed[key] = _describe(future.exception())
            st.progress(len(out.results) + len(out.failed), len(tasks), finished=len(out.results),
                        running=len(running), failed=len(out.failed))
    return out
