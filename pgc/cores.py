"""How many cores this process may use, and which thread count runs a repeated kernel call fastest."""

from __future__ import annotations

import os
import time
from typing import Callable, Sequence, TypeVar

T = TypeVar("T")

BLAS_THREADS = "OPENBLAS_NUM_THREADS"
"""The variable that sets OpenBLAS's thread count (numpy's and scipy's BLAS), read once when it loads."""


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports one)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def keep_blas_single_threaded() -> None:
    """Hold OpenBLAS to one thread unless whoever started the process chose a count (:data:`BLAS_THREADS`).

    PGC's BLAS products are tall and thin (N points by a 3 x 3 matrix): a second thread gains nothing there,
    and while another process keeps the cores busy its waits at every call cost 10-60x (docs/architecture.md,
    "BLAS threads"). OpenBLAS reads the variable when numpy first loads it: ``import pgc`` calls this, so the
    command line and everything importing pgc before numpy get one thread; the results are the same bits."""
    os.environ.setdefault(BLAS_THREADS, "1")


def given_threads() -> int | None:
    """``OMP_NUM_THREADS`` when whoever started the process set a positive count (a sweep worker, a job
    script), else None."""
    given = os.environ.get("OMP_NUM_THREADS", "")
    return int(given) if given.isdigit() and int(given) > 0 else None


def allotted_cores() -> int:
    """This process's share of the cores: :func:`given_threads`, else every usable core."""
    return given_threads() or usable_cores()


class ThreadChooser:
    """Runs a repeated call on the fastest of several thread counts, chosen by timing the calls themselves.

    For calls whose result does not depend on the thread count (a deterministic kernel), so choosing costs
    nothing but the probes. The first call is a warm-up on ``candidates[0]`` (not timed: lazy set-up); the next
    ``len(candidates)`` calls time each count once; afterwards the count with the least latest time runs, and
    every ``probe_every`` calls one other count is timed again (round robin), so the choice follows the
    machine's load. On 2 idle cores two threads are faster; with another busy process on the machine one
    thread is (a descheduled thread stalls every barrier), which no fixed default gets right.
    """

    def __init__(self, candidates: Sequence[int], probe_every: int = 20,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        if not candidates:
            raise ValueError("ThreadChooser needs at least one thread count")
        self.candidates = list(dict.fromkeys(candidates))
        self.probe_every = probe_every
        self.clock = clock
        self.latest: dict[int, float] = {}
        self.calls = 0
        self._probe_turn = 0

    @classmethod
    def for_cores(cls, probe_every: int = 20) -> "ThreadChooser":
        """All allotted cores against one thread (just one thread where one core is allotted)."""
        return cls([allotted_cores(), 1], probe_every)

    @property
    def choice(self) -> int:
        """The count that runs next outside the probes: the least latest time (the first candidate until
        every count has been timed)."""
        if len(self.latest) < len(self.candidates):
            return self.candidates[0]
        return min(self.candidates, key=lambda n: self.latest[n])

    def _next(self) -> tuple[int, bool]:
        """The thread count of the next call, and whether to time it."""
        k = self.calls
        if k == 0 or len(self.candidates) == 1:
            return self.candidates[0], k > 0
        if k <= len(self.candidates):
            return self.candidates[k - 1], True
        if (k - len(self.candidates)) % self.probe_every == 0:
            others = [n for n in self.candidates if n != self.choice]
            self._probe_turn += 1
            return others[(self._probe_turn - 1) % len(others)], True
        return self.choice, True

    def run(self, call: Callable[[int], T]) -> T:
        """``call(threads)`` on the chosen count, timed."""
        threads, timed = self._next()
        start = self.clock()
        out = call(threads)
        if timed:
            self.latest[threads] = self.clock() - start
        self.calls += 1
        return out
