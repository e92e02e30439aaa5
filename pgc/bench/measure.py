"""Timing and peak memory of one benchmark run.

``peak_mb`` is the peak resident set size (RSS) of the process above its level when the measurement starts,
sampled every 2 ms from ``/proc/self/statm`` (so native allocations of torch/JAX/Mitsuba count, unlike with
tracemalloc); where /proc is missing it falls back to the ``resource.getrusage`` ``ru_maxrss`` delta.
"""

from __future__ import annotations

import resource
import statistics
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable

from pgc.io.asset import package_versions



def _rss_mb() -> float | None:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * resource.getpagesize() / 2**20
    except OSError:
        return None


class PeakRSS:
    """Context manager: ``mb`` is the peak RSS above the starting level while the block runs (MB)."""

    def __enter__(self) -> "PeakRSS":
        self.start = _rss_mb()
        if self.start is None:  # no /proc: the (monotonic) maximum RSS of the process instead
            self._maxrss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
            return self
        self.peak = self.start
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def _sample(self) -> None:
        while not self._stop.wait(0.002):
            self.peak = max(self.peak, _rss_mb() or 0.0)

    def __exit__(self, *exc: Any) -> None:
        if self.start is None:
            self.mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0 - self._maxrss0
            return
        self._stop.set()
        self._thread.join()
        self.mb = max(self.peak, _rss_mb() or 0.0) - self.start


@dataclass
class Timing:
    seconds: float
    """Median wall-clock seconds of the timed calls."""
    seconds_std: float
    peak_mb: float
    value: Any
    """The result of the last call."""


def timed(fn: Callable[[], Any], repeats: int = 1, warmup: bool = True) -> Timing:
    """Time ``fn``: one untimed warm-up call (JIT compilation, caches) when ``warmup``, then ``repeats``
    timed calls; their median seconds, standard deviation and the peak extra RSS while they ran."""
    if warmup:
        fn()
    times, value = [], None
    with PeakRSS() as mem:
        for _ in range(max(repeats, 1)):
            start = time.perf_counter()
            value = fn()
            times.append(time.perf_counter() - start)
    std = statistics.stdev(times) if len(times) > 1 else 0.0
    return Timing(statistics.median(times), std, round(max(mem.mb, 0.0), 2), value)


def versions() -> dict[str, str]:
    """Python and package versions recorded with every run."""
    return package_versions()
