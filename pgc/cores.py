"""How many cores this process may use."""

from __future__ import annotations

import os


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports one)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def given_threads() -> int | None:
    """``OMP_NUM_THREADS`` when whoever started the process set a positive count (a sweep worker, a job
    script), else None."""
    given = os.environ.get("OMP_NUM_THREADS", "")
    return int(given) if given.isdigit() and int(given) > 0 else None


def allotted_cores() -> int:
    """This process's share of the cores: :func:`given_threads`, else every usable core."""
    return given_threads() or usable_cores()
